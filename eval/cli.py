"""The ``ipbench`` command.

ipbench demo [--out DIR] [--scenes uncluttered,cluttered] [--seed N] [--no-video]
ipbench eval perception [--env ID] [--out DIR] [--cache DIR]
ipbench eval sorting [--scenes ...] [--policies ...] [--seeds A:B] [--workers N]
                     [--backend process|ray] [--video] [--out DIR] [--cache DIR]
ipbench eval exploration [--scenes ...] [--policies ...] [--features ...] [--seeds A:B] ...
ipbench eval calibration [--out DIR] [--seeds A:B] [--workers N]
ipbench calibrate --out FILE [--cameras head,wrist] [--poses N] [--seed S] [--overwrite]
ipbench figures [--env ID] [--out DIR]
ipbench bench sim [--env ID] [--scene S] [--json [FILE]]
ipbench bench perception|eval|exploration [--json [FILE]]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from ipbench.eval.calibration.cli import (
    add_calibrate,
    add_eval_calibration,
    main_calibrate,
    main_eval_calibration,
)
from ipbench.eval.cli_options import (
    add_json_option,
    parse_names,
    parse_seeds,
    parse_thresholds,
    print_figures,
    run_to_summary,
    writable,
)
from ipbench.eval.exploration.cli import (
    add_bench_exploration,
    add_eval_exploration,
    main_exploration,
)
from ipbench.eval.report.docs import add_report_parser, main_report
from ipbench.eval.repro.check import add_check_parser, main_check

__all__ = ["main", "build_parser"]


def _valid_names() -> dict[str, tuple[str, ...]]:
    """The names help texts list, by placeholder (imported when help is shown: slow)."""
    from ipbench.envs import ENV_IDS, EXPLORATION_IDS
    from ipbench.envs.exploration_scene import LEVELS
    from ipbench.envs.sorting_scenes import SCENES
    from ipbench.eval.sorting.evaluate import BACKENDS
    from ipbench.perception.features2d import FEATURE_TYPES
    from ipbench.policies import FUSIONS, POLICIES
    from ipbench.policies.exploration import EXPLORATION_ABLATIONS, EXPLORATION_POLICIES

    return {
        "{LEVELS}": tuple(LEVELS),
        "{EXPLORATION_POLICIES}": EXPLORATION_POLICIES,
        "{EXPLORATION_ABLATIONS}": EXPLORATION_ABLATIONS,
        "{FEATURES}": FEATURE_TYPES,
        "{ENV_IDS}": tuple(ENV_IDS),
        "{EXPLORATION_IDS}": tuple(EXPLORATION_IDS),
        "{SCENES}": tuple(SCENES),
        "{POLICIES}": POLICIES,
        "{BACKENDS}": BACKENDS,
        "{FUSIONS}": tuple(FUSIONS),
    }


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows each option's default (not None or a flag's False), fills the lists of valid
    names (``{SCENES}``, ``{POLICIES}``, ... of :func:`_valid_names`) into help texts, and
    wraps each line of a description or epilog on its own: an epilog ``example: COMMAND``
    shows the command whole on the last line."""

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        lines = []
        for line in text.splitlines():
            head, example, command = line.partition("example: ")
            if example and not head.strip():
                lines += [f"{indent}example:", f"{indent}  {command.strip()}"]
            else:
                lines.append(super()._fill_text(line, width, indent) if line.strip() else "")
        return "\n".join(lines)

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if "{" in text:
            for token, names in _valid_names().items():
                text = text.replace(token, ", ".join(names))
        shown = action.option_strings or action.nargs in (argparse.OPTIONAL, argparse.ZERO_OR_MORE)
        if (
            shown
            and "%(default)" not in text
            and action.default not in (None, argparse.SUPPRESS)
            and not isinstance(action.default, bool)
        ):
            text += " (default: %(default)s)"
        return text


