"""``ipbench eval sorting``: run sorting policies as episodes and compare them (thesis Table 5.1).

Policies x scenes x seeds, the same seeds for every policy (paired comparison). Steps:

1. The perception models (GP; SVM when ``svm-ipm`` runs; for the policies that inspect in
   hand, the same classifiers trained on in-hand views) are loaded from the cache or trained
   (:func:`ipbench.eval.perception.evaluate.trained_models`).
2. The confidence threshold of each interactive policy's classifier is chosen on validation
   seeds disjoint from the test seeds (:func:`ipbench.policies.threshold.choose_threshold`
   on every decision of random sorting through both standard scenes) and saved in the cache.
3. Episodes run serially, in ``workers`` processes, or as Ray tasks; each record is appended to
   ``episodes.jsonl`` as soon as it finishes, so an interrupted run resumes where it stopped.
   ``run.json`` fingerprints the configuration; resuming into a folder made by another
   configuration is refused rather than mixing results.
4. ``summary.json``, ``sorting.md`` and plots (:mod:`ipbench.eval.sorting.report`), and
   optionally one MP4 per policy and scene with the semantic overlay
   (:mod:`ipbench.eval.sorting.overlay`).
"""

from __future__ import annotations

import hashlib
import json
import time
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import gymnasium as gym
import numpy as np
from threadpoolctl import threadpool_limits
from tqdm import tqdm

import ipbench.envs  # noqa: F401  (registers the environments)
from ipbench.assets.objects import CATEGORIES
from ipbench.envs import env_status
from ipbench.envs.sorting import workcell_places
from ipbench.envs.sorting_scenes import SCENES, STANDARD_SCENES
from ipbench.eval.capture.dataset import DATASET_VERSION
from ipbench.eval.episodes import BACKENDS, run_episodes, run_grid
from ipbench.eval.perception.evaluate import model_key, trained_models
from ipbench.eval.perception.prepare import prepare_perception
from ipbench.eval.schedule import longest_first, task_cost
from ipbench.eval.sorting.config import (
    EPISODE_VERSION,
    SortingEvalConfig,
    SortingEvalError,
    Task,
)
from ipbench.eval.sorting.curve import write_curve
from ipbench.eval.sorting.label_curve import label_curve, label_curve_lines
from ipbench.eval.sorting.report import (
    ThresholdSweep,
    loss_decomposition,
    write_report,
)
from ipbench.policies import (
    EVAL_CAMERAS,
    INTERACTIVE,
    POLICY_VERSION,
    READS_INFO,
    NothingToSort,
    PolicyModels,
    make_policy,
    policy_classifier,
    split_policy_name,
)
from ipbench.policies.custom import is_reference
from ipbench.policies.oracle import true_category, true_object
from ipbench.policies.threshold import RULE, ThresholdChoice, choose_threshold

__all__ = [
    "BACKENDS",
    "EPISODE_VERSION",
    "SortingEvalConfig",
    "SortingEvalError",
    "Task",
    "prepare_models",
    "run_episode",
    "run_sorting_eval",
]

_VALIDATION_PROTOCOL = 3
"""Version of how threshold evidence is gathered (3: every labelled segment of the first view
of each validation scene, :func:`validation_view`)."""


# -- models and thresholds ---------------------------------------------------------------------
def _validation_tasks(config: SortingEvalConfig) -> list[Task]:
    """The validation scenes: both standard scenes (whichever are evaluated: the thresholds
    stay those released) at every validation seed."""
    return [
        Task(scene, "validation", seed)
        for scene in SCENES
        if scene in STANDARD_SCENES
        for seed in config.validation_seeds
    ]


def _under_test(model, config: SortingEvalConfig) -> PolicyModels:
    """The models of a validation scene: ``model`` on the table, nothing else."""
    area = tuple(float(v) for v in workcell_places().inspection_area.center)
    seg, feat = config.perception.dataset.segmentation, config.perception.dataset.features
    return PolicyModels(
        gp=model, inspection_area=area, thresholds={}, segmentation=seg, features=feat
    )


