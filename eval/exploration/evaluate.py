"""``ipbench eval exploration``: active binocular exploration as episodes (thesis Tables 3.2/3.3).

Policies x feature types x scenes x seeds, the same seeds for every policy (paired). Steps:

1. The recognition database of each feature type is loaded from the cache or built from views
   the head takes of each database object alone (:mod:`ipbench.eval.capture.exploration_database`).
2. Episodes of an exploration id (``ipbench/Exploration-v0`` by default) run through the
   shared machinery
   (:mod:`ipbench.eval.episodes`: the resumable ``episodes.jsonl``, ``run.json``'s fingerprint,
   serial / process / Ray executors), each record written as soon as it finishes.
3. ``summary.json``, ``exploration.md`` and ``recall.png``
   (:mod:`ipbench.eval.exploration.report`) over every episode in the folder (runs of other
   scenes, policies, feature types or seeds with the same settings add up), and optionally
   one MP4 per policy, feature and scene (its first seed) of the left head view with the
   hypotheses, the fixation and the inhibited places (:mod:`ipbench.eval.exploration.video`).
"""

from __future__ import annotations

import hashlib
import json
import time
from collections import Counter
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import gymnasium as gym
import numpy as np
from threadpoolctl import threadpool_limits

import ipbench.envs  # registers the environments
from ipbench.envs.exploration import ExplorationConfig
from ipbench.envs.exploration_scene import LEVELS
from ipbench.envs.sensors import SensorError
from ipbench.envs.sensors.foveation import fovea_window
from ipbench.eval.capture.exploration_database import DatabaseCaptureConfig, load_or_build_database
from ipbench.eval.episodes import BACKENDS, check_out, run_episodes, run_grid
from ipbench.eval.exploration.missed import MissedTracker, known_objects
from ipbench.eval.exploration.sightings import look_sightings
from ipbench.perception.features2d import FEATURE_TYPES
from ipbench.perception.object_database import ObjectDatabase
from ipbench.perception.saliency import INHIBITION_RADIUS_RAD
from ipbench.policies.exploration import (
    EXPLORATION_ABLATIONS,
    EXPLORATION_POLICIES,
    EXPLORATION_POLICY_VERSION,
    READS_INFO,
    make_exploration_policy,
)

__all__ = [
    "ENV_ID",
    "EPISODE_VERSION",
    "ExplorationEvalConfig",
    "ExplorationEvalError",
    "ExplorationTask",
    "run_exploration_episode",
    "run_exploration_eval",
]

ENV_ID = "ipbench/Exploration-v0"
"""The exploration id run by default."""
EPISODE_VERSION = 1
"""Version of the episode record (part of the run fingerprint)."""


class ExplorationEvalError(ValueError):
    """Bad evaluation settings or output folder; the message says what is valid."""


