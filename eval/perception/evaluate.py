"""``ipbench eval perception``: train and compare the classifiers on simulator views.

Two viewing conditions, one model each (:data:`CONDITIONS`): ``scene`` models classify what the
wrist camera sees on the table (and in the inspection area) and train on the *known*
instances' isolated views; ``in_hand`` models classify an object held up to the camera and train
on the known instances' in-hand views (see :mod:`ipbench.eval.capture.dataset`). Both share one
codebook, fitted on the isolated views. The test sets are the *unknown* instances (isolated,
and in hand) and segments cut out of cluttered scenes. The GP, the Platt-calibrated SVM and
scikit-learn's one-vs-rest GP are trained on the same 256-word bag-of-words vectors, for all
five classes and for the chapter-6 subset (juice bottle, milk carton, mug); the PointNet deep
ensemble ``pointnet_ensemble`` (:mod:`ipbench.perception.pointnet`) on the same views' point
samples. Written to the output folder: ``metrics.json`` (keys ``5class`` and ``3class``, each
with every classifier of :attr:`PerceptionEvalConfig.classifiers` and its ``accuracy``,
``log_loss``, ``ece``, ``fit_s``, ``predict_s`` on the unknown isolated instances, a point
classifier also ``predict_ms_per_scene``, the same on cluttered segments under
``cluttered``, the in-hand model on unknown in-hand views under ``in_hand`` and the scene model
on them under ``in_hand_scene_model``; ``splits``; ``fusion``: fused accuracy against the
number of views, in hand and on the table, :mod:`ipbench.eval.perception.view_fusion`; with the
ablations
``ablation`` and ``in_hand_ablation``, :mod:`ipbench.eval.perception.in_hand_ablation`),
``perception.md`` and PNG figures.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from ipbench.assets.objects import CATEGORIES, instances
from ipbench.envs.sensors.depth_noise import SENSOR_EFFECTS, without_effect
from ipbench.eval.capture.dataset import DatasetConfig, ViewSet, load_or_build
from ipbench.perception._pointnet_config import PointNetConfig
from ipbench.perception.classifiers import (
    CLASSIFIERS,
    GPClassifier,
    check_classifier_name,
    make_classifier,
)
from ipbench.perception.cloud import depth_to_points
from ipbench.perception.features import Codebook
from ipbench.perception.metrics import (
    accuracy,
    confusion_matrix,
    expected_calibration_error,
    log_loss,
    per_class_precision_recall,
)
from ipbench.perception.model import MODEL_VERSION, PerceptionModel, load_or_train
from ipbench.perception.segment_eval import match_segments
from ipbench.perception.segmentation import segment_scene
from ipbench.policies import EVAL_CAMERAS

__all__ = [
    "ABLATION_PROTOCOL",
    "CONDITIONS",
    "EVAL_CLASSIFIERS",
    "POINT_CLASSIFIERS",
    "SPLIT_TESTS",
    "PerceptionEvalConfig",
    "SUBSETS",
    "THESIS",
    "run_perception_eval",
    "segmentation_scores",
    "sensor_ablation",
    "split_tests",
    "encode",
    "model_key",
    "model_path",
    "trained_model",
    "trained_models",
    "training_views",
]

CONDITIONS: dict[str, str] = {"scene": "isolated", "in_hand": "in_hand"}
"""Viewing condition -> the view source its models train on (known instances only)."""

SUBSETS: dict[str, tuple[str, ...]] = {
    "5class": CATEGORIES,
    "3class": ("juice_bottle", "milk_carton", "mug"),
}
"""Class subsets evaluated: all five, and the chapter-6 three."""

SPLIT_TESTS: tuple[str, ...] = ("similar", "novel", "in_hand", "clutter")
"""The 5-class test sets of ``metrics.json["splits"]``: table-top views of new instances of
trained families (*similar*) and of held-out families (*novel*), in-hand views of every
instance not trained on (classified by the in-hand model), and cluttered-scene segments."""

ABLATION_PROTOCOL: dict = {
    "yaw_step_deg": 60.0,
    "elevations_deg": (50.0,),
    "side_elevation_deg": 55.0,
    "in_hand_views": 0,
    "cluttered_seeds": (),
    "per_category": 3,
}
"""The lighter capture protocol of the sensor ablation (3 instances of each category and split,
6 yaws, one elevation, lying too; no in-hand views or clutter): each effect switched off costs
a re-render of train and test views, so the ablation compares its rows with its own
all-effects-on row, not with ``splits``."""

POINT_CLASSIFIERS: tuple[str, ...] = ("pointnet_ensemble",)
"""Classifiers of a view's points (:attr:`ViewSet.points`) rather than its FPFH bag of words:
the PointNet deep ensemble of :mod:`ipbench.perception.pointnet`."""

EVAL_CLASSIFIERS: tuple[str, ...] = CLASSIFIERS + POINT_CLASSIFIERS
"""Every classifier ``ipbench eval perception`` compares by default."""

SCENE_SEGMENTS = 15
"""Segments of the scene whose classification time is reported for point classifiers
(``predict_ms_per_scene``: one core)."""

THESIS = {"5class": {"gp": 0.79, "svm": 0.75}, "3class": {"gp": 0.92, "svm": 0.83}}
"""The thesis' accuracies on real Xtion data (ch. 5 and 6), shown beside ours."""