class _Parser(argparse.ArgumentParser):
    """An argument parser (and sub-parsers) with :class:`_HelpFormatter`."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)


def _add_env_option(parser: argparse.ArgumentParser, default: str | None = None) -> None:
    from ipbench.envs import LATEST

    parser.add_argument(
        "--env",
        default=default or LATEST,
        help="environment id whose objects and sensor are used: {ENV_IDS}",
    )


def _env_id(text: str) -> str:
    from ipbench.envs import ENV_IDS

    if text not in ENV_IDS:
        raise SystemExit(f"ipbench: unknown --env {text!r}; valid: {', '.join(ENV_IDS)}")
    return text


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="ipbench",
        description=(
            "ipbench: a MuJoCo benchmark of robotic interactive perception on the CloPeMa "
            "dual-arm work cell. A robot sorts household objects into bins, and may pick an "
            "object up to look at it again before it decides."
        ),
        epilog="example: ipbench eval sorting --scenes uncluttered --policies random,gp-ipm "
        "--seeds 0:5",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    demo = sub.add_parser(
        "demo",
        help="run a scripted sorting episode per scene (ground-truth labels), write MP4s",
        description="Scripted sorting with ground-truth labels: one episode per scene, an MP4 "
        "from the overview camera and demo_summary.json in --out.",
        epilog="example: ipbench demo --out results/demo --scenes uncluttered",
    )
    demo.add_argument("--out", type=Path, default=Path("results"), help="output folder")
    demo.add_argument(
        "--scenes", default="uncluttered,cluttered", help="comma-separated scenes of {SCENES}"
    )
    demo.add_argument("--seed", type=int, default=0, help="episode seed")
    demo.add_argument("--no-video", action="store_true", help="skip the MP4s")

    add_calibrate(sub)

    evaluate = sub.add_parser(
        "eval",
        help="benchmark evaluations that write reports",
        description="Benchmark evaluations; each writes a report folder (--out).",
        epilog="example: ipbench eval perception --classifiers gp,svm --out results/perception",
    )
    eval_sub = evaluate.add_subparsers(dest="target", required=True, metavar="TARGET")
    perception = eval_sub.add_parser(
        "perception",
        help="train and compare the GP, SVM, scikit-learn GP and PointNet ensemble classifiers",
        description="Renders (or loads from --cache) views of every object instance, fits "
        "the FPFH codebook, trains the classifiers on the known instances and evaluates them "
        "on the unknown ones and on cluttered-scene segments; writes metrics.json, "
        "perception.md and figures to --out. A classifier of your own is named "
        "module:attribute (docs/custom.md).",
        epilog="example: ipbench eval perception --classifiers "
        "gp,svm,examples.my_classifier:LogisticClassifier --out results/perception",
    )
    _add_env_option(perception)
    perception.add_argument(
        "--classifiers",
        default=None,
        help="comma-separated classifiers to compare (default: all of gp, gp_mode, svm, "
        "sklearn_gp, pointnet_ensemble; scikit-learn's GP is cubic in the training views: "
        "minutes on v2's 3,800), and classifiers of your own as module:attribute, e.g. "
        "examples.my_classifier:LogisticClassifier",
    )
    perception.add_argument(
        "--out", type=Path, default=Path("results/perception"), help="report folder"
    )
    perception.add_argument(
        "--cache", type=Path, default=Path("results/cache"), help="rendered-view cache folder"
    )

    sorting = eval_sub.add_parser(
        "sorting",
        help="run sorting policies as episodes and compare them (thesis Table 5.1)",
        description="Runs every policy on every scene for every seed (the same seeds for "
        "every policy: a paired comparison). Perception models are trained on first use and "
        "cached in --cache; the confidence-driven policies' threshold is chosen on the first "
        "views of validation scenes (seeds 1000-1039, disjoint from the test seeds) and "
        "cached too; --threshold sets it, --thresholds runs each such policy at several. "
        "Each finished episode is "
        "appended to OUT/episodes.jsonl, so an interrupted run resumes where it stopped. "
        "Writes OUT/summary.json, OUT/sorting.md, plots and (--video) MP4s. A policy of your "
        "own is named module:attribute (docs/custom.md).",
        epilog="example: ipbench eval sorting --scenes uncluttered --policies "
        "random,gp-ipm,examples.my_policy:LargestFirst --seeds 0:5 --workers 2",
    )
    sorting.add_argument(
        "--scenes", default="uncluttered,cluttered", help="comma-separated scenes of {SCENES}"
    )
    sorting.add_argument(
        "--policies",
        default="random,gp-ipm",
        help="comma-separated policies: random, gp-ipm (inspect in hand), gp-ipm-area "
        "(inspect in the inspection area), svm-ipm (SVM confidences), deep-ipm (a PointNet "
        "deep ensemble's confidences), oracle-inspect (inspects exactly the objects whose "
        "first label is wrong), random-inspect@P (inspects a fraction P at random), oracle "
        "(true label of the object held; v2), oracle-scene (true label of the segment aimed "
        "at); a confidence-driven policy at threshold T: gp-ipm@T; a policy of your own as "
        "module:attribute, e.g. examples.my_policy:LargestFirst",
    )
    sorting.add_argument(
        "--threshold",
        type=float,
        default=None,
        help="run every confidence-driven policy at this confidence threshold (0..1) instead "
        "of the validated one",
    )
    sorting.add_argument(
        "--thresholds",
        default=None,
        help="comma-separated thresholds (e.g. 0.5,0.8,1.0): each confidence-driven policy "
        "runs once per threshold, as NAME@T (same seeds, paired); OUT/curve.json and "
        "curve.png draw accuracy against inspections per object",
    )
    sorting.add_argument(
        "--seeds", default="0:30", help="episode seeds: A:B (A..B-1) or a comma-separated list"
    )
    sorting.add_argument(
        "--workers",
        type=int,
        default=1,
        help="processes rendering the training views, training the models and running the "
        "episodes in parallel; 1 runs everything here (make eval: 2)",
    )
    _add_env_option(sorting)
    sorting.add_argument(
        "--backend",
        default="process",
        help="one of {BACKENDS}: process (local worker processes) or ray (Ray tasks; "
        "pip install 'ipbench[ray]')",
    )
    sorting.add_argument(
        "--ray-address",
        default=None,
        help="Ray cluster address, with --backend ray only (default: a local instance)",
    )
    sorting.add_argument(
        "--video", action="store_true", help="an MP4 of each policy and scene (first seed)"
    )
    sorting.add_argument(
        "--fusion", default="majority", help="view fusion, one of {FUSIONS} (thesis: majority)"
    )
    sorting.add_argument(
        "--extrinsics",
        default="true",
        help="what the robot knows of its cameras: true (the simulator's exact values, the "
        "released envs), nominal (the true cell of --robot-seed, believed to be the nominal "
        "model) or calibrated (that cell, believed to be --calibration FILE)",
    )
    sorting.add_argument(
        "--calibration",
        default=None,
        help="calibration file for --extrinsics calibrated (ipbench calibrate --cameras wrist "
        "--robot-seed R --out FILE)",
    )
    sorting.add_argument(
        "--robot-seed", type=int, default=0, help="the true cell's error seed (not with true)"
    )
    sorting.add_argument("--out", type=Path, default=Path("results/sorting"), help="report folder")
    sorting.add_argument(
        "--cache", type=Path, default=Path("results/cache"), help="model and view cache folder"
    )

    add_eval_exploration(eval_sub)
    compare = eval_sub.add_parser(
        "compare",
        help="two sorting runs paired by seed (e.g. --extrinsics calibrated against true)",
        description="For every scene and policy both runs ran: accuracy of each on their "
        "common seeds, failed grasps, and OTHER - BASE paired over seeds (bootstrap interval, "
        "sign-flip p). Prints a markdown table; --json writes the rows.",
        epilog="example: ipbench eval compare results/sorting results/sorting-calibrated",
    )
    compare.add_argument("base", type=Path, help="folder of `ipbench eval sorting --out BASE`")
    compare.add_argument("other", type=Path, help="folder of the run compared with BASE")
    compare.add_argument("--json", type=Path, default=None, help="write the rows to this file")
    add_eval_calibration(eval_sub)

    figures = sub.add_parser(
        "figures",
        help="the README's pictures of an env's objects and sensor",
        description="Renders every object family of the env's catalogue (objects_<v>.png) and "
        "a cluttered wrist view: RGB, ideal and sensor depth (depth_<v>.png), into --out.",
        epilog="example: ipbench figures --env ipbench/Sorting-v2 --out assets",
    )
    _add_env_option(figures, "ipbench/Sorting-v2")
    figures.add_argument("--out", type=Path, default=Path("assets"), help="output folder")

    bench = sub.add_parser(
        "bench",
        help="speed benchmarks that print figures",
        description="Speed benchmarks; each prints its figures (--json also writes them).",
        epilog="example: ipbench bench sim --scene cluttered --json sim.json",
    )
    bench_sub = bench.add_subparsers(dest="target", required=True, metavar="TARGET")
    sim = bench_sub.add_parser(
        "sim",
        help="physics, rendering, skill and reset speed of the sorting scene",
        description="Physics steps/s (vs raw mj_step), wrist RGB-D fps at 640x480, head "
        "stereo fps, pick-and-place skill wall time, reset time.",
        epilog="example: ipbench bench sim --scene cluttered --json sim.json",
    )
    _add_env_option(sim)
    sim.add_argument("--scene", default="uncluttered", help="scene to measure, one of {SCENES}")
    add_json_option(sim)
    bench_perception = bench_sub.add_parser(
        "perception",
        help="segmentation, features and classification time of a cluttered scene; GP fit",
        description="Per cluttered 640x480 observation: segmentation, FPFH + bag-of-words and "
        "classification seconds (one core); GP and scikit-learn GP fit seconds on ~1,500 "
        "256-d training vectors.",
        epilog="example: ipbench bench perception --json perception.json",
    )
    add_json_option(bench_perception)
    bench_eval = bench_sub.add_parser(
        "eval",
        help="sorting episodes per minute for each policy with 1 and 2 workers",
        description="Runs a few cluttered episodes per policy serially and with 2 worker "
        "processes and prints episodes/minute (models from --cache, trained if missing).",
        epilog="example: ipbench bench eval --policies random,gp-ipm --episodes 4",
    )
    bench_eval.add_argument(
        "--policies",
        default="random,gp-ipm",
        help="comma-separated policies to time: {POLICIES}, or module:attribute",
    )
    bench_eval.add_argument(
        "--episodes",
        type=int,
        default=4,
        help="episodes per measurement (seeds 0 .. N-1; 1 <= N <= 1000, below the validation "
        "seeds)",
    )
    bench_eval.add_argument(
        "--cache", type=Path, default=Path("results/cache"), help="model cache folder"
    )
    add_json_option(bench_eval)
    add_bench_exploration(bench_sub)
    check = add_check_parser(sub)
    check.epilog = check.epilog or "example: ipbench check --json check.json"
    report = add_report_parser(sub)
    report.epilog = report.epilog or "example: ipbench report docs --from results"
    return parser


def _classifiers(args) -> dict:
    """``{"classifiers": (...)}`` from ``--classifiers``, checked; ``{}`` without it."""
    from ipbench.eval.perception.evaluate import EVAL_CLASSIFIERS as CLASSIFIERS
    from ipbench.perception.classifiers import ClassifierError, check_classifier_name

    if args.classifiers is None:
        return {}
    names = tuple(n.strip() for n in args.classifiers.split(",") if n.strip())
    bad = [n for n in names if n not in CLASSIFIERS and ":" not in n]
    if bad or not names:
        raise SystemExit(
            f"ipbench: unknown classifier(s) {', '.join(bad) or '(none)'}; "
            f"valid: {', '.join(CLASSIFIERS)}, or your own as module:attribute (e.g. "
            "mypkg.models:MyClassifier, see docs/custom.md)"
        )
    try:  # a classifier of the user's own: imported and checked before any work
        for name in names:
            check_classifier_name(name, CLASSIFIERS)
    except ClassifierError as err:
        raise SystemExit(f"ipbench: {err}") from err
    return {"classifiers": names}


def _scenes(text: str) -> tuple[str, ...]:
    from ipbench.envs.sorting_scenes import SCENES

    return parse_names(text, SCENES, "scene(s)", "valid scenes")


def main(argv: list[str] | None = None) -> int:
    os.environ.setdefault("MUJOCO_GL", "egl")
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    args = build_parser().parse_args(argv)
    if args.command == "check":
        return main_check(args)
    if args.command == "report":
        return main_report(args)
    if args.command == "calibrate":
        return main_calibrate(args)
    if args.command == "demo":
        from ipbench.eval.sorting.demo import run_demo

        scenes = _scenes(args.scenes)
        writable(args.out, "--out")
        return run_to_summary(
            lambda: run_demo(args.out, scenes, seed=args.seed, video=not args.no_video),
            lambda summary: (
                f"{scene}: {s['correct']}/{s['objects']} objects in the right bin, "
                f"{s['steps']} steps, {s['wall_time_s']} s"
                for scene, s in summary.items()
            ),
            f"results written to {args.out.resolve()}",
        )
    if args.command == "eval" and args.target == "perception":
        from ipbench.eval.perception.evaluate import PerceptionEvalConfig, run_perception_eval

        config = PerceptionEvalConfig.for_env(_env_id(args.env), **_classifiers(args))
        writable(args.out, "--out")
        writable(args.cache, "--cache")

        def perception_rows(metrics):
            for split, by_name in metrics["splits"].items():
                row = ", ".join(
                    f"{n} {m['accuracy']:.3f}" for n, m in by_name.items() if m.get("n", 0)
                )
                yield f"5-class accuracy, {split}: {row or 'no views'}"

        return run_to_summary(
            lambda: run_perception_eval(args.out, args.cache, config),
            perception_rows,
            f"report written to {(args.out / 'perception.md').resolve()}",
        )
    if args.command == "eval" and args.target == "sorting":
        from ipbench.eval.perception.evaluate import PerceptionEvalConfig
        from ipbench.eval.sorting.evaluate import (
            SortingEvalConfig,
            SortingEvalError,
            expand_thresholds,
            run_sorting_eval,
        )

        def run():
            policies = tuple(p.strip() for p in args.policies.split(",") if p.strip())
            config = SortingEvalConfig(
                perception=PerceptionEvalConfig.for_env(_env_id(args.env)),
                scenes=_scenes(args.scenes),
                policies=expand_thresholds(policies, parse_thresholds(args.thresholds)),
                threshold=args.threshold,
                seeds=parse_seeds(args.seeds),
                workers=args.workers,
                backend=args.backend,
                ray_address=args.ray_address,
                video=args.video,
                fusion=args.fusion,
                extrinsics=args.extrinsics,
                calibration=args.calibration,
                robot_seed=args.robot_seed,
            )
            writable(args.out, "--out")
            writable(args.cache, "--cache")
            return run_sorting_eval(args.out, args.cache, config)

        return run_to_summary(
            run,
            lambda summary: (
                f"{scene}: "
                + ", ".join(
                    f"{p} {m['accuracy_mean']:.0%} [{m['ci_low']:.0%}, {m['ci_high']:.0%}]"
                    for p, m in by_policy.items()
                )
                for scene, by_policy in summary.items()
            ),
            f"report written to {(args.out / 'sorting.md').resolve()}",
            (SortingEvalError,),
        )
    if args.command == "eval" and args.target == "calibration":
        return main_eval_calibration(args)
    if args.command == "eval" and args.target == "compare":
        from ipbench.eval.sorting.compare import (
            CompareError,
            as_json,
            compare_runs,
            comparison_markdown,
        )

        try:
            rows = compare_runs(args.base, args.other)
        except CompareError as err:
            raise SystemExit(f"ipbench: {err}") from err
        print(comparison_markdown(rows, str(args.base), str(args.other)), end="")
        if args.json is not None:
            args.json.write_text(json.dumps(as_json(rows), indent=1))
        return 0
    if args.command in ("eval", "bench") and args.target == "exploration":
        return main_exploration(args)
    if args.command == "figures":
        from ipbench.eval.capture.figures import depth_figure, family_gallery

        env_id = _env_id(args.env)
        writable(args.out, "--out")
        version = env_id.rsplit("-", 1)[-1]
        for path in (
            family_gallery(args.out / f"objects_{version}.png", env_id),
            depth_figure(args.out / f"depth_{version}.png", env_id),
        ):
            print(f"wrote {path}")
        return 0
    if args.command == "bench" and args.target == "eval":
        from ipbench.eval.bench.episodes import bench_eval, check_bench_eval
        from ipbench.eval.bench.sim import report
        from ipbench.eval.sorting.evaluate import SortingEvalError

        policies = tuple(p.strip() for p in args.policies.split(",") if p.strip())
        try:
            check_bench_eval(policies, args.episodes)
            writable(args.cache, "--cache")
            figures = bench_eval(args.cache, policies, args.episodes)
        except SortingEvalError as err:
            raise SystemExit(f"ipbench: {err}") from err
        print_figures(figures, args.json, report)
        return 0
    if args.command == "bench" and args.target == "sim":
        from ipbench.eval.bench.sim import bench_sim, report

        _scenes(args.scene)
        print_figures(bench_sim(args.scene, env_id=_env_id(args.env)), args.json, report)
        return 0
    if args.command == "bench" and args.target == "perception":
        from ipbench.eval.bench.perception import bench_perception
        from ipbench.eval.bench.sim import report

        print_figures(bench_perception(), args.json, report)
        return 0
    return 2


if __name__ == "__main__":
    sys.exit(main())