def validation_view(task: Task, models: PolicyModels, config: SortingEvalConfig) -> dict:
    """The labelled first view of one validation scene: ``reset(seed)`` (the layout settles;
    no grasp, no contact chaos), the scene perceived as every sorter perceives it, each segment
    with its label, confidence and the category of the object under it (None: background)."""
    with threadpool_limits(1):
        dataset = config.perception.dataset
        env = gym.make(
            dataset.env_id, scene=task.scene, depth_noise=dataset.sensor, cameras=EVAL_CAMERAS
        )
        try:
            policy = make_policy("random", models, config.n_views, config.fusion)
            policy.reset(task.seed)
            obs, info = env.reset(seed=task.seed)
            detections = policy.perceive_scene(obs)
        finally:
            env.close()
    decisions = [
        {
            "first_label": d.label,
            "first_confidence": round(d.confidence, 4),
            "true_category": true_category(d.segment.pixels, info),
        }
        for d in detections
    ]
    return {"scene": task.scene, "seed": task.seed, "decisions": decisions}


def _evidence_of(records, tasks: list[Task]) -> tuple[np.ndarray, np.ndarray]:
    """Confidence and correctness of every labelled segment in ``records`` (the views of
    ``tasks``), in task order whatever order the workers finished in: the same evidence file
    every run."""
    order = {(t.scene, t.seed): i for i, t in enumerate(tasks)}
    conf, correct = [], []
    for record in sorted(records, key=lambda r: order[r["scene"], r["seed"]]):
        for d in record["decisions"]:
            if d["true_category"] is not None:
                conf.append(d["first_confidence"])
                correct.append(d["first_label"] == d["true_category"])
    return np.array(conf), np.array(correct, bool)


