"""``ipbench eval calibration``: how well the robot calibrates its cameras (thesis ch. 4).

Each seed (:func:`run_calibration_seed`) runs three parts, all against the simulator's truth,
and every figure is reported over the seeds (:mod:`.aggregate`, :mod:`.report`), the seeds run
through the episode machinery every task family shares (:mod:`ipbench.eval.episodes`: the
resumable ``episodes.jsonl``, one record a seed; worker processes or Ray):

1. **Hand-eye study** (:mod:`.study`, pose level): every method's X error against
   the truth for 3/5/10/20 poses at OpenCV's regression-test noise and a tenth of it, and the
   rotation-diversity sweep that breaks Tsai; ``metrics.json``'s ``hand_eye`` block is the
   10-pose view at the default noise.
2. **Self-calibration in the simulated cell** (:mod:`.calibrate`): a cell whose true model
   differs from the nominal one (``robot_seed``) calibrates itself from rendered images; per
   camera, the error of the nominal model's X and of the calibrated X against the truth, and
   the intrinsics' error.
3. **Reconstruction** (:mod:`.reconstruction`): the board at random poses, the head at a
   random pan/tilt each time, triangulated with the calibrated cameras carried by the
   encoders, or updated from tracked features (the dynamic update, with its consistency
   check) on another board pose than the one scored; the wrist Xtion's
   corners from its noisy depth (:mod:`.wrist_reconstruction`), as board shape and carried into
   the robot frame through the calibrated and the nominal chain (thesis Table 4.4).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import cv2
import numpy as np
from threadpoolctl import threadpool_limits

from ipbench.eval.calibration.aggregate import aggregate
from ipbench.eval.calibration.calibrate import (
    CalibrationCaptureConfig,
    CellCalibration,
    calibrate_capture,
    calibration_truth,
    capture_views,
)
from ipbench.eval.calibration.reconstruction import THESIS, reconstruct_head
from ipbench.eval.calibration.report import calibration_markdown, write_spread_figure
from ipbench.eval.calibration.study import HandEyeStudyConfig, metrics_view, run_hand_eye_study
from ipbench.eval.calibration.wrist_reconstruction import reconstruct_wrist
from ipbench.eval.episodes import BACKENDS, check_out, run_episodes, run_grid
from ipbench.perception.calibration.poses import rotation_angle_deg, translation_error_mm

__all__ = [
    "RECORD_VERSION",
    "CalibrationEvalConfig",
    "CalibrationEvalError",
    "reconstruction_metrics",
    "run_calibration_eval",
    "run_calibration_seed",
    "self_calibration",
]

RECORD_VERSION = 3
"""Version of a seed's record (part of the run fingerprint): 3 scores the head on a board
shown after the dynamic update, checks the update, and measures no view with a corner found
off the board's plane."""


def _error(a: np.ndarray, b: np.ndarray) -> dict[str, float]:
    return {
        "rotation_deg": float(rotation_angle_deg(a, b)),
        "translation_mm": float(translation_error_mm(a, b)),
    }


def self_calibration(
    seed: int = 0, robot_seed: int = 1, poses: int = 15
) -> tuple[dict, CellCalibration]:
    """The cell of ``robot_seed`` calibrates itself (pose sampling ``seed``): per camera, the
    nominal and calibrated X errors against the truth, the method kept, the intrinsics'
    error (|K - K_true| / fx for fx, fy, cx, cy) and the stereo transform's error; and the
    calibration itself."""
    config = CalibrationCaptureConfig(poses_per_camera=poses, seed=seed, robot_seed=robot_seed)
    capture = capture_views(config)
    result = calibrate_capture(capture)
    truth = calibration_truth(capture)
    nominal_capture = capture_views(
        CalibrationCaptureConfig(poses_per_camera=3, seed=seed, robot_seed=None)
    )  # the same gaze and cell without errors: what the robot's model believes
    nominal = calibration_truth(nominal_capture)
    cameras = {}
    for name, entry in result.file.hand_eye.items():
        K, K_true = result.file.camera(name).K, truth.K[name]
        cameras[name] = {
            "setup": entry.setup,
            "method": entry.method,
            "nominal": _error(nominal.X[name], truth.X[name]),
            "calibrated": _error(entry.X, truth.X[name]),
            "intrinsics_error_fraction": (
                np.abs(K - K_true)[[0, 1, 0, 1], [0, 1, 2, 2]] / K_true[0, 0]
            ).tolist(),
            "reprojection_rms_px": result.file.camera(name).rms_px,
        }
    out = {"seed": seed, "robot_seed": robot_seed, "poses": poses, "cameras": cameras}
    if result.file.stereo is not None and truth.left_to_right is not None:
        out["stereo"] = {
            "nominal": _error(nominal.left_to_right, truth.left_to_right),
            "calibrated": _error(result.file.stereo.left_to_right, truth.left_to_right),
        }
    out["seconds"] = round(capture.seconds, 1)
    return out, result