@dataclass(frozen=True)
class ExplorationEvalConfig:
    """What ``ipbench eval exploration`` runs.

    Attributes
    ----------
    scenes, policies, features : names (:data:`~ipbench.envs.exploration_scene.LEVELS`,
        :data:`~ipbench.policies.exploration.EXPLORATION_POLICIES`,
        :data:`~ipbench.perception.features2d.FEATURE_TYPES`).
    seeds : episode seeds, the same for every policy and feature (paired); the thesis used 3
        random home positions per scene, we default to 10.
    saccade_budget : saccades before an episode is cut (the env's truncation).
    env_id : the exploration id (:data:`ipbench.envs.EXPLORATION_IDS`).
    head_size : (height, width) px each head camera renders; None: the id's. The recognition
        database is captured at the same size (``database.head_size`` follows it: one cache
        entry per size), with the id's objects (``database.upright_prints`` follows them).
    fovea_factor : 1, or the foveation of the head cameras
        (:mod:`ipbench.envs.sensors.foveation`); None: the id's.
    workers, backend, ray_address : parallel episodes (:mod:`ipbench.eval.episodes`).
    video : one MP4 per policy, feature and scene (its first seed).
    database : how the recognition database's views are captured.
    """

    scenes: tuple[str, ...] = tuple(LEVELS)
    policies: tuple[str, ...] = EXPLORATION_POLICIES
    features: tuple[str, ...] = ("sift",)
    seeds: tuple[int, ...] = tuple(range(10))
    saccade_budget: int = 30
    env_id: str = ENV_ID
    head_size: tuple[int, int] | None = None
    fovea_factor: int | None = None
    workers: int = 1
    backend: str = "process"
    ray_address: str | None = None
    video: bool = False
    database: DatabaseCaptureConfig = field(default_factory=DatabaseCaptureConfig)

    def __post_init__(self) -> None:
        for kind, names, valid in (
            ("scene", self.scenes, tuple(LEVELS)),
            ("policy", self.policies, (*EXPLORATION_POLICIES, *EXPLORATION_ABLATIONS)),
            ("feature type", self.features, FEATURE_TYPES),
        ):
            bad = [n for n in names if n not in valid] or ([] if names else ["(none)"])
            if bad:
                raise ExplorationEvalError(f"unknown {kind} {bad[0]!r}; valid: {', '.join(valid)}")
            if len(set(names)) != len(names):
                raise ExplorationEvalError(f"a {kind} is given twice in {', '.join(names)}")
        if not self.seeds or any(int(s) < 0 for s in self.seeds):
            raise ExplorationEvalError(f"seeds must be non-negative integers, got {self.seeds!r}")
        repeated = sorted(s for s, n in Counter(self.seeds).items() if n > 1)
        if repeated:
            raise ExplorationEvalError(
                f"seeds repeat: {', '.join(map(str, repeated))}; give each seed once"
            )
        if self.env_id not in ipbench.envs.EXPLORATION_IDS:
            valid = ", ".join(ipbench.envs.EXPLORATION_IDS)
            raise ExplorationEvalError(f"unknown exploration id {self.env_id!r}; valid: {valid}")
        fixed = {**vars(ExplorationConfig()), **ipbench.envs.EXPLORATION_IDS[self.env_id]}
        size = tuple(fixed["head_size"] if self.head_size is None else self.head_size)
        if len(size) != 2 or not all(isinstance(v, int) and v > 0 for v in size):
            raise ExplorationEvalError(
                f"head_size must be (height, width) positive ints (px), got {self.head_size!r}"
            )
        object.__setattr__(self, "head_size", size)
        factor = fixed["fovea_factor"] if self.fovea_factor is None else self.fovea_factor
        object.__setattr__(self, "fovea_factor", factor)
        if factor != 1:
            try:
                fovea_window(*size, factor)
            except SensorError as err:
                raise ExplorationEvalError(str(err)) from None
        upright = fixed["objects"].upright_prints
        if (self.database.head_size, self.database.upright_prints) != (size, upright):
            # the database views are taken as the episodes' cameras see the episodes' objects
            object.__setattr__(
                self, "database", replace(self.database, head_size=size, upright_prints=upright)
            )
        if self.saccade_budget < 1:
            raise ExplorationEvalError(f"saccade_budget must be >= 1, got {self.saccade_budget}")
        if self.backend not in BACKENDS:
            raise ExplorationEvalError(f"backend {self.backend!r}; valid: {', '.join(BACKENDS)}")
        if self.ray_address is not None and self.backend != "ray":
            raise ExplorationEvalError(
                f"a Ray address ({self.ray_address!r}) is used by the ray backend only; add "
                "--backend ray, or drop --ray-address"
            )
        if self.workers < 1:
            raise ExplorationEvalError(f"workers must be >= 1, got {self.workers}")

    def fingerprint(self) -> str:
        """Hash of everything that changes an episode's result (not which episodes run, nor
        where, nor videos)."""
        drop = ("scenes", "policies", "features", "seeds", "workers", "backend", "ray_address")
        keep = {k: v for k, v in asdict(self).items() if k not in (*drop, "video")}
        keep["database"] = self.database.key()
        if (keep["env_id"], keep["fovea_factor"]) == (ENV_ID, 1):  # the first runs' settings:
            del keep["env_id"], keep["fovea_factor"]  # the fingerprint they always had
        text = json.dumps(
            [keep, EPISODE_VERSION, EXPLORATION_POLICY_VERSION], sort_keys=True, default=str
        )
        return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class ExplorationTask:
    """One episode to run."""

    scene: str
    policy: str
    feature: str
    seed: int
    video: Path | None = None


def _record_key(record: dict) -> tuple:
    return (record["scene"], record["policy"], record["feature"], int(record["seed"]))


def _cost(task: ExplorationTask) -> float:
    """Expected relative wall time (longest first): objects to recognise, times a slower
    detector's factor (KAZE's nonlinear scale space is the slowest; bench exploration)."""
    factor = {"kaze": 3.0, "sift": 1.5}.get(task.feature, 1.0)
    return LEVELS[task.scene].n_table * factor


