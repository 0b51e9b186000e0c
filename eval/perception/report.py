"""The perception report: ``perception.md`` and its figures (matplotlib, headless).

Confusion matrices in the style of the thesis' figures 5.9/5.10, a reliability diagram
(15 bins) and a confidence-per-class scatter like figure 5.11.
"""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ipbench.eval.perception.in_hand_report import fusion_table, in_hand_ablation_table  # noqa: E402
from ipbench.perception.metrics import reliability_curve  # noqa: E402

__all__ = ["write_report"]


def _fmt(value) -> str:
    return "n/a" if value is None else f"{value:.2f}"


def _confusion_png(path: Path, matrix: np.ndarray, classes, title: str) -> None:
    m = np.asarray(matrix, float)
    rows = m / np.maximum(m.sum(axis=1, keepdims=True), 1)
    fig, ax = plt.subplots(figsize=(4.6, 4.0), dpi=110)
    ax.imshow(rows, cmap="Blues", vmin=0, vmax=1)
    for i in range(len(classes)):
        for j in range(len(classes)):
            ax.text(
                j,
                i,
                f"{rows[i, j]:.2f}",
                ha="center",
                va="center",
                color="white" if rows[i, j] > 0.5 else "black",
                fontsize=8,
            )
    labels = [c.replace("_", " ") for c in classes]
    ax.set_xticks(range(len(classes)), labels, rotation=35, ha="right", fontsize=8)
    ax.set_yticks(range(len(classes)), labels, fontsize=8)
    ax.set_xlabel("predicted")
    ax.set_ylabel("true")
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _reliability_png(path: Path, curves: dict, title: str) -> None:
    fig, ax = plt.subplots(figsize=(4.4, 4.0), dpi=110)
    ax.plot([0, 1], [0, 1], "k:", lw=1, label="perfectly calibrated")
    for name, (probs, labels) in curves.items():
        if len(labels) == 0:
            continue
        conf, acc, count = reliability_curve(probs, labels, n_bins=15)
        ok = count > 0
        ax.plot(conf[ok], acc[ok], "o-", ms=3, label=name)
    ax.set_xlabel("confidence (max probability)")
    ax.set_ylabel("accuracy")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _scatter_png(path: Path, probs: np.ndarray, labels: np.ndarray, classes, title: str) -> None:
    fig, ax = plt.subplots(figsize=(5.0, 3.6), dpi=110)
    rng = np.random.default_rng(0)
    if len(labels):
        conf, pred = probs.max(axis=1), probs.argmax(axis=1)
        x = labels + rng.uniform(-0.25, 0.25, len(labels))
        right = pred == labels
        ax.scatter(x[right], conf[right], s=8, c="tab:green", label="correct")
        ax.scatter(x[~right], conf[~right], s=10, c="tab:red", marker="x", label="wrong")
    ax.set_xticks(range(len(classes)), [c.replace("_", " ") for c in classes], fontsize=8)
    ax.set_ylabel("confidence of the predicted class")
    ax.set_ylim(0, 1.02)
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _calibration_note(metrics: dict) -> list[str]:
    """Why ``gp`` (Laplace + Monte Carlo) and ``gp_mode`` (plug-in) differ in calibration."""
    lines = [
        "## GP predictive: Monte Carlo (`gp`) vs plug-in (`gp_mode`)",
        "",
        "`gp` is GPML Algorithm 3.4: the softmax averaged over the Laplace posterior of the "
        "latents. `gp_mode` is the same fitted model predicting the softmax of the latent "
        "mean. On nearly separable data the Laplace covariance stays close to the prior's "
        "(the likelihood curvature W vanishes where the softmax saturates), so the Monte-Carlo "
        "predictive is systematically under-confident — a known property of the Laplace "
        "approximation (Kuss & Rasmussen 2005; Nickisch & Rasmussen 2008), not of the data. "
        "Both share the hyper-parameters chosen by the marginal likelihood.",
        "",
    ]
    for subset, m in metrics.items():
        if "gp" in m and "gp_mode" in m:
            a, b = m["gp"], m["gp_mode"]
            lines.append(
                f"- {subset}: `gp` log loss {a['log_loss']:.3f} / ECE {a['ece']:.3f}, "
                f"`gp_mode` {b['log_loss']:.3f} / {b['ece']:.3f}"
                + (
                    f", `svm` {m['svm']['log_loss']:.3f} / {m['svm']['ece']:.3f}"
                    if "svm" in m
                    else ""
                )
                + " (unknown instances)."
            )
    return lines