def _validation_evidence(
    model, config: SortingEvalConfig, progress: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Confidence and correctness of every labelled segment of the validation scenes' first
    views, classified by ``model`` (from an empty cache the views are taken in the
    preparation pool instead: :func:`_validation_scene`)."""
    tasks = _validation_tasks(config)
    config = config.validation_config()
    records = run_episodes(
        validation_view,
        tasks,
        (_under_test(model, config), config),
        workers=config.workers,
        backend=config.backend,
        ray_address=config.ray_address,
        error=SortingEvalError,
    )
    bar = tqdm(records, total=len(tasks), desc="validation scenes", disable=not progress)
    return _evidence_of(list(bar), tasks)


_VALIDATION_MODELS: dict = {}  # in a preparation worker: the last models it validated


def _validation_scene(cache: Path, classifier: str, config: SortingEvalConfig, task: Task):
    """One validation view in a worker of
    :func:`ipbench.eval.perception.prepare.prepare_perception`, with the table-top
    ``classifier`` model read from ``cache`` (loaded once per worker; mapped, so it costs a
    fraction of a second)."""
    key = (str(cache), classifier, config.perception)
    if key not in _VALIDATION_MODELS:
        model = trained_models(
            cache, config.perception, CATEGORIES, (classifier,), workers=1, progress=False
        )[classifier]
        _VALIDATION_MODELS.clear()
        _VALIDATION_MODELS[key] = _under_test(model, config)
    return validation_view(task, _VALIDATION_MODELS[key], config.validation_config())


@dataclass(frozen=True)
class _Keyed:
    """A model known by its key only (what :func:`_validation_key` reads)."""

    key: str


def _validation_key(model, config: SortingEvalConfig) -> list:
    """What the validation evidence of ``model`` (anything with its ``key``) depends on."""
    # no cell: validation runs in the released cell (SortingEvalConfig.validation_config)
    return [model.key, list(config.validation_seeds), _VALIDATION_PROTOCOL, POLICY_VERSION]


def _cache_path(cache: Path, kind: str, classifier: str, parts: list) -> Path:
    digest = hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()[:16]
    return Path(cache) / f"{kind}-{classifier}-{digest}.json"


def _write_json(path: Path, record: dict) -> None:
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(record))
    tmp.replace(path)


def _evidence(
    cache: Path,
    model,
    classifier: str,
    config: SortingEvalConfig,
    progress: bool,
    records: list | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_validation_evidence`, cached: it does not depend on the target precision or the
    rule, so a sweep over targets takes the validation views once; ``records``: those views,
    taken already (in the preparation pool)."""
    path = _cache_path(cache, "evidence", classifier, _validation_key(model, config))
    if path.exists():
        try:
            d = json.loads(path.read_text())
            conf, correct = np.array(d["confidence"], float), np.array(d["correct"], bool)
            if conf.shape == correct.shape and conf.ndim == 1:
                return conf, correct
            print(f"ipbench: evidence file {path} is malformed; gathering it again")
        except (ValueError, KeyError, TypeError) as err:
            print(f"ipbench: evidence file {path} is corrupt ({err}); gathering it again")
    if records is not None:
        conf, correct = _evidence_of(records, _validation_tasks(config))
    else:
        conf, correct = _validation_evidence(model, config, progress)
    _write_json(path, {"confidence": conf.tolist(), "correct": correct.tolist()})
    return conf, correct


def _threshold_path(cache: Path, model, classifier: str, config: SortingEvalConfig) -> Path:
    key = [*_validation_key(model, config), config.target_precision, RULE]
    return _cache_path(cache, "threshold", classifier, key)


def _needs_validation(cache: Path, model, classifier: str, config: SortingEvalConfig) -> bool:
    """Neither the threshold nor the evidence of ``model`` is cached."""
    evidence = _cache_path(cache, "evidence", classifier, _validation_key(model, config))
    return not (_threshold_path(cache, model, classifier, config).exists() or evidence.exists())


def _threshold(
    cache: Path,
    model,
    classifier: str,
    config: SortingEvalConfig,
    progress: bool = False,
    records: list | None = None,
) -> ThresholdChoice:
    """The threshold chosen for ``model`` on the validation views (``records``: taken
    already), saved in ``cache``."""
    path = _threshold_path(cache, model, classifier, config)
    if path.exists():
        try:
            d = json.loads(path.read_text())
            return ThresholdChoice(
                float(d["threshold"]),
                float(d["target_precision"]),
                int(d["n"]),
                np.array(d["thresholds"], float),
                np.array(d["precision"], float),
                np.array(d["inspected"], float),
                np.array(d["fitted_precision"], float),
                (float(d["fit"][0]), float(d["fit"][1])),
                str(d["rule"]),
            )
        except (ValueError, KeyError, TypeError, IndexError) as err:
            print(f"ipbench: threshold file {path} is corrupt ({err}); choosing again")
    conf, correct = _evidence(cache, model, classifier, config, progress, records)
    choice = choose_threshold(conf, correct, config.target_precision)
    _write_json(
        path,
        {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in asdict(choice).items()},
    )
    return choice


def prepare_models(
    cache: Path, config: SortingEvalConfig, progress: bool = False
) -> tuple[PolicyModels, dict[str, ThresholdChoice]]:
    """Trained models and validated thresholds for ``config.policies`` (cached in ``cache``;
    ``progress``: a bar over the validation views when a threshold must be chosen)."""
    cache = Path(cache)
    try:
        cache.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError) as err:
        raise SortingEvalError(
            f"the cache {cache} is not a folder ({err.filename} is a file); pass a folder path "
            "(created if missing), or move the file away"
        ) from err
    # the table-top models: the GP (every policy perceives with it) and each interactive
    # policy's classifier
    inspecting = [c for p in config.policies if (c := policy_classifier(p)) is not None]
    needed = sorted({classifier for classifier, _ in inspecting})
    wanted = ("gp",) + tuple(c for c in needed if c != "gp")
    hand = {classifier for classifier, mode in inspecting if mode == "hand"}
    if any(is_reference(p) for p in config.policies):  # a policy of the user's own sees with
        hand.add("gp")  # GP-IPM's perceiver, whichever policies run beside it
    in_hand = tuple(sorted(hand))
    # validation views still to take go into the same pool (not with Ray: they run there)
    pending = [
        c
        for c in needed
        if config.backend == "process"
        and _needs_validation(
            cache, _Keyed(model_key(config.perception, CATEGORIES, c, "scene")), c, config
        )
    ]
    validation = _validation_tasks(config)
    # the views, the models and the validation scenes from an empty cache in one pool
    # (ipbench.eval.perception.prepare): the scenes are taken while the in-hand models train
    ran = prepare_perception(
        cache,
        config.perception,
        (("scene", wanted), ("in_hand", in_hand)),
        config.workers,
        progress,
        then=[(_validation_scene, cache, c, config, t) for c in pending for t in validation],
    )
    records = {
        c: ran[k * len(validation) : (k + 1) * len(validation)] for k, c in enumerate(pending)
    }
    with threadpool_limits(1):
        models = trained_models(
            cache, config.perception, CATEGORIES, wanted, workers=config.workers
        )
        hand = trained_models(
            cache, config.perception, CATEGORIES, in_hand, "in_hand", workers=config.workers
        )
        choices = {
            c: _threshold(cache, models[c], c, config, progress, records.get(c)) for c in needed
        }
    policy_models = PolicyModels(
        gp=models["gp"],
        svm=models.get("svm"),
        gp_hand=hand.get("gp"),
        svm_hand=hand.get("svm"),
        pointnet_ensemble=models.get("pointnet_ensemble"),
        pointnet_ensemble_hand=hand.get("pointnet_ensemble"),
        inspection_area=tuple(float(v) for v in workcell_places().inspection_area.center),
        thresholds={c: ch.threshold for c, ch in choices.items()},
        segmentation=config.perception.dataset.segmentation,
        features=config.perception.dataset.features,
    )
    return policy_models, choices