# -- one episode ---------------------------------------------------------------------------------
def run_exploration_episode(
    task: ExplorationTask, databases: dict[str, ObjectDatabase], config: ExplorationEvalConfig
) -> dict:
    """Run one episode and return its record (schema: :mod:`ipbench.eval.exploration.report`)."""
    with threadpool_limits(1):
        import cv2

        cv2.setNumThreads(1)
        return _run_episode(task, databases, config)


def _project(points: list[np.ndarray], K: np.ndarray, pose: np.ndarray) -> list[np.ndarray]:
    """Image points (2,) of world ``points`` in front of a camera (``K``, world-from-camera
    ``pose``)."""
    out = []
    for p in points:
        c = pose[:3, :3].T @ (np.asarray(p, float) - pose[:3, 3])
        if c[2] > 1e-6:
            out.append((K @ (c / c[2]))[:2])
    return out


def _video_frame(recorder, obs: dict, policy) -> None:
    K, pose = obs["head_left_K"], obs["head_left_pose"]
    seen = policy.last_look
    hypotheses = []
    if seen is not None:
        verified = {(c.label, tuple(np.round(c.left_centre, 3))) for c in seen.candidates}
        for h in seen.recognition_left.hypotheses:
            key = (h.class_name, tuple(np.round(h.centre, 3)))
            outline = (np.asarray(h.outline, float) + 0.5) / seen.scale - 0.5  # image px
            hypotheses.append((h.class_name, outline, key in verified))
    ior = getattr(policy, "inhibition", None)
    rays = [] if ior is None else [pose[:3, 3] + d for d in ior.directions]
    reported = [
        (label, xy)
        for label, xy in zip(
            [r[0] for r in policy.reported],
            _project([r[1] for r in policy.reported], K, pose),
            strict=False,
        )
    ]
    recorder.add(obs["head_left"], hypotheses, K[:2, 2].copy(), _project(rays, K, pose), reported)


def _run_episode(
    task: ExplorationTask, databases: dict[str, ObjectDatabase], config: ExplorationEvalConfig
) -> dict:
    t0 = time.perf_counter()
    env = gym.make(
        config.env_id,
        scene=task.scene,
        head_size=tuple(config.head_size),
        fovea_factor=config.fovea_factor,
        saccade_budget=config.saccade_budget,
    )
    policy = make_exploration_policy(task.policy, databases[task.feature])
    recorder = None
    if task.video:
        from ipbench.eval.exploration.video import ExplorationVideoRecorder

        recorder = ExplorationVideoRecorder(fps=2)
    policy.reset(task.seed)
    obs, info = env.reset(seed=task.seed)
    n_database = int(info["score"]["not_found"])
    objects = info["objects"]
    recall, sim = [0.0], [0.0]
    steps = 0
    localisation: list[float] = []
    mistaken: set[str] = set()  # instances an earlier report took for another class
    recovered = 0
    reasons: Counter = Counter()
    terminated = truncated = False
    sightings: list[list] = []
    false_candidates = looks = 0
    tracker = MissedTracker(objects)
    found_instances: set[str] = set()
    while not (terminated or truncated):
        known = known_objects(policy)
        action = policy.act(obs, info if task.policy in READS_INFO else None)
        tracker.look(policy, obs, info, known)
        seen = look_sightings(policy.last_look, obs, info, config.fovea_factor)
        sightings += [[e, r, p] for e, r, p in seen.sightings]
        false_candidates += seen.false_candidates
        looks += 1
        if recorder is not None:
            _video_frame(recorder, obs, policy)
        obs, _, terminated, truncated, info = env.step(action)
        steps += 1
        outcome = info["report"]
        if outcome is not None:
            if outcome["kind"] == "true_positive":
                true = np.asarray(objects[outcome["instance"]]["position"])
                reported = np.asarray(action["report"]["position"], float)
                localisation.append(round(1000 * float(np.linalg.norm(reported - true)), 2))
                recovered += outcome["instance"] in mistaken
                found_instances.add(outcome["instance"])
            else:
                reasons[outcome["reason"]] += 1
                if outcome["reason"] == "wrong_class":
                    mistaken.add(outcome["instance"])
        if not terminated:  # every step but "done" is a saccade
            found = info["score"]["true_positives"]
            recall.append(found / n_database if n_database else 1.0)
            sim.append(sim[-1] + float(info["saccade_s"]))
    if recorder is not None:
        recorder.add(obs["head_left"], [], obs["head_left_K"][:2, 2].copy(), [], [])
        recorder.save(task.video)
    env.close()
    to_all = next((k for k, r in enumerate(recall) if r >= 1.0), None)
    score = info["score"]
    return {
        "scene": task.scene,
        "policy": task.policy,
        "feature": task.feature,
        "seed": task.seed,
        "n_database": n_database,
        "true_positives": int(score["true_positives"]),
        "false_positives": int(score["false_positives"]),
        "not_found": int(score["not_found"]),
        "performance": float(score["performance"]),
        "recovered": int(recovered),
        "fp_reasons": {
            r: int(reasons[r]) for r in ("wrong_class", "already_reported", "nothing_there")
        },
        "saccades": int(info["saccades"]),
        "sim_time_s": round(sim[-1], 3),
        "wall_time_s": round(time.perf_counter() - t0, 2),
        "steps": steps,
        "recall_curve": [round(r, 4) for r in recall],
        "saccades_to_all": to_all,
        "sim_s_to_all": None if to_all is None else round(sim[to_all], 3),
        "refixation_rate": refixation_rate(policy.fixations),
        "localisation_mm": localisation,
        "halted": bool(terminated),
        "truncated": bool(truncated),
        "video": str(task.video) if task.video else None,
        "cycle_s": round((time.perf_counter() - t0) / max(steps, 1), 3),
        "sightings": sightings,
        "false_candidates": false_candidates,
        "looks": looks,
        "missed": tracker.missed(found_instances, mistaken),
    }