@dataclass(frozen=True)
class PerceptionEvalConfig:
    """What the perception benchmark trains and evaluates.

    Attributes
    ----------
    dataset : how views are rendered (its hash keys the cache).
    codebook_size : words in the bag-of-words codebook (the thesis' best: 256).
    codebook_samples : descriptors sampled from the training views to fit the codebook.
    classifiers : which classifiers to compare (of :data:`EVAL_CLASSIFIERS`, or the user's own
        as ``module:attribute``: :func:`~ipbench.perception.classifiers.load_classifier`; such
        a classifier reads the bag-of-words vectors, as the GP does).
    seed : seeds the codebook and the classifiers (the PointNet ensemble's too: it replaces
        ``pointnet.seed``).
    segmentation_seeds : episode seeds of both standard scenes whose segmentation is scored
        against the ground-truth masks.
    ablation : also run the sensor ablation (:func:`sensor_ablation`): every switchable
        effect of the env's sensor switched off in turn, on the :data:`ABLATION_PROTOCOL`;
        and the in-hand ablation (:mod:`ipbench.eval.perception.in_hand_ablation`): each in-hand
        factor
        removed in turn.
    pointnet : the PointNet ensemble's architecture and training (``pointnet_ensemble``).
    """

    dataset: DatasetConfig = field(default_factory=DatasetConfig)
    codebook_size: int = 256
    codebook_samples: int = 60_000
    classifiers: tuple[str, ...] = EVAL_CLASSIFIERS
    seed: int = 0
    segmentation_seeds: tuple[int, ...] = tuple(range(10_100, 10_110))
    ablation: bool = False
    pointnet: PointNetConfig = field(default_factory=PointNetConfig)

    def __post_init__(self) -> None:
        for name in self.classifiers:  # a module:attribute reference is imported and checked
            check_classifier_name(name, EVAL_CLASSIFIERS)

    def pointnet_config(self) -> PointNetConfig:
        """:attr:`pointnet` seeded by :attr:`seed`."""
        return replace(self.pointnet, seed=self.seed)

    @classmethod
    def for_env(cls, env_id: str, **overrides) -> PerceptionEvalConfig:
        """The benchmark's configuration for ``env_id``'s objects and sensor (the sensor and
        in-hand ablations for the catalogues with splits to generalise to, i.e. v2 on)."""
        dataset = DatasetConfig(env_id=env_id)
        return cls(dataset=dataset, ablation=dataset.catalog != "v1", **overrides)


def model_key(
    config: PerceptionEvalConfig,
    classes: tuple[str, ...],
    classifier: str = "gp",
    condition: str = "scene",
) -> str:
    """Hash of everything that determines the trained ``classifier`` model for ``classes``
    in the viewing ``condition`` (a point classifier's: also its settings, not the codebook's;
    the FPFH classifiers' keys are as before)."""
    fields = [
        config.dataset.key(),
        config.codebook_size,
        config.codebook_samples,
        config.seed,
        list(classes),
        classifier,
        condition,
        MODEL_VERSION,
    ]
    if classifier in POINT_CLASSIFIERS:
        fields[1:3] = [asdict(config.pointnet_config())]
    text = json.dumps(fields)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def training_views(views: ViewSet, condition: str = "scene") -> ViewSet:
    """The known instances' views that train a ``condition`` model (see :data:`CONDITIONS`)."""
    if condition not in CONDITIONS:
        raise ValueError(f"unknown condition {condition!r}; valid: {', '.join(CONDITIONS)}")
    return views.subset((views.source == CONDITIONS[condition]) & views.known)


