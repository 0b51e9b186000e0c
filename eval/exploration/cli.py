"""The exploration commands of ``ipbench`` (thesis ch. 3).

ipbench eval exploration [--scenes simple,medium,complex] [--policies ...] [--features sift,...]
                         [--seeds A:B] [--budget N] [--env ID] [--head-size HxW]
                         [--fovea-factor F] [--workers N] [--video] [--out DIR] [--cache DIR]
ipbench bench exploration [--features ...] [--cache DIR] [--json [FILE]]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ipbench.eval.cli_options import (
    add_json_option,
    parse_names,
    parse_seeds,
    parse_size,
    print_figures,
    run_to_summary,
    writable,
)

__all__ = ["add_bench_exploration", "add_eval_exploration", "main_exploration"]


def add_eval_exploration(eval_sub) -> argparse.ArgumentParser:
    """Register ``eval exploration`` on ``eval_sub`` (an ``add_subparsers()`` object)."""
    p = eval_sub.add_parser(
        "exploration",
        help="explore table scenes with the stereo head and report objects (thesis Tables 3.2/3.3)",
        description="Runs every exploration policy with every feature type on every scene for "
        "every seed of an exploration id (the same seeds for all: paired). The "
        "recognition database of each feature type is captured by the head on first use and "
        "cached in --cache. Each finished episode is appended to OUT/episodes.jsonl, so an "
        "interrupted run resumes. Writes OUT/summary.json, OUT/exploration.md, OUT/recall.png "
        "and (--video) MP4s of the left head view.",
        epilog="example: ipbench eval exploration --scenes simple --policies "
        "active-vision,random-gaze --seeds 0:3",
    )
    p.add_argument(
        "--scenes", default="simple,medium,complex", help="comma-separated scenes: {LEVELS}"
    )
    p.add_argument(
        "--policies",
        default="active-vision,random-gaze,raster-scan,oracle-gaze",
        help="comma-separated: {EXPLORATION_POLICIES}; ablations: {EXPLORATION_ABLATIONS}",
    )
    p.add_argument("--features", default="sift", help="comma-separated feature types: {FEATURES}")
    p.add_argument(
        "--seeds", default="0:10", help="episode seeds: A:B (A..B-1) or a comma-separated list"
    )
    p.add_argument("--budget", type=int, default=30, help="saccades before an episode is cut")
    p.add_argument(
        "--env",
        default="ipbench/Exploration-v0",
        help="the exploration id: {EXPLORATION_IDS}",
    )
    p.add_argument(
        "--head-size",
        default=None,
        help="HEIGHTxWIDTH px each head camera renders (default: the id's, 680x1024 for v0, "
        "3264x4928 for v1, the thesis' Nikon D5100); the database is captured at the same size",
    )
    p.add_argument(
        "--fovea-factor",
        type=int,
        default=None,
        help="1: whole frames; F > 1: foveated cameras, the field downsampled F times and its "
        "central 1/F at full resolution (default: the id's, 1 for v0, 4 for v1)",
    )
    p.add_argument("--workers", type=int, default=1, help="episodes run in parallel")
    p.add_argument("--backend", default="process", help="one of {BACKENDS}")
    p.add_argument("--ray-address", default=None, help="Ray cluster address (--backend ray)")
    p.add_argument("--video", action="store_true", help="an MP4 per policy, feature and scene")
    p.add_argument("--out", type=Path, default=Path("results/exploration"), help="report folder")
    p.add_argument(
        "--cache", type=Path, default=Path("results/cache"), help="database cache folder"
    )
    return p


def add_bench_exploration(bench_sub) -> argparse.ArgumentParser:
    """Register ``bench exploration`` on ``bench_sub``."""
    p = bench_sub.add_parser(
        "exploration",
        help="stereo rendering fps and the saccade cycle's wall time per feature type",
        description="Complex scene of the id at its head size, one core: stereo pairs/s, and "
        "the active-vision policy's cycle (render pair, features, recognition, stereo, "
        "decision) per feature type (databases from --cache, captured if missing). Figures of "
        "another id than v0 end in its version (e.g. cycle_s_v1).",
        epilog="example: ipbench bench exploration --features sift,orb",
    )
    p.add_argument("--features", default="sift,kaze,akaze,orb", help="feature types: {FEATURES}")
    p.add_argument(
        "--env", default="ipbench/Exploration-v0", help="the exploration id: {EXPLORATION_IDS}"
    )
    p.add_argument(
        "--head-size", default=None, help="HEIGHTxWIDTH px of each head camera (default: the id's)"
    )
    p.add_argument(
        "--cache", type=Path, default=Path("results/cache"), help="database cache folder"
    )
    add_json_option(p)
    return p


def main_exploration(args) -> int:
    """Run ``eval exploration`` or ``bench exploration``."""
    from ipbench.perception.features2d import FEATURE_TYPES

    features = parse_names(args.features, FEATURE_TYPES, "feature type(s)")
    if args.command == "bench":
        from ipbench.eval.bench.exploration import bench_exploration
        from ipbench.eval.bench.sim import report
        from ipbench.eval.exploration.evaluate import ExplorationEvalError

        writable(args.cache, "--cache")
        try:
            size = None if args.head_size is None else parse_size(args.head_size)
            figures = bench_exploration(args.cache, features, env_id=args.env, head_size=size)
        except ExplorationEvalError as err:
            raise SystemExit(f"ipbench: {err}") from None
        print_figures(figures, args.json, report)
        return 0
    from ipbench.envs.exploration_scene import LEVELS
    from ipbench.eval.exploration.evaluate import (
        ExplorationEvalConfig,
        ExplorationEvalError,
        run_exploration_eval,
    )
    from ipbench.policies.exploration import EXPLORATION_ABLATIONS, EXPLORATION_POLICIES

    def run():
        config = ExplorationEvalConfig(
            scenes=parse_names(args.scenes, tuple(LEVELS), "scene(s)"),
            policies=parse_names(
                args.policies, (*EXPLORATION_POLICIES, *EXPLORATION_ABLATIONS), "policy(ies)"
            ),
            features=features,
            seeds=parse_seeds(args.seeds),
            saccade_budget=args.budget,
            env_id=args.env,
            head_size=None if args.head_size is None else parse_size(args.head_size),
            fovea_factor=args.fovea_factor,
            workers=args.workers,
            backend=args.backend,
            ray_address=args.ray_address,
            video=args.video,
        )
        writable(args.out, "--out")
        writable(args.cache, "--cache")
        return run_exploration_eval(args.out, args.cache, config)

    def rows(summary):
        for scene, by_policy in summary.items():
            for policy, by_feature in by_policy.items():
                row = ", ".join(
                    f"{f} {m['performance_mean']:.0%} [{m['ci_low']:.0%}, {m['ci_high']:.0%}]"
                    for f, m in by_feature.items()
                )
                yield f"{scene} {policy}: {row}"

    return run_to_summary(
        run,
        rows,
        f"report written to {(args.out / 'exploration.md').resolve()}",
        (ExplorationEvalError,),
    )