def _pointnet_note(metrics: dict) -> list[str]:
    """What ``pointnet_ensemble`` reads and what it costs (fit, one scene's prediction)."""
    rows = [
        f"- {subset}: fit {m['fit_s']:.1f} s, {m['predict_ms_per_scene']:.1f} ms to classify a "
        "scene of 15 segments (one core)"
        for subset, by_name in metrics.items()
        if isinstance(by_name, dict)
        for name, m in by_name.items()
        if name == "pointnet_ensemble" and "predict_ms_per_scene" in m
    ]
    if not rows:
        return []
    return [
        "## PointNet deep ensemble (`pointnet_ensemble`)",
        "",
        "Classifies each view's points (a fixed-size sample, centred, metric scale, z up) "
        "rather than its FPFH bag of words: independently seeded PointNets trained on the same "
        "views as the GP, their softmax outputs averaged (`ipbench.perception.pointnet`).",
        "",
        *rows,
        "",
    ]


_SPLIT_TITLES = {
    "similar": "similar (new instances of trained families, table top)",
    "novel": "novel (held-out families, table top)",
    "in_hand": "in hand (instances not trained on; in-hand model)",
    "clutter": "clutter (segments of cluttered scenes)",
}


def _cell(m: dict) -> str:
    if not m.get("n"):
        return "—"
    return f"{m['accuracy']:.3f} / {m['log_loss']:.3f} / {m['ece']:.3f} (n={m['n']})"


def _splits_table(metrics: dict, thesis: dict) -> list[str]:
    """5 classes on every test split: accuracy / log loss / ECE per classifier."""
    splits = metrics.get("splits", {})
    if not splits:
        return []
    names = list(next(iter(splits.values())))
    lines = [
        "## 5 classes on every test split",
        "",
        "Accuracy / log loss / ECE (15 bins), and the number of views. The thesis, with a real "
        "Xtion on real objects: GP "
        f"{thesis['5class']['gp']:.2f}, SVM {thesis['5class']['svm']:.2f} (5 classes); GP "
        f"{thesis['3class']['gp']:.2f}, SVM {thesis['3class']['svm']:.2f} (3 classes).",
        "",
        "| split | " + " | ".join(names) + " |",
        "|---|" + "---|" * len(names),
    ]
    for split, by_name in splits.items():
        cells = [_cell(by_name.get(n, {})) for n in names]
        lines.append(f"| {_SPLIT_TITLES.get(split, split)} | " + " | ".join(cells) + " |")
    return lines + [""]


def _ablation_table(metrics: dict) -> list[str]:
    """Accuracy with each sensor effect switched off in turn."""
    ablation = metrics.get("ablation", {})
    if not ablation:
        return []
    names = list(next(iter(ablation.values())))
    lines = [
        "## Sensor ablation",
        "",
        "5-class accuracy on the similar and novel table-top views with one sensor effect "
        "switched off (train and test re-captured, lighter protocol: 6 yaws, one elevation, "
        "lying too); `none` switches nothing off.",
        "",
        "| effect switched off | " + " | ".join(names) + " |",
        "|---|" + "---|" * len(names),
    ]
    for effect, by_name in ablation.items():
        cells = [f"{by_name[n]['accuracy']:.3f}" if by_name[n].get("n") else "—" for n in names]
        lines.append(f"| {effect} | " + " | ".join(cells) + " |")
    return lines + [""]