def _fit_codebook(train: ViewSet, config: PerceptionEvalConfig) -> Codebook:
    rng = np.random.default_rng(config.seed)
    n = len(train.descriptors)
    take = rng.choice(n, min(config.codebook_samples, n), replace=False)
    return Codebook.fit(train.descriptors[take], config.codebook_size, config.seed)


def trained_models(
    cache: Path,
    config: PerceptionEvalConfig = PerceptionEvalConfig(),
    classes: tuple[str, ...] = CATEGORIES,
    classifiers: tuple[str, ...] = ("gp",),
    condition: str = "scene",
    workers: int = 2,
    progress: bool = True,
) -> dict:
    """The perception models for ``classes`` in the viewing ``condition`` (one of
    :data:`CONDITIONS`), cached in ``cache`` (trained if missing, stale or corrupt) — what the
    sorting policies classify with: a :class:`PerceptionModel` (codebook + classifier) for each
    of ``"gp"``, ``"gp_mode"``, ``"svm"``, ``"sklearn_gp"``, and a
    :class:`~ipbench.perception.pointnet.PointNetEnsemble` (``probabilities`` of segments'
    (n_i, 3) points) for ``"pointnet_ensemble"``. Models trained together share one dataset
    load, codebook and encoding; the codebook is fitted on the isolated views in every
    condition. Missing views render in ``workers`` processes, with a bar if ``progress``
    (:func:`ipbench.eval.perception.prepare.prepare_perception` renders and trains several models in
    one pool)."""
    unknown = [c for c in classifiers if c not in EVAL_CLASSIFIERS]
    if unknown:
        raise ValueError(f"unknown classifiers {unknown}; valid: {', '.join(EVAL_CLASSIFIERS)}")
    shared: dict = {}

    def condition_views() -> tuple[ViewSet, ViewSet, np.ndarray, np.ndarray]:
        """All loaded views, the condition's training views of ``classes``, their labels."""
        if "views" not in shared:  # the isolated views (the codebook's) and the condition's
            kinds = tuple(dict.fromkeys((CONDITIONS["scene"], CONDITIONS[condition])))
            views = load_or_build(
                cache,
                config.dataset,
                progress=progress,
                workers=workers,
                training_only=True,
                kinds=kinds,
            )
            train = training_views(views, condition)
            keep = np.isin(train.labels, [CATEGORIES.index(c) for c in classes])
            labels = np.array([classes.index(CATEGORIES[v]) for v in train.labels[keep]])
            if len(labels) == 0:
                raise ValueError(
                    f"no {condition} training views in the dataset; set "
                    "DatasetConfig.in_hand_views > 0 to render in-hand views"
                )
            shared["views"] = (views, train, keep, labels)
        return shared["views"]

    def training_data() -> tuple[Codebook, np.ndarray, np.ndarray]:
        if "data" not in shared:
            views, train, keep, labels = condition_views()
            codebook = _fit_codebook(training_views(views, "scene"), config)
            shared["data"] = (codebook, encode(train, codebook)[keep], labels)
        return shared["data"]

    def point_trainer(key: str):
        def train():
            from ipbench.perception.pointnet import PointNetEnsemble

            _, views, keep, y = condition_views()
            model = PointNetEnsemble(len(classes), config.pointnet_config(), classes, key)
            return model.fit(views.points[keep], y, groups=views.instance[keep])

        return train

    def trainer(classifier: str, key: str):
        def train() -> PerceptionModel:
            codebook, x, y = training_data()
            clf = make_classifier(classifier, n_classes=len(classes), seed=config.seed)
            clf.fit(x, y)
            fitted = clf.model_ if isinstance(clf, GPClassifier) else clf
            return PerceptionModel(tuple(classes), codebook, fitted, key)

        return train

    models = {}
    with threadpool_limits(1):
        for classifier in classifiers:
            key = model_key(config, classes, classifier, condition)
            path = model_path(cache, key)
            if classifier in POINT_CLASSIFIERS:
                from ipbench.perception.pointnet import load_or_train_pointnet

                models[classifier] = load_or_train_pointnet(path, key, point_trainer(key))
            else:
                models[classifier] = load_or_train(path, key, trainer(classifier, key))
    return models