def refixation_rate(fixations, radius_rad: float = INHIBITION_RADIUS_RAD) -> float:
    """Share of the saccades (vergence corrections and halts aside) that land within
    ``radius_rad`` (inhibition of return's radius) of a place already fixated."""
    axes = [np.asarray(f.axis, float) for f in fixations]
    moves = [k for k in range(1, len(axes)) if fixations[k - 1].kind not in ("verge", "halt")]
    if not moves:
        return 0.0
    cos = np.cos(radius_rad)
    again = sum(any(float(axes[k] @ axes[j]) >= cos for j in range(k)) for k in moves)
    return round(again / len(moves), 4)


# -- the evaluation -------------------------------------------------------------------------------
def run_exploration_eval(
    out: Path,
    cache: Path,
    config: ExplorationEvalConfig = ExplorationEvalConfig(),
    progress: bool = True,
) -> dict:
    """Run (or resume) the evaluation into ``out``; returns the summary."""
    from ipbench.eval.exploration.report import write_exploration_report

    out = Path(out)
    fingerprint = config.fingerprint()
    check_out(out, fingerprint, ExplorationEvalError)
    databases = {
        f: load_or_build_database(f, Path(cache), config.database, progress)
        for f in config.features
    }
    first = min(config.seeds)
    log = run_grid(
        out,
        fingerprint,
        {
            "env": config.env_id,
            "env_status": ipbench.envs.env_status(config.env_id),
            "policy_version": EXPLORATION_POLICY_VERSION,
            "databases": {f: d.stats() for f, d in databases.items()},
            "config": asdict(config),
        },
        _record_key,
        [
            (scene, policy, feature, int(seed))
            for scene in config.scenes
            for policy in config.policies
            for feature in config.features
            for seed in config.seeds
        ],
        lambda k: ExplorationTask(
            *k,
            out / "videos" / f"{k[0]}_{k[1]}_{k[2]}_seed{k[3]}.mp4"
            if config.video and k[3] == first
            else None,
        ),
        lambda tasks: run_episodes(
            run_exploration_episode,
            tasks,
            (databases, config),
            workers=config.workers,
            backend=config.backend,
            ray_address=config.ray_address,
            cost=_cost,
            error=ExplorationEvalError,
        ),
        lambda r: f"{r['scene']} {r['policy']} {r['feature']} {r['performance']:.0%}",
        ExplorationEvalError,
        progress,
    )
    # the report covers every episode in the folder (all of one fingerprint): a benchmark run
    # in parts (a feature type at a time, say) ends with one report of all of them
    h, w = config.head_size
    cameras = f"{w}x{h} px" + (
        f", foveated {config.fovea_factor}x" if config.fovea_factor > 1 else ""
    )
    title = f"Active exploration on {config.env_id} ({cameras}): database objects found"
    write_exploration_report(log.records(), out, config.saccade_budget, title)
    return json.loads((out / "summary.json").read_text())
