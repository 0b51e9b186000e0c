"""Synthetic exploration episode records for the report tests: a consistent record from its
counts and recall curve (:func:`episode_record`), and SIFT records whose performances are known
by hand."""

from __future__ import annotations

BUDGET = 4
N = 10  # database instances per episode


def episode_record(scene, policy, feature, seed, tp, fp, nf, curve, **extra) -> dict:
    """A consistent record: performance from the counts, all false positives "nothing there",
    one localisation error of 10 mm per true positive unless given."""
    to_all = next((k for k, r in enumerate(curve) if r >= 1.0), None)
    record = {
        "scene": scene,
        "policy": policy,
        "feature": feature,
        "seed": seed,
        "n_database": tp + nf,
        "true_positives": tp,
        "false_positives": fp,
        "not_found": nf,
        "performance": tp / (tp + fp + nf),
        "recovered": 0,
        "fp_reasons": {"wrong_class": 0, "already_reported": 0, "nothing_there": fp},
        "saccades": len(curve) - 1,
        "sim_time_s": 1.5 * (len(curve) - 1),
        "wall_time_s": 3.0,
        "steps": len(curve),
        "recall_curve": curve,
        "saccades_to_all": to_all,
        "sim_s_to_all": None if to_all is None else 1.5 * to_all,
        "refixation_rate": 0.0,
        "localisation_mm": [10.0] * tp,
        "halted": True,
        "truncated": False,
        "video": None,
        "cycle_s": 0.5,
    }
    record.update(extra)
    return record


def record(scene: str, policy: str, seed: int, tp: int, fp: int) -> dict:
    """A consistent SIFT record with ``tp`` of N instances found and ``fp`` false positives (of
    the wrong class), in two saccades."""
    return episode_record(
        scene, policy, "sift", seed, tp, fp, N - tp, [0.0, tp / N / 2, tp / N],
        fp_reasons={"wrong_class": fp, "already_reported": 0, "nothing_there": 0},
    )  # fmt: skip


def sample_records(seeds=range(20), late_drop: int = 0) -> list[dict]:
    """active-vision finds 5 + seed % 3 instances; random-gaze 2 fewer, and ``late_drop``
    fewer again on seeds 10 and up; oracle-gaze finds 8; raster-scan only ran seeds 0-9."""
    out = []
    for seed in seeds:
        av = 5 + seed % 3
        out.append(record("simple", "active-vision", seed, av, 0))
        out.append(record("simple", "random-gaze", seed, av - 2 - late_drop * (seed >= 10), 0))
        out.append(record("simple", "oracle-gaze", seed, 8, 0))
        if seed < 10:
            out.append(record("simple", "raster-scan", seed, av, 0))
    return out