def model_path(cache: Path, key: str) -> Path:
    """Where the model of :func:`model_key` ``key`` is cached."""
    return Path(cache) / f"model-{key}.npz"


def trained_model(
    cache: Path,
    config: PerceptionEvalConfig = PerceptionEvalConfig(),
    classes: tuple[str, ...] = CATEGORIES,
    classifier: str = "gp",
):
    """One model of :func:`trained_models`."""
    return trained_models(cache, config, classes, (classifier,))[classifier]


def encode(views: ViewSet, codebook: Codebook) -> np.ndarray:
    """(n, k) bag-of-words vector of every view."""
    if not len(views):
        return np.zeros((0, codebook.size))
    return np.stack([codebook.encode(views.view(i)) for i in range(len(views))])


def _scores(probs: np.ndarray, labels: np.ndarray, n_classes: int) -> dict:
    preds = probs.argmax(axis=1)
    precision, recall = per_class_precision_recall(labels, preds, n_classes)
    return {
        "n": int(len(labels)),
        "accuracy": float(accuracy(labels, preds)),
        "log_loss": float(log_loss(probs, labels)),
        "ece": float(expected_calibration_error(probs, labels, n_bins=15)),
        "precision": [None if np.isnan(v) else float(v) for v in precision],
        "recall": [None if np.isnan(v) else float(v) for v in recall],
        "confusion": confusion_matrix(labels, preds, n_classes).tolist(),
    }


def segmentation_scores(
    seeds: tuple[int, ...], config: PerceptionEvalConfig
) -> dict[str, dict[str, float]]:
    """Segments of each standard scene's first observation against the ground-truth masks
    (IoU >= 0.5): mean precision and recall over ``seeds``, total merged and split."""
    import gymnasium as gym

    import ipbench.envs  # noqa: F401
    from ipbench.envs.sorting_scenes import STANDARD_SCENES

    out = {}
    for scene in STANDARD_SCENES:
        env = gym.make(
            config.dataset.env_id,
            scene=scene,
            depth_noise=config.dataset.sensor,
            cameras=EVAL_CAMERAS,
        )
        rows = []
        for seed in seeds:
            obs, info = env.reset(seed=seed)
            cloud = depth_to_points(obs["wrist_depth"], obs["wrist_K"], obs["wrist_pose"])
            segments = segment_scene(cloud, config.dataset.segmentation).segments
            rows.append(match_segments(segments, info["wrist_mask"], valid=obs["wrist_depth"] > 0))
        env.close()
        out[scene] = {
            "scenes": len(rows),
            "precision": float(np.mean([r["precision"] for r in rows])),
            "recall": float(np.mean([r["recall"] for r in rows])),
            "merged": int(sum(r["merged"] for r in rows)),
            "split": int(sum(r["split"] for r in rows)),
        }
    return out


def split_tests(views: ViewSet, catalog: str) -> dict[str, ViewSet]:
    """The views of each of :data:`SPLIT_TESTS` (see there), by the split of each view's
    instance in ``catalog`` (v1: its unknown instances are *similar*; it has no *novel*)."""
    split_of = {inst.name: inst.split for inst in instances(catalog=catalog)}
    split = np.array([split_of.get(str(n), "train") for n in views.instance])
    isolated, hand = views.source == "isolated", views.source == "in_hand"
    return {
        "similar": views.subset(isolated & (split == "similar")),
        "novel": views.subset(isolated & (split == "novel")),
        "in_hand": views.subset(hand & (split != "train")),
        "clutter": views.subset(views.source == "cluttered"),
    }


def _brief(scores: dict) -> dict:
    """The headline figures of a score entry (``n`` and, with views, accuracy, log loss,
    ECE)."""
    return {k: scores[k] for k in ("n", "accuracy", "log_loss", "ece") if k in scores}


