"""The ``ipbench`` command.

ipbench demo [--out DIR] [--scenes uncluttered,cluttered] [--seed N] [--no-video]
ipbench bench sim [--scene NAME] [--json [FILE]]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

__all__ = ["main", "build_parser"]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ipbench",
        description=(
            "ipbench: a MuJoCo benchmark of robotic interactive perception on the CloPeMa "
            "dual-arm work cell. A robot sorts household objects into bins, and may pick an "
            "object up to look at it again before it decides."
        ),
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    demo = sub.add_parser(
        "demo",
        help="run a scripted sorting episode per scene (ground-truth labels), write MP4s",
        description="Scripted sorting with ground-truth labels: one episode per scene, an MP4 "
        "from the overview camera and demo_summary.json in --out.",
    )
    demo.add_argument("--out", type=Path, default=Path("results"), help="output folder")
    demo.add_argument(
        "--scenes", default="uncluttered,cluttered", help="comma-separated scene names"
    )
    demo.add_argument("--seed", type=int, default=0, help="episode seed")
    demo.add_argument("--no-video", action="store_true", help="skip the MP4s")

    bench = sub.add_parser("bench", help="speed benchmarks that print figures")
    bench_sub = bench.add_subparsers(dest="target", required=True, metavar="TARGET")
    sim = bench_sub.add_parser(
        "sim",
        help="physics, rendering, skill and reset speed of the sorting scene",
        description="Physics steps/s (vs raw mj_step), wrist RGB-D fps at 640x480, head "
        "stereo fps, pick-and-place skill wall time, reset time.",
    )
    sim.add_argument("--scene", default="uncluttered", help="scene to measure")
    sim.add_argument(
        "--json",
        nargs="?",
        const="-",
        default=None,
        metavar="FILE",
        help="also write the figures as one JSON object (to FILE, or stdout with no FILE)",
    )
    return parser


def _scenes(text: str) -> tuple[str, ...]:
    from ipbench.envs.layout import SCENES

    names = tuple(s.strip() for s in text.split(",") if s.strip())
    bad = [s for s in names if s not in SCENES]
    if bad or not names:
        raise SystemExit(
            f"ipbench: unknown scene(s) {', '.join(bad) or '(none)'}; "
            f"valid scenes: {', '.join(SCENES)}"
        )
    return names


def main(argv: list[str] | None = None) -> int:
    os.environ.setdefault("MUJOCO_GL", "egl")
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    args = build_parser().parse_args(argv)
    if args.command == "demo":
        from ipbench.eval.demo import run_demo

        scenes = _scenes(args.scenes)
        try:
            args.out.mkdir(parents=True, exist_ok=True)
            probe = args.out / ".write-test"
            probe.write_text("")
            probe.unlink()
        except OSError as err:
            raise SystemExit(f"ipbench: cannot write to --out {args.out}: {err}") from err
        summary = run_demo(args.out, scenes, seed=args.seed, video=not args.no_video)
        for scene, s in summary.items():
            print(
                f"{scene}: {s['correct']}/{s['objects']} objects in the right bin, "
                f"{s['steps']} steps, {s['wall_time_s']} s"
            )
        print(f"results written to {args.out.resolve()}")
        return 0
    if args.command == "bench" and args.target == "sim":
        from ipbench.eval.bench import bench_sim, report

        _scenes(args.scene)
        figures = bench_sim(args.scene)
        path = None if args.json in (None, "-") else Path(args.json)
        print(report(figures, path))
        if args.json == "-":
            print(json.dumps(figures))
        return 0
    return 2


if __name__ == "__main__":
    sys.exit(main())