def validation_source(config: SortingEvalConfig) -> str:
    """In words, the data the thresholds are chosen on."""
    scenes = ", ".join(s for s in SCENES if s in STANDARD_SCENES)
    seeds = config.validation_seeds
    return (
        f"every labelled segment of the first view (after reset, before any grasp) of the "
        f"{scenes} scenes at validation seeds {min(seeds)}-{max(seeds)} ({len(seeds)} each)"
    )


def threshold_record(choice: ThresholdChoice, config: SortingEvalConfig) -> dict:
    """What ``run.json`` records of a validated threshold: the value, the rule and its data."""
    return {
        "threshold": choice.threshold,
        "rule": choice.rule,
        "target_precision": choice.target_precision,
        "fit": list(choice.fit),
        "decisions": choice.n,
        "data": validation_source(config),
        "used": config.threshold is None,
    }


def expand_thresholds(policies: tuple[str, ...], thresholds: tuple[float, ...]) -> tuple[str, ...]:
    """``policies`` with each plain confidence-driven one (``gp-ipm``) replaced by one policy per
    threshold (``gp-ipm@0.5``, ``gp-ipm@1.0``, ...; same seeds, paired); the others as given."""
    if not thresholds:
        return tuple(policies)
    out: list[str] = []
    for name in policies:
        base, value = split_policy_name(name)
        if base in INTERACTIVE and value is None:
            out += [f"{base}@{float(t)}" for t in thresholds]
        else:
            out.append(name)
    return tuple(dict.fromkeys(out))


# -- one episode --------------------------------------------------------------------------------
def run_episode(task: Task, models: PolicyModels, config: SortingEvalConfig) -> dict:
    """Run one episode and return its record (see :mod:`ipbench.eval.sorting.report`)."""
    with threadpool_limits(1):
        return _run_episode(task, models, config)