def sensor_ablation(cache: Path, config: PerceptionEvalConfig) -> dict:
    """5-class accuracy with every switchable effect of the env's sensor switched off in turn
    (key: the effect; ``"none"``: every effect on), trained on the *train* split and tested on
    the *similar* and *novel* table-top views of :data:`ABLATION_PROTOCOL` captures, per
    classifier: ``{effect: {classifier: {"accuracy", "log_loss", "ece", "n"}}}``. An effect
    the sensor does not use is left out."""
    base = replace(config.dataset, **ABLATION_PROTOCOL)
    sensor = base.sensor
    effects = ["none"] + [e for e in SENSOR_EFFECTS if without_effect(sensor, e) != sensor]
    index = {i: i for i in range(len(CATEGORIES))}
    out: dict = {}
    for effect in effects:
        noise = sensor if effect == "none" else without_effect(sensor, effect)
        views = load_or_build(cache, replace(base, depth_noise=noise))
        train = training_views(views, "scene")
        sets = split_tests(views, base.catalog)
        test = ViewSet.concat([sets["similar"], sets["novel"]])
        codebook = _fit_codebook(train, config)
        x_train, x_test = encode(train, codebook), encode(test, codebook)
        fitted: dict = {}
        out[effect] = {}
        for name in config.classifiers:
            clf, _ = _fit(name, _inputs(name, train, x_train), train, index, config, fitted)
            out[effect][name] = _brief(_score(clf, test, _inputs(name, test, x_test), index)[0])
    return out


def _inputs(name: str, views: ViewSet, bow: np.ndarray) -> np.ndarray:
    """What classifier ``name`` reads of ``views``: their (n, P, 3) points for a point
    classifier, else their bag-of-words vectors ``bow``."""
    return views.points if name in POINT_CLASSIFIERS else bow


def _fit(
    name: str,
    x: np.ndarray,
    train: ViewSet,
    index: dict[int, int],
    config: PerceptionEvalConfig,
    fitted: dict,
):
    """Fit classifier ``name`` on ``x`` (:func:`_inputs` of ``train``), the views whose
    category is in ``index`` (category -> class); ``fitted`` collects ``(classifier, fit
    seconds)`` by name (``gp_mode`` reuses ``gp``)."""
    keep = np.isin(train.labels, list(index))
    y = np.array([index[v] for v in train.labels[keep]])
    t0 = time.perf_counter()
    if name == "gp_mode" and "gp" in fitted:  # the same fit, another predictive
        fitted[name] = (
            GPClassifier.from_model(fitted["gp"][0].model_.with_predictive("mode")),
            fitted["gp"][1],
        )
    elif name in POINT_CLASSIFIERS:
        from ipbench.perception.pointnet import PointNetEnsemble

        clf = PointNetEnsemble(len(index), config.pointnet_config())
        clf.fit(x[keep], y, groups=train.instance[keep])
        fitted[name] = (clf, time.perf_counter() - t0)
    else:
        clf = make_classifier(name, n_classes=len(index), seed=config.seed)
        clf.fit(x[keep], y)
        fitted[name] = (clf, time.perf_counter() - t0)
    return fitted[name]


def _scene_predict_ms(clf, clouds: np.ndarray, repeats: int = 5) -> float:
    """Median wall time (ms, one core) for ``clf`` to classify :data:`SCENE_SEGMENTS` of
    ``clouds`` (repeated cyclically when fewer), as one scene's segments."""
    take = [clouds[i % len(clouds)] for i in range(SCENE_SEGMENTS)]
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        clf.predict_proba(take)
        times.append(time.perf_counter() - t0)
    return round(1000 * float(np.median(times)), 2)


def _score(clf, test: ViewSet, x: np.ndarray, index: dict[int, int]):
    """Scores, probabilities and labels of ``clf`` on the views of ``test`` in ``index``."""
    sel = np.isin(test.labels, list(index))
    labels = np.array([index[v] for v in test.labels[sel]])
    if not sel.any():
        return {"n": 0}, np.zeros((0, len(index))), labels
    t0 = time.perf_counter()
    probs = clf.predict_proba(x[sel])
    scores = _scores(probs, labels, len(index))
    scores["predict_s"] = round(time.perf_counter() - t0, 3)
    return scores, probs, labels


def run_perception_eval(
    out: Path, cache: Path, config: PerceptionEvalConfig = PerceptionEvalConfig()
) -> dict:
    """Train and evaluate every classifier on every subset; write the report to ``out``.

    Linear algebra runs on one thread: on a small loaded machine multi-threaded BLAS was
    measured up to 150x slower for these n x n Cholesky factorisations.
    """
    with threadpool_limits(1):
        return _run_perception_eval(out, cache, config)


