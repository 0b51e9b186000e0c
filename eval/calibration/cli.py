"""The calibration commands of ``ipbench`` (thesis ch. 4).

ipbench eval calibration [--out DIR] [--seeds A:B] [--robot-seed R] [--workers N]
ipbench calibrate --out FILE [--cameras head,wrist] [--poses N] [--seed S] [--robot-seed R]
                  [--overwrite]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ipbench.eval.cli_options import parse_seeds, run_to_summary, writable

__all__ = ["add_calibrate", "add_eval_calibration", "main_calibrate", "main_eval_calibration"]


def add_calibrate(sub) -> argparse.ArgumentParser:
    """Register ``calibrate`` on ``sub`` (the top-level ``add_subparsers()`` object)."""
    p = sub.add_parser(
        "calibrate",
        help="the robot calibrates its cameras in the simulated cell, writes a calibration file",
        description="The left arm presents a 24 mm checkerboard (9x6 inner corners) to the "
        "head at sampled poses, and the wrist Xtion looks at it from sampled viewpoints; from "
        "the images and the robot's joint readings the routine computes each camera's "
        "intrinsics (cv2.calibrateCamera), the hand-eye transforms (all five methods of "
        "cv2.calibrateHandEye; the file keeps the one with the smallest residual), and the "
        "head's stereo transform (eq. 4.7 and bundle adjustment). Writes FILE (JSON).",
        epilog="example: ipbench calibrate --out calibration.json --cameras wrist --poses 10",
    )
    p.add_argument("--out", type=Path, required=True, help="calibration file to write (JSON)")
    p.add_argument("--cameras", default="head,wrist", help="comma-separated of: head, wrist")
    p.add_argument("--poses", type=int, default=15, help="board views per camera group (>= 3)")
    p.add_argument("--seed", type=int, default=0, help="seed of the pose sampling")
    p.add_argument(
        "--robot-seed",
        type=_robot_seed,
        default=0,
        help="seed of the simulated cell's model errors (camera mounts, PTU bases and zeros, "
        "lenses; ipbench.envs.cell.model_errors), the envs' robot_seed (default 0, the envs' "
        "default cell); 'none': the cell is exactly the nominal model",
    )
    p.add_argument("--overwrite", action="store_true", help="replace an existing FILE")
    return p


def _robot_seed(text: str) -> int | None:
    """``--robot-seed``: an int >= 0, or ``none`` (the nominal cell)."""
    if text.strip().lower() == "none":
        return None
    try:
        seed = int(text)
    except ValueError:
        seed = -1
    if seed < 0:
        raise argparse.ArgumentTypeError(f"{text!r}; valid: an int >= 0, or none")
    return seed


def main_calibrate(args) -> int:
    """Run ``ipbench calibrate``: capture, calibrate, save; errors become clear exits."""
    from ipbench.eval.calibration.calibrate import (
        CalibrationCaptureConfig,
        calibrate_capture,
        capture_views,
    )
    from ipbench.perception.calibration.errors import CalibrationError

    if args.out.exists() and not args.overwrite:
        raise SystemExit(
            f"ipbench: {args.out} exists and was left as it is; pass --overwrite to replace it"
            " or choose another --out"
        )
    try:
        config = CalibrationCaptureConfig(
            cameras=args.cameras,
            poses_per_camera=args.poses,
            seed=args.seed,
            robot_seed=args.robot_seed,
        )
        result = calibrate_capture(capture_views(config))
        path = result.file.save(args.out, overwrite=args.overwrite)
    except (CalibrationError, ValueError) as err:
        raise SystemExit(f"ipbench: {err}") from err
    for camera in result.file.cameras:
        print(f"{camera.name}: reprojection RMS {camera.rms_px:.3f} px")
    for name, entry in result.file.hand_eye.items():
        print(
            f"{name} hand-eye ({entry.method}, {entry.setup}): residual "
            f"{entry.residual_rotation_deg:.3f} deg / {entry.residual_translation_mm:.2f} mm"
        )
    if result.file.stereo is not None:
        print(f"head stereo: bundle-adjusted RMS {result.file.stereo.rms_px:.3f} px")
    print(f"calibration written to {path.resolve()}")
    return 0


def add_eval_calibration(eval_sub) -> argparse.ArgumentParser:
    """Register ``eval calibration`` on ``eval_sub``."""
    p = eval_sub.add_parser(
        "calibration",
        help="hand-eye accuracy against the truth, and the cell's self-calibration (ch. 4), "
        "over seeds",
        description="Per seed: a pose-level study of every hand-eye method against the truth "
        "(3/5/10/20 poses, OpenCV's test noise and a tenth of it, rotation diversity), the "
        "simulated cell with seeded model errors calibrating itself (nominal vs calibrated X "
        "against the truth), and the board reconstructed by the head (true extrinsics, "
        "encoders, dynamic update) and the wrist Xtion. Every figure is reported over the "
        "seeds: mean, median and 95 %% bootstrap interval, and paired differences. Writes "
        "OUT/metrics.json, OUT/calibration.md, OUT/spread.png and OUT/episodes.jsonl (one "
        "record a seed; an interrupted run resumes).",
        epilog="example: ipbench eval calibration --seeds 0:20 --workers 2 --out "
        "results/calibration",
    )
    p.add_argument("--out", type=Path, default=Path("results/calibration"), help="report folder")
    p.add_argument(
        "--seeds",
        default="0:20",
        help="seeds of the trials and pose sampling: A:B (A..B-1) or a comma-separated list",
    )
    p.add_argument(
        "--robot-seed",
        type=_robot_seed,
        default=1,
        help="seed of the simulated cell's model errors, one cell for every seed (default 1); "
        "'none': the nominal cell",
    )
    p.add_argument("--workers", type=int, default=1, help="seeds run in parallel")
    p.add_argument("--backend", default="process", help="process (local workers) or ray")
    p.add_argument("--ray-address", default=None, help="Ray cluster address (--backend ray)")
    return p


def main_eval_calibration(args) -> int:
    """Run ``ipbench eval calibration``."""
    from ipbench.eval.calibration.evaluate import (
        CalibrationEvalConfig,
        CalibrationEvalError,
        run_calibration_eval,
    )
    from ipbench.eval.calibration.study import CalibrationStudyError
    from ipbench.perception.calibration.errors import CalibrationError

    seeds = parse_seeds(args.seeds)

    def run():
        config = CalibrationEvalConfig(
            seeds=seeds,
            robot_seed=args.robot_seed,
            workers=args.workers,
            backend=args.backend,
            ray_address=args.ray_address,
        )
        writable(args.out, "--out")
        return run_calibration_eval(args.out, config)

    def interval(d, digits=3):
        if d is None:
            return "not measured"
        if d["ci_low"] is None:
            return f"{d['mean']:.{digits}f} (one seed)"
        return f"{d['mean']:.{digits}f} [{d['ci_low']:.{digits}f}, {d['ci_high']:.{digits}f}]"

    def rows(metrics):
        rec, n = metrics["reconstruction"], len(metrics["seeds"])
        yield f"{n} seeds; mean [95 % interval] over the seeds"
        for key, text in (
            ("head_true_rmse_mm", "head reconstruction RMSE, true extrinsics"),
            ("head_encoders_rmse_mm", "head reconstruction RMSE, encoders"),
            ("head_dynamic_rmse_mm", "head reconstruction RMSE, dynamic update"),
            ("wrist_robot_rmse_mm", "wrist Xtion in the robot frame, calibrated"),
            ("wrist_robot_nominal_rmse_mm", "wrist Xtion in the robot frame, nominal"),
        ):
            yield f"{text}: {interval(rec.get(key))} mm"
        for cam, c in metrics["self_calibration"].items():
            yield (
                f"self-calibration {cam}: X error nominal "
                f"{interval(c['nominal']['translation_mm'], 1)} mm -> calibrated "
                f"{interval(c['calibrated']['translation_mm'], 2)} mm"
            )

    return run_to_summary(
        run,
        rows,
        f"report written to {(args.out / 'calibration.md').resolve()}",
        (CalibrationError, CalibrationStudyError, CalibrationEvalError),
    )