@dataclass(frozen=True)
class CalibrationEvalConfig:
    """What ``ipbench eval calibration`` runs.

    Attributes
    ----------
    seeds : one run of the routine per seed (its hand-eye study, board poses and gazes);
        every figure is reported as a distribution over them.
    robot_seed : the simulated cell's model errors (one cell for every seed; None: the
        nominal cell).
    poses : board views per camera group of the self-calibration.
    reconstructions : board poses of each reconstruction (head and wrist).
    study : the hand-eye study (its ``seed`` is replaced by each seed); None: the full study.
    workers, backend, ray_address : seeds in parallel (:mod:`ipbench.eval.episodes`).
    confidence : coverage of the bootstrap intervals.
    """

    seeds: tuple[int, ...] = tuple(range(20))
    robot_seed: int | None = 1
    poses: int = 15
    reconstructions: int = 10
    study: HandEyeStudyConfig | None = None
    workers: int = 1
    backend: str = "process"
    ray_address: str | None = None
    confidence: float = 0.95

    def __post_init__(self) -> None:
        seeds = tuple(self.seeds)
        if not seeds or any(not isinstance(s, (int, np.integer)) or s < 0 for s in seeds):
            raise CalibrationEvalError(f"seeds must be integers >= 0, got {self.seeds!r}")
        if len(set(seeds)) != len(seeds):
            raise CalibrationEvalError(f"seeds repeat in {seeds}; give each seed once")
        object.__setattr__(self, "seeds", tuple(int(s) for s in seeds))
        if self.robot_seed is not None and self.robot_seed < 0:
            raise CalibrationEvalError(f"robot_seed is {self.robot_seed}; valid: None or >= 0")
        for name, least in (("poses", 3), ("reconstructions", 1), ("workers", 1)):
            if getattr(self, name) < least:
                raise CalibrationEvalError(f"{name} is {getattr(self, name)}; valid: >= {least}")
        if self.backend not in BACKENDS:
            raise CalibrationEvalError(f"backend {self.backend!r}; valid: {', '.join(BACKENDS)}")
        if not 0.0 < self.confidence < 1.0:
            raise CalibrationEvalError(f"confidence is {self.confidence}; valid: 0 < c < 1")

    def fingerprint(self) -> str:
        """Hash of everything that changes a seed's record (not which seeds, nor where)."""
        where = ("seeds", "workers", "backend", "ray_address", "confidence")
        keep = {k: v for k, v in asdict(self).items() if k not in where}
        text = json.dumps([keep, RECORD_VERSION], sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


class CalibrationEvalError(ValueError):
    """Bad evaluation settings or output folder; the message says what is valid."""


def run_calibration_seed(seed: int, config: CalibrationEvalConfig) -> dict:
    """One seed's record: the hand-eye study, the self-calibration and the reconstruction
    (the metrics of one run of the routine, as :func:`~.report.seed_markdown` reports them)."""
    threads = cv2.getNumThreads()
    # OpenCV's parallel loops (corner search, calibrateCamera) add up in an order that varies
    # run to run, and the figures with it in their last bits: one thread makes a seed's record
    # the same every time
    cv2.setNumThreads(1)
    try:
        with threadpool_limits(1):
            study = replace(config.study or HandEyeStudyConfig(), seed=seed)
            result = run_hand_eye_study(study)
            record = {"seed": seed, **metrics_view(result), "hand_eye_study": result}
            record["self_calibration"], calibration = self_calibration(
                seed=seed, robot_seed=config.robot_seed, poses=config.poses
            )
            record["reconstruction"] = reconstruction_metrics(
                calibration, config.robot_seed, seed=seed, poses=config.reconstructions
            )
    finally:
        cv2.setNumThreads(threads)
    return json.loads(json.dumps(record, default=_plain))  # what the log will read back


def _plain(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not JSON-serialisable")


def run_calibration_eval(
    out: Path, config: CalibrationEvalConfig = CalibrationEvalConfig(), progress: bool = True
) -> dict:
    """Run (or resume) every seed of ``config`` into ``out`` (``episodes.jsonl``, one record a
    seed), then write ``metrics.json`` (:func:`~.aggregate.aggregate` of the seeds in the
    folder's log that ``config`` asks for), ``calibration.md`` and ``spread.png``; return the
    metrics."""
    out = Path(out)
    fingerprint = config.fingerprint()
    check_out(out, fingerprint, CalibrationEvalError)
    log = run_grid(
        out,
        fingerprint,
        {"config": asdict(config), "record_version": RECORD_VERSION},
        lambda r: int(r["seed"]),
        config.seeds,
        int,
        lambda seeds: run_episodes(
            run_calibration_seed,
            seeds,
            (config,),
            workers=config.workers,
            backend=config.backend,
            ray_address=config.ray_address,
            error=CalibrationEvalError,
        ),
        lambda r: f"seed {r['seed']}",
        CalibrationEvalError,
        progress,
    )
    records = [r for r in log.records() if int(r["seed"]) in set(config.seeds)]
    metrics = aggregate(records, config.robot_seed, config.confidence)
    first = min(records, key=lambda r: int(r["seed"]))
    (out / "metrics.json").write_text(json.dumps(metrics, indent=1) + "\n")
    (out / "calibration.md").write_text(calibration_markdown(metrics, first))
    write_spread_figure(metrics, out / "spread.png")
    return metrics


def reconstruction_metrics(
    calibration: CellCalibration, robot_seed: int | None, seed: int = 0, poses: int = 10
) -> dict:
    """``{"head_dynamic_rmse_mm", "head_encoders_rmse_mm", "wrist_rmse_mm",
    "wrist_robot_rmse_mm", "wrist_robot_nominal_rmse_mm", "tables", ...}``: the metrics.json
    ``reconstruction`` block, with our figures beside the thesis' in ``tables``. A camera group
    the calibration lacks gives None."""
    head = reconstruct_head(calibration, robot_seed, seed, poses) if (
        "head_left" in calibration.intrinsics) else None  # fmt: skip
    wrist = reconstruct_wrist(calibration, robot_seed, seed, poses) if (
        "wrist" in calibration.intrinsics) else None  # fmt: skip

    def rmse(method):
        return None if head is None or method not in head["methods"] else (
            head["methods"][method]["rmse_mm"])  # fmt: skip

    def robot(chain):
        return None if wrist is None else wrist["robot_frame"][chain]["rmse_mm"]

    tables = {
        "table_4_2_head_axis_residual_mm": {
            "ours": None
            if head is None
            else {m: s["axis_mean_abs_residual_mm"] for m, s in head["methods"].items()},
            "thesis_max": THESIS["head_axis_residual_max_mm"],
        },  # fmt: skip
        "table_4_3_head_rmse_mm": {
            "ours": None if head is None else {m: s["rmse_mm"] for m, s in head["methods"].items()},
            "thesis": THESIS["head_rmse_mm"],
        },
        "table_4_4_xtion_rmse_mm": {
            "ours": None if wrist is None else wrist["rmse_mm"],
            "thesis": THESIS["xtion_rmse_mm"],
        },
        # the thesis' figure is in the robot frame (a real arm's kinematic error included)
        "table_4_4_xtion_robot_frame_rmse_mm": {
            "ours": None if wrist is None else {c: robot(c) for c in wrist["robot_frame"]},
            "thesis": THESIS["xtion_rmse_mm"],
        },
        "table_4_5_kinect_v2_rmse_mm": {"ours": None, "thesis": THESIS["kinect_v2_rmse_mm"]},
    }
    return {
        # the dynamic update of each camera: updating the left one and chaining the right one
        # through the encoders keeps the encoders' relative pose, so corner distances are the
        # encoders' ("dynamic", reported beside)
        "head_dynamic_rmse_mm": rmse("dynamic_both"),
        "head_dynamic_left_chain_rmse_mm": rmse("dynamic"),
        "head_encoders_rmse_mm": rmse("encoders"),
        "wrist_rmse_mm": None if wrist is None else wrist["rmse_mm"],
        "wrist_robot_rmse_mm": robot("calibrated"),
        "wrist_robot_nominal_rmse_mm": robot("nominal"),
        "tables": tables,
        "head": head,
        "wrist": wrist,
    }