def _run_episode(task: Task, models: PolicyModels, config: SortingEvalConfig) -> dict:
    t0 = time.perf_counter()
    n_objects, dataset = SCENES[task.scene].n_objects, config.perception.dataset
    env = gym.make(
        dataset.env_id,  # the objects and sensor the models were trained on
        scene=task.scene,
        render_mode="rgb_array" if task.video else None,
        max_steps=config.steps_per_object * n_objects + 10,
        depth_noise=dataset.sensor,
        cameras=EVAL_CAMERAS,
        **config.env_options(),
    )
    policy = make_policy(task.policy, models, config.n_views, config.fusion, env.unwrapped.commands)
    recorder = None
    if task.video:
        from ipbench.eval.sorting.overlay import SemanticVideoRecorder

        recorder = SemanticVideoRecorder(env, fps=15)
    policy.reset(task.seed)
    obs, info = env.reset(seed=task.seed)
    skills: Counter = Counter()
    grasp_failures = steps = undone = 0
    terminated = truncated = stopped = False
    # for the loss decomposition: every object's status at reset and after each step, and
    # per step the object its decision aimed at (per decision: mapped in the view it was
    # made on; an inspection's later steps belong to the decision that picked)
    statuses = [[o["status"] for o in info["objects"].values()]]
    aimed: list[int | None] = []  # per decision, parallel to policy.decisions
    step_aims: list[int | None] = []
    step_bins: list[str | None] = []  # the bin each place step sent its object to
    while not (terminated or truncated):
        try:
            action = policy.act(obs, info if task.policy in READS_INFO else None)
        except NothingToSort:
            stopped = True
            break
        aimed += [true_object(d.pixels, info) for d in policy.decisions[len(aimed) :]]
        for decision in policy.decisions:
            if decision.true_category is None:
                decision.true_category = true_category(decision.pixels, info)
        if recorder is not None:
            recorder.update(obs, policy.detections)
        obs, _, terminated, truncated, info = env.step(action)
        step_aims.append(aimed[-1] if aimed else None)
        placing = env.unwrapped.commands[int(action["command"])] == "place_in_bin"
        step_bins.append(CATEGORIES[int(action["bin"])] if placing else None)
        statuses.append([o["status"] for o in info["objects"].values()])
        steps += 1
        undone += bool(info.get("physics_undone"))
        for s in info["skills"]:
            skills[s["name"]] += 1
            grasp_failures += s["name"] == "pick" and not s["success"]
    if recorder is not None:
        recorder.update(obs, [])
        recorder.save(task.video)
    env.close()
    objects = list(info["objects"].values())
    per_category: dict[str, dict[str, int]] = {}
    for o in objects:
        entry = per_category.setdefault(o["category"], {"total": 0, "correct": 0})
        entry["total"] += 1
        entry["correct"] += o["status"] == f"in_bin:{o['category']}"
    correct = sum(e["correct"] for e in per_category.values())
    in_bin = sum(o["status"].startswith("in_bin:") for o in objects)
    threshold = getattr(getattr(policy, "config", None), "threshold", None)
    return {
        "scene": task.scene,
        "policy": task.policy,
        "seed": task.seed,
        "objects": len(objects),
        "correct": correct,
        "accuracy": correct / len(objects),
        "per_category": per_category,
        "wrong_bin": in_bin - correct,
        "left": sum(o["status"] in ("on_table", "in_inspection_area", "in_hand") for o in objects),
        "dropped": sum(o["status"] == "dropped" for o in objects),
        "losses": loss_decomposition(
            [o["category"] for o in objects], statuses, step_aims, step_bins
        ),
        "inspections": sum(d.kind == "inspect" for d in policy.decisions),
        "grasp_failures": int(grasp_failures),
        "physics_undone": int(undone),
        "steps": steps,
        "skills": dict(skills),
        "sim_time_s": round(float(info["sim_time"]), 2),
        "wall_time_s": round(time.perf_counter() - t0, 2),
        "truncated": bool(truncated),
        "stopped": stopped,
        "threshold": threshold,
        "decisions": [d.record() for d in policy.decisions],
        "video": str(task.video) if task.video else None,
    }


# -- executors ------------------------------------------------------------------------------------
def _cost(task: Task) -> float:
    """Expected relative wall time of a task (longest first, :mod:`ipbench.eval.schedule`)."""
    return task_cost(SCENES[task.scene].n_objects, split_policy_name(task.policy)[0])


def _longest_first(tasks: list[Task]) -> list[Task]:
    """The tasks, longest expected episode first (:mod:`ipbench.eval.schedule`)."""
    return longest_first(tasks, _cost)