def _run_perception_eval(out: Path, cache: Path, config: PerceptionEvalConfig) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    views = load_or_build(cache, config.dataset)
    train = training_views(views, "scene")
    hand_train = training_views(views, "in_hand")
    tests = {
        "unknown": views.subset((views.source == "isolated") & ~views.known),
        "cluttered": views.subset(views.source == "cluttered"),
        "in_hand": views.subset((views.source == "in_hand") & ~views.known),
    }
    split_sets = split_tests(views, config.dataset.catalog)
    splits: dict = {}
    split_probs: dict = {}  # (split, classifier) -> (n, 5) probabilities, for view fusion
    codebook = _fit_codebook(train, config)
    x_split = {name: encode(t, codebook) for name, t in split_sets.items()}
    x_train = encode(train, codebook)
    x_hand = encode(hand_train, codebook)
    x_tests = {name: encode(t, codebook) for name, t in tests.items()}

    def inputs(name: str, test: str) -> np.ndarray:
        return _inputs(name, tests[test], x_tests[test])

    metrics: dict = {}
    figures: dict = {}
    for subset, classes in SUBSETS.items():
        index = {CATEGORIES.index(c): i for i, c in enumerate(classes)}
        metrics[subset] = {}
        fitted: dict = {}
        fitted_hand: dict = {}
        for name in config.classifiers:
            clf, fit_s = _fit(name, _inputs(name, train, x_train), train, index, config, fitted)
            entry: dict = {"fit_s": round(fit_s, 3)}
            scores, probs, labels = _score(clf, tests["unknown"], inputs(name, "unknown"), index)
            entry.update(scores)
            if name in POINT_CLASSIFIERS and len(tests["unknown"]):
                entry["predict_ms_per_scene"] = _scene_predict_ms(clf, tests["unknown"].points)
            figures[(subset, name, "unknown")] = (probs, labels)
            for test_name, field_name in (
                ("cluttered", "cluttered"),
                ("in_hand", "in_hand_scene_model"),
            ):
                entry[field_name] = _score(clf, tests[test_name], inputs(name, test_name), index)[0]
            if len(hand_train):
                hand_clf, hand_fit_s = _fit(
                    name, _inputs(name, hand_train, x_hand), hand_train, index, config, fitted_hand
                )
                scores, probs, labels = _score(
                    hand_clf, tests["in_hand"], inputs(name, "in_hand"), index
                )
                entry["in_hand"] = {**scores, "fit_s": round(hand_fit_s, 3)}
                figures[(subset, name, "in_hand")] = (probs, labels)
            metrics[subset][name] = entry
            if subset == "5class":
                scene_clf, hand_clf = clf, fitted_hand.get(name, (None,))[0]
                for split, test in split_sets.items():
                    model = hand_clf if split == "in_hand" else scene_clf
                    got = {"n": 0}
                    if model is not None:
                        x = _inputs(name, test, x_split[split])
                        got, split_probs[split, name], _ = _score(model, test, x, index)
                    splits.setdefault(split, {})[name] = _brief(got)
    metrics["splits"] = splits
    from ipbench.eval.perception.view_fusion import fusion_metrics

    metrics["fusion"] = fusion_metrics(split_sets, split_probs, config.dataset.catalog)
    if config.ablation:
        from ipbench.eval.perception.in_hand_ablation import in_hand_ablation

        metrics["ablation"] = sensor_ablation(cache, config)
        metrics["in_hand_ablation"] = in_hand_ablation(cache, config)
    segmentation = segmentation_scores(config.segmentation_seeds, config)
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2))
    (out / "segmentation.json").write_text(json.dumps(segmentation, indent=2))
    from ipbench.eval.perception.report import write_report

    write_report(
        out,
        metrics,
        figures,
        SUBSETS,
        THESIS,
        {
            "train_views": len(train),
            "unknown_views": len(tests["unknown"]),
            "cluttered_segments": len(tests["cluttered"]),
            "in_hand_train_views": len(hand_train),
            "in_hand_views": len(tests["in_hand"]),
            "codebook_size": config.codebook_size,
            "dataset_key": config.dataset.key(),
            "segmentation": segmentation,
        },
    )
    return metrics