def write_report(
    out: Path, metrics: dict, figures: dict, subsets: dict, thesis: dict, info: dict
) -> Path:
    """Write ``perception.md`` and the PNGs into ``out``; returns the markdown's path."""
    lines = [
        "# Perception: FPFH bag-of-words and GP classification on simulator views",
        "",
        f"Training: {info['train_views']} views of the known instances (isolated; the in-hand "
        "model: their in-hand views). Test: "
        f"{info['unknown_views']} views of the unknown instances (isolated) and "
        f"{info['cluttered_segments']} segments cut out of cluttered scenes (labelled by "
        f"overlap with the ground truth). Codebook: {info['codebook_size']} words. "
        f"Dataset key: `{info['dataset_key']}`.",
        "",
        "## Segmentation against the ground-truth masks (IoU >= 0.5)",
        "",
        "Mean per-scene precision and recall of the segments of each scene's first wrist view; "
        "clutter should show merged and split segments (what interaction later repairs).",
        "",
        "| scene | scenes | precision | recall | merged | split |",
        "|---|---|---|---|---|---|",
    ]
    for scene, m in info.get("segmentation", {}).items():
        lines.append(
            f"| {scene} | {m['scenes']} | {m['precision']:.3f} | {m['recall']:.3f} | "
            f"{m['merged']} | {m['split']} |"
        )
    lines += ["", *_splits_table(metrics, thesis), *_ablation_table(metrics)]
    lines += [*in_hand_ablation_table(metrics), *fusion_table(metrics)]
    lines += ["", *_calibration_note(metrics), "", *_pointnet_note(metrics)]
    for subset, classes in subsets.items():
        lines += [
            f"## {subset}: {', '.join(classes)}",
            "",
            "| classifier | accuracy | log loss | ECE (15 bins) | fit s | predict s | "
            "cluttered accuracy | cluttered log loss | cluttered ECE | thesis accuracy |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for name, m in metrics[subset].items():
            c = m.get("cluttered", {})
            ref = thesis.get(subset, {}).get(name)
            lines.append(
                f"| {name} | {m.get('accuracy', float('nan')):.3f} | "
                f"{m.get('log_loss', float('nan')):.3f} | {m.get('ece', float('nan')):.3f} | "
                f"{m['fit_s']:.2f} | {m['predict_s']:.3f} | "
                f"{c.get('accuracy', float('nan')):.3f} | {c.get('log_loss', float('nan')):.3f} "
                f"| {c.get('ece', float('nan')):.3f} | {'' if ref is None else f'{ref:.2f}'} |"
            )
        hand = {n: m for n, m in metrics[subset].items() if m.get("in_hand", {}).get("n")}
        if hand:
            lines += [
                "",
                f"In hand: {next(iter(hand.values()))['in_hand']['n']} views of the unknown "
                "instances held up "
                "to the wrist camera, classified by the in-hand model (trained on "
                f"{info.get('in_hand_train_views', 0)} in-hand views of the known instances) "
                "and by the table-top model above:",
                "",
                "| classifier | in-hand model accuracy | log loss | ECE | fit s | "
                "table-top model accuracy |",
                "|---|---|---|---|---|---|",
            ]
            for name, m in hand.items():
                h, t = m["in_hand"], m.get("in_hand_scene_model", {})
                lines.append(
                    f"| {name} | {h['accuracy']:.3f} | {h['log_loss']:.3f} | {h['ece']:.3f} | "
                    f"{h['fit_s']:.2f} | {t.get('accuracy', float('nan')):.3f} |"
                )
        lines += [
            "",
            "Per-class recall / precision on the unknown instances:",
            "",
            "| classifier | " + " | ".join(classes) + " |",
            "|---|" + "---|" * len(classes),
        ]
        for name, m in metrics[subset].items():
            cells = [
                f"{_fmt(r)} / {_fmt(p)}"
                for r, p in zip(m.get("recall", []), m.get("precision", []), strict=True)
            ]
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
        lines.append("")
        curves = {}
        for name in metrics[subset]:
            probs, labels = figures[(subset, name, "unknown")]
            if len(labels):
                png = f"confusion_{subset}_{re.sub(r'[^A-Za-z0-9_.-]', '-', name)}.png"  # file-safe
                _confusion_png(
                    out / png,
                    metrics[subset][name]["confusion"],
                    classes,
                    f"{name}, {subset}, unknown instances",
                )
                lines.append(f"![{name} confusion]({png})")
            curves[name] = (probs, labels)
        rel = f"reliability_{subset}.png"
        _reliability_png(out / rel, curves, f"reliability, {subset}, unknown instances")
        lines += ["", f"![reliability]({rel})"]
        if "gp" in metrics[subset]:
            probs, labels = figures[(subset, "gp", "unknown")]
            sc = f"confidence_{subset}_gp.png"
            _scatter_png(out / sc, probs, labels, classes, f"GP confidence per class, {subset}")
            lines += [f"![confidence]({sc})", ""]
    path = out / "perception.md"
    path.write_text("\n".join(lines) + "\n")
    return path