def _executor(config: SortingEvalConfig) -> Callable:
    """``run(tasks, models, config)`` yielding records: the shared executors
    (:func:`ipbench.eval.episodes.run_episodes`) with this configuration's workers and backend."""

    def run(tasks, models: PolicyModels, config: SortingEvalConfig) -> Iterator[dict]:
        return run_episodes(
            run_episode,
            tasks,
            (models, config),
            workers=config.workers,
            backend=config.backend,
            ray_address=config.ray_address,
            cost=_cost,
            error=SortingEvalError,
        )

    return run


# -- the evaluation -------------------------------------------------------------------------------
def _record_key(record: dict) -> tuple[str, str, int]:
    return (record["scene"], record["policy"], int(record["seed"]))


def run_sorting_eval(
    out: Path, cache: Path, config: SortingEvalConfig | None = None, progress: bool = True
) -> dict:
    """Run (or resume) the evaluation into ``out`` (``config``: default
    ``SortingEvalConfig()``); returns the summary."""
    config = SortingEvalConfig() if config is None else config
    out = Path(out)
    models, choices = prepare_models(cache, config, progress=progress)
    if config.threshold is not None:  # the user's operating point, for every classifier
        models = replace(models, thresholds={c: float(config.threshold) for c in models.thresholds})
    keys = {
        name: None if getattr(models, name) is None else getattr(models, name).key
        for name in ("gp", "svm", "gp_hand", "svm_hand")
    }
    for name in ("pointnet_ensemble", "pointnet_ensemble_hand"):  # only when used: the
        if getattr(models, name) is not None:  # fingerprints of other runs stay as they were
            keys[name] = getattr(models, name).key
    fingerprint = config.fingerprint(json.dumps([keys, models.thresholds], sort_keys=True))
    first_seed = min(config.seeds)
    log = run_grid(
        out,
        fingerprint,
        {
            "policy_version": POLICY_VERSION,
            "thresholds": models.thresholds,
            "validated_thresholds": {
                c: threshold_record(ch, config) for c, ch in sorted(choices.items())
            },
            "model_keys": keys,
            "perception_key": model_key(config.perception, CATEGORIES),
            "dataset_version": DATASET_VERSION,
            "env_status": env_status(config.perception.dataset.env_id),
            "config": asdict(config),
        },
        _record_key,
        [
            (s, p, int(seed))
            for s in config.scenes
            for p in config.policies
            for seed in config.seeds
        ],
        lambda k: Task(
            *k,
            out / "videos" / f"{k[0]}_{k[1]}_seed{k[2]}.mp4"
            if config.video and k[2] == first_seed
            else None,
        ),
        lambda tasks: _executor(config)(tasks, models, config),
        lambda r: f"{r['scene']} {r['policy']} {r['accuracy']:.0%}",
        SortingEvalError,
        progress,
    )
    episodes = [
        e
        for e in log.records()
        if e["scene"] in config.scenes
        and e["policy"] in config.policies
        and e["seed"] in config.seeds
    ]
    sweep = None
    if "gp" in choices:
        c = choices["gp"]
        sweep = ThresholdSweep(
            thresholds=c.thresholds,
            accuracy=np.nan_to_num(c.precision, nan=1.0),
            inspected_fraction=c.inspected,
            chosen=c.threshold,
            source=f"The GP's {c.n} labelled segments of {validation_source(config)}: accuracy "
            "of the labels at or above the threshold (as counted, and under the logistic "
            "calibration fit the rule reads), and the fraction below it (inspected); the "
            f"validated threshold is the lowest on a 0.05 grid whose fitted accuracy reaches "
            f"{c.target_precision:.0%}"
            + ("." if config.threshold is None else f"; this run uses {config.threshold}."),
            fitted=np.nan_to_num(c.fitted_precision, nan=1.0),
        )
    curve = write_curve(episodes, out)
    labels = label_curve(episodes)
    if labels:
        (out / "label_curve.json").write_text(json.dumps(labels, indent=1) + "\n")
    write_report(episodes, out, sweep, sections=[*curve["lines"], *label_curve_lines(labels)])
    return json.loads((out / "summary.json").read_text())
