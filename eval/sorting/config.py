"""What ``ipbench eval sorting`` runs: its configuration, checked when made, with the
fingerprint that keeps one run folder to one configuration, and one episode to run."""

from __future__ import annotations

import hashlib
import json
from collections import Counter
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import ipbench.envs  # noqa: F401  (registers the environments)
from ipbench.envs.cell.calibration_file import CalibrationFile, CalibrationFileError
from ipbench.envs.cell.extrinsics import ExtrinsicsError, check_extrinsics
from ipbench.envs.sorting_scenes import SCENES
from ipbench.eval.episodes import BACKENDS
from ipbench.eval.perception.evaluate import PerceptionEvalConfig
from ipbench.policies import (
    FUSIONS,
    POLICIES,
    POLICY_VERSION,
    PolicyError,
    check_policy_name,
)

__all__ = ["EPISODE_VERSION", "SortingEvalConfig", "SortingEvalError", "Task"]

EPISODE_VERSION = 2
"""Version of the episode record; part of the run fingerprint."""


class SortingEvalError(ValueError):
    """Bad evaluation settings or output folder; the message says what is valid."""


@dataclass(frozen=True)
class SortingEvalConfig:
    """What ``ipbench eval sorting`` runs.

    Attributes
    ----------
    scenes, policies : names (see ``SCENES`` and :data:`~ipbench.policies.POLICIES`; a policy
        may also be the user's own, ``module:attribute``, :mod:`ipbench.policies.custom`).
    seeds : episode seeds (the same for every policy and scene).
    validation_seeds : seeds of the validation scenes whose first views choose the thresholds
        (:func:`validation_view`); disjoint from ``seeds``.
    target_precision : the threshold is the lowest grid confidence whose labels the
        calibration fit expects at least this often right over the validation views
        (:func:`~ipbench.policies.threshold.choose_threshold`).
    threshold : when set, every confidence-driven policy runs at this threshold instead of
        the validated one (the operating point a user chooses).
    n_views, fusion : inspection views fused per object, and how.
    steps_per_object : the episode's step limit is this x objects + 10.
    workers : parallel episodes (processes, or Ray tasks).
    backend : ``"process"`` or ``"ray"``; ``ray_address``: a cluster (None: a local instance).
    video : one MP4 per policy and scene (its first seed) with the semantic overlay.
    perception : the perception models' training configuration.
    extrinsics, calibration, robot_seed : what the robot knows of its cameras
        (:mod:`ipbench.envs.cell.extrinsics`): ``"true"`` (default) runs the envs as released;
        ``"nominal"`` / ``"calibrated"`` run the test episodes in the true cell of
        ``robot_seed``, the robot believing its nominal model or the ``calibration`` file
        (``ipbench calibrate --robot-seed R --cameras wrist``). Thresholds are validated in the
        released (``"true"``) cell whatever the mode, so that a comparison of cells measures
        what the cameras' errors cost with the same decision rule (validated in each cell, the
        8-seed threshold moved from 0.97 to 0.76 between the true cell and a calibrated one
        and changed the inspections more than the cameras did).
    """

    scenes: tuple[str, ...] = ("uncluttered", "cluttered")
    policies: tuple[str, ...] = ("random", "gp-ipm")
    seeds: tuple[int, ...] = tuple(range(30))
    validation_seeds: tuple[int, ...] = tuple(range(1000, 1040))
    target_precision: float = 0.95
    threshold: float | None = None
    n_views: int = 3
    fusion: str = "majority"
    steps_per_object: int = 6
    workers: int = 1
    backend: str = "process"
    ray_address: str | None = None
    video: bool = False
    perception: PerceptionEvalConfig = field(default_factory=PerceptionEvalConfig)
    extrinsics: str = "true"
    calibration: str | None = None
    robot_seed: int = 0

    def __post_init__(self) -> None:
        try:
            check_extrinsics(self.extrinsics, self.calibration, self.robot_seed)
            if self.calibration is not None:
                CalibrationFile.load(self.calibration)
        except (ExtrinsicsError, CalibrationFileError) as err:
            raise SortingEvalError(f"--extrinsics: {err}") from err
        if self.extrinsics == "true" and self.robot_seed != 0:
            raise SortingEvalError(
                f"robot_seed={self.robot_seed} chooses the true cell of extrinsics 'nominal' or "
                "'calibrated'; with 'true' (the released envs) there is none: drop --robot-seed "
                "or add --extrinsics nominal|calibrated"
            )
        if not self.scenes:
            raise SortingEvalError(f"no scene given; valid: {', '.join(SCENES)}")
        bad = [n for n in self.scenes if n not in SCENES]
        if bad:
            raise SortingEvalError(f"unknown scene {bad[0]!r}; valid: {', '.join(SCENES)}")
        if not self.policies:
            raise SortingEvalError(f"no policy given; valid: {', '.join(POLICIES)}")
        for name in self.policies:
            try:
                check_policy_name(name)
            except PolicyError as err:
                raise SortingEvalError(str(err)) from err
        if len(set(self.policies)) != len(self.policies):
            raise SortingEvalError(f"policies repeat: {', '.join(self.policies)}; give each once")
        if self.threshold is not None and not 0.0 <= self.threshold <= 1.0:
            raise SortingEvalError(f"--threshold must be in [0, 1], got {self.threshold!r}")
        if not self.seeds or any(int(s) < 0 for s in self.seeds):
            raise SortingEvalError(f"seeds must be non-negative integers, got {self.seeds!r}")
        # an episode is keyed by (scene, policy, seed): a repeated seed would run twice and
        # leave two records of one episode in episodes.jsonl (which the report refuses)
        for kind, seeds in (("seeds", self.seeds), ("validation_seeds", self.validation_seeds)):
            counts = Counter(int(s) for s in seeds)
            repeated = sorted(s for s, n in counts.items() if n > 1)
            if repeated:
                once = ",".join(map(str, counts))  # first occurrences, in the given order
                fix = f"--seeds {once}" if kind == "seeds" else f"validation_seeds=({once})"
                raise SortingEvalError(
                    f"{kind} repeat: {', '.join(map(str, repeated))} given more than once (each "
                    f"episode runs once per scene, policy and seed); give each seed once, e.g. "
                    f"{fix}"
                )
        if set(self.seeds) & set(self.validation_seeds):
            raise SortingEvalError(
                "validation seeds overlap the test seeds: "
                f"{sorted(set(self.seeds) & set(self.validation_seeds))[:5]}; pick test seeds "
                f"outside {min(self.validation_seeds)}..{max(self.validation_seeds)}"
            )
        if self.backend not in BACKENDS:
            raise SortingEvalError(f"backend {self.backend!r}; valid: {', '.join(BACKENDS)}")
        if self.ray_address is not None and self.backend != "ray":
            raise SortingEvalError(
                f"a Ray address ({self.ray_address!r}) is used by the ray backend only, and the "
                f"backend is {self.backend!r}; add --backend ray, or drop --ray-address"
            )
        if self.workers < 1:
            raise SortingEvalError(f"workers must be >= 1, got {self.workers}")
        if self.fusion not in FUSIONS:
            raise SortingEvalError(f"fusion {self.fusion!r}; valid: {', '.join(FUSIONS)}")
        if self.steps_per_object < 1:
            raise SortingEvalError("steps_per_object must be >= 1")

    def env_options(self) -> dict:
        """The envs' keyword arguments for :attr:`extrinsics` (none for ``"true"``)."""
        if self.extrinsics == "true":
            return {}
        return {
            "extrinsics": self.extrinsics,
            "calibration": self.calibration,
            "robot_seed": int(self.robot_seed),
        }

    def validation_config(self) -> SortingEvalConfig:
        """This configuration in the released cell (``extrinsics="true"``): the validation
        episodes' (class docstring)."""
        return replace(self, extrinsics="true", calibration=None, robot_seed=0)

    def cell_key(self) -> list:
        """What the robot's cell adds to a fingerprint: nothing for ``"true"`` (so its keys equal
        those of a config without the option), else the mode, the robot seed and the calibration
        file's content hash (not its path)."""
        if self.extrinsics == "true":
            return []
        digest = None
        if self.calibration is not None:
            digest = hashlib.sha256(Path(self.calibration).read_bytes()).hexdigest()[:16]
        return [self.extrinsics, int(self.robot_seed), digest]

    def fingerprint(self, models_key: str) -> str:
        """Hash of everything that changes an episode's result (not seeds, workers, video)."""
        skip = ("scenes", "policies", "seeds", "workers", "backend", "ray_address", "video")
        skip += ("extrinsics", "calibration", "robot_seed")  # as cell_key()
        keep = {k: v for k, v in asdict(self).items() if k not in skip}
        if self.extrinsics != "true":
            keep["cell"] = self.cell_key()
        text = json.dumps(
            [keep, models_key, EPISODE_VERSION, POLICY_VERSION], sort_keys=True, default=str
        )
        return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class Task:
    """One episode to run."""

    scene: str
    policy: str
    seed: int
    video: Path | None = None

    @property
    def key(self) -> tuple[str, str, int]:
        return (self.scene, self.policy, self.seed)
