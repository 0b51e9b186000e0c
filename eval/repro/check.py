"""``ipbench check``: does this platform reproduce the reference results exactly, statistically,
or not at all?

It runs the stage digests of :mod:`ipbench.eval.repro.digests` (about 30 s on one core) and compares
them with the reference shipped in ``ipbench/eval/data/check_reference.json`` (or
``--reference FILE``). Each stage is

* **exact**: every output bit equals the reference's;
* **close**: some bits differ, but every summary number is within the stage's tolerance
  (:attr:`~ipbench.eval.repro.digests.Stage.tolerances`);
* **differs**: a summary is out of tolerance, or the reference has no such stage.

The verdict is ``exact`` when every stage is, ``statistical`` when none differs, and
``differs`` otherwise (:data:`MEANINGS` says what each means for comparing results).
``--json`` prints (or writes) ``{"verdict", "meaning", "complete", "stages", "platform",
"reference_platform", "platform_differences"}``. ``--write-reference FILE`` runs the stages and
writes a new reference (with this platform) instead of comparing.

Exit status: 0 for ``exact`` and ``statistical``, 1 for ``differs``, 2 when the reference
cannot be read (the message says how to regenerate it).

Tolerances
----------
"Close" is meant as "what round-off differences alone do". Measured on the reference machine
(AMD EPYC, AVX-512, one thread): a 1e-12 m change of the objects' reset poses moves the settled
scene by 1e-7 m (object heights), the maximum resting speed by 2e-5 m/s, and leaves the
contact count and the scripted pick unchanged (others moved 1e-7 m): the physics tolerances
are 1e-5 m, 1e-3 m/s, 4 contacts, 1e-4 m. A 1e-9 m change moves the wrist image's mean
colour by 1e-5 levels and the noisy depth's mean error by 1e-7 m; edge pixels that flip on
another rasteriser cost about 1.6e-6 m of mean depth each, hence 5e-4 m, 0.25 levels and 0.1 %
of the pixels. The GP trained with BLAS on 2 threads instead of 1 (other bits) has the same
accuracy, log hyperparameters within 1e-10 and a mean confidence within 2.4e-4 (tolerance
0.002); inputs changed by 1e-15 flip one of the 200 test points (accuracy tolerance 0.015). A
1e-12 m change of the synthetic cloud leaves the segments, the FPFH voxel count and its spread
(2e-6 relative) nearly unchanged, but moves the k-means quantisation error by 0.2 % (tolerance
1 %). Layout summaries allow round-off only (1e-6 m): any layout drawn differently moves the
means by about 1 mm. One short episode is chaotic: a 1e-12 m change of the reset state changed
a 6-step oracle episode's reward by up to 3 (4 perturbations), and OpenBLAS's Haswell kernels
instead of SkylakeX turned the v1 episode's 3 sorted objects into 0 (6 failed grasps); so only
an episode's length must agree, its outcomes may span the step budget. Episodes are compared
statistically by an evaluation over many seeds, with confidence intervals.

Across machines
---------------
Emulated here by switching kernels (``OPENBLAS_CORETYPE=Haswell``,
``NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL"``, ``OPENCV_CPU_DISABLE=AVX512_SKX``,
``NUMBA_CPU_NAME=haswell``, ``LP_NATIVE_VECTOR_WIDTH=128``), the bits depend on the instruction
set a library dispatches to, not on the CPU vendor: OpenBLAS's kernel (SkylakeX with AVX-512,
Haswell or Zen without) changes the compiled models (keyframe poses, inertias), the layouts'
poses, hence physics, renders, the segmentation's plane and the GP: a ``statistical`` platform.
numpy's AVX-512 paths change the compiled models' geom sizes and the GP only. OpenCV's
dispatch, numba's target CPU and llvmpipe's vector width change nothing. So the Intel Xeon
that recorded ``tests/data/sorting_v1_digests.json`` and this AMD EPYC give the same Sorting-v1
observations (renders, physics, depth noise) bit for bit: same wheels, and (inferred) the same
AVX-512 kernels. Not emulated: other Mesa/LLVM versions (the system's libGL renders),
another glibc (libm), a GPU renderer, other wheel versions; all are recorded in the platform.
BLAS on 2 threads gives other (repeatable) GP bits than on 1: every stage runs on one thread.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path

from ipbench.eval.cli_options import add_json_option
from ipbench.eval.repro.digests import STAGES, StageResult, platform_info, run_stages

__all__ = [
    "CHECK_FORMAT",
    "MEANINGS",
    "REFERENCE_FILE",
    "CheckError",
    "add_check_parser",
    "check_report",
    "compare_stage",
    "format_report",
    "load_reference",
    "main_check",
    "reference_payload",
    "verdict_of",
    "write_reference",
]

CHECK_FORMAT = 1
"""Version of the reference file's layout (and of the stage definitions): a reference of
another version is refused, with how to regenerate it."""
REFERENCE_FILE = Path(__file__).parents[1] / "data" / "check_reference.json"
"""The reference shipped with the package."""
MEANINGS: dict[str, str] = {
    "exact": "episodes reproduce bit for bit: a result of this platform can be compared seed by "
    "seed (and should be identical) with the reference's",
    "statistical": "some stages differ in their last bits, within tolerance: episodes diverge, so "
    "compare aggregate results only (means over seeds with confidence intervals), never "
    "single episodes",
    "differs": "results are not comparable with the reference's: report the platform "
    "(ipbench check --json FILE) with any result, and the stages that differ",
}
"""What each verdict means for comparing results."""
_STATUSES = ("exact", "close", "differs")
_REPORTING = (
    "To report a result, give the env id (e.g. ipbench/Sorting-v2), the policy code version "
    "(ipbench.policies.POLICY_VERSION, in run.json), the seeds and this verdict "
    "(ipbench check --json FILE holds the platform too)."
)


class CheckError(RuntimeError):
    """A reference file that is missing, unreadable or of another format version."""


# -- the reference ------------------------------------------------------------------------------
def _regenerate(path: Path) -> str:
    return (
        f"regenerate it with `ipbench check --write-reference {path}` on the machine whose "
        "results are the reference (the shipped one comes with the package: reinstall ipbench "
        "to restore it)"
    )


def reference_payload(results: Mapping[str, StageResult], platform: Mapping) -> dict:
    """The reference file's content: format version, stage results and platform."""
    return {
        "format": CHECK_FORMAT,
        "stages": {name: r.to_json() for name, r in results.items()},
        "platform": dict(platform),
    }


def write_reference(
    path: str | Path, results: Mapping[str, StageResult], platform: Mapping
) -> Path:
    """Write a reference file atomically (a temporary file renamed into place)."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(json.dumps(reference_payload(results, platform), indent=1) + "\n")
        tmp.replace(path)
    except OSError as err:
        raise CheckError(
            f"cannot write the reference {path}: {err.strerror or err}; pass a writable FILE"
        ) from err
    return path


def _is_number(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def load_reference(path: str | Path = REFERENCE_FILE) -> dict:
    """Read and validate a reference file; :class:`CheckError` (saying how to regenerate it)
    when it is missing, not JSON, of another format version, or incomplete."""
    path = Path(path)
    if not path.is_file():
        raise CheckError(f"the reference file {path} is missing; {_regenerate(path)}")
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise CheckError(
            f"the reference file {path} is unreadable ({err}); {_regenerate(path)}"
        ) from err
    if not isinstance(data, dict) or data.get("format") != CHECK_FORMAT:
        found = data.get("format") if isinstance(data, dict) else type(data).__name__
        raise CheckError(
            f"the reference file {path} has format {found!r}, this ipbench reads format "
            f"{CHECK_FORMAT}; {_regenerate(path)}"
        )
    stages, problem = data.get("stages"), None
    if not isinstance(stages, dict) or not stages:
        problem = "no stages"
    elif not isinstance(data.get("platform"), dict):
        problem = "no platform"
    else:
        for name, stage in stages.items():
            ok = (
                isinstance(stage, dict)
                and isinstance(stage.get("digest"), str)
                and isinstance(stage.get("parts"), dict)
                and all(isinstance(v, str) for v in stage["parts"].values())
                and isinstance(stage.get("summary"), dict)
                and all(_is_number(v) for v in stage["summary"].values())
            )
            if not ok:
                problem = f"stage {name!r} lacks a digest, parts or numeric summary"
                break
    if problem:
        raise CheckError(f"the reference file {path} is corrupt ({problem}); {_regenerate(path)}")
    return data


# -- comparison ---------------------------------------------------------------------------------
def compare_stage(
    result: Mapping, reference: Mapping | None, tolerances: Mapping[str, tuple[float, float]]
) -> dict:
    """Compare one stage's result (:meth:`StageResult.to_json`) with the reference's.

    Returns ``{"status", "digest", "reference_digest", "parts_differing", "out_of_tolerance",
    "summary", "reference_summary", "seconds"}``; ``status`` is ``exact`` (digests equal),
    ``close`` (every summary within ``tolerances``: name -> ``(abs, rel)``, a value ``a``
    is within of the reference's ``b`` when ``|a - b| <= abs + rel * |b|``; a name not listed
    must be equal) or ``differs``.
    """
    summary = dict(result["summary"])
    out = {
        "status": "differs",
        "digest": result["digest"],
        "reference_digest": None,
        "parts_differing": [],
        "out_of_tolerance": {},
        "summary": summary,
        "reference_summary": None,
        "seconds": result.get("seconds"),
    }
    if reference is None:
        out["out_of_tolerance"] = {"(stage)": "not in the reference: regenerate it"}
        return out
    ref_summary = dict(reference["summary"])
    out["reference_digest"], out["reference_summary"] = reference["digest"], ref_summary
    parts, ref_parts = result.get("parts", {}), reference.get("parts", {})
    out["parts_differing"] = sorted(
        p for p in set(parts) | set(ref_parts) if parts.get(p) != ref_parts.get(p)
    )
    if result["digest"] == reference["digest"]:
        out["status"] = "exact"
        return out
    bad = {}
    for key in sorted(set(summary) | set(ref_summary)):
        a, b = summary.get(key), ref_summary.get(key)
        abs_tol, rel_tol = tolerances.get(key, (0.0, 0.0))
        if a is None or b is None:
            bad[key] = {"value": a, "reference": b, "tolerance": "missing on one side"}
        elif not (math.isfinite(a) and abs(a - b) <= abs_tol + rel_tol * abs(b)):
            bad[key] = {"value": a, "reference": b, "tolerance": [abs_tol, rel_tol]}
    out["out_of_tolerance"] = bad
    out["status"] = "differs" if bad else "close"
    return out


def verdict_of(statuses: Iterable[str]) -> str:
    """``exact`` if every status is, ``statistical`` if none is ``differs``, else ``differs``."""
    statuses = list(statuses)
    unknown = sorted(set(statuses) - set(_STATUSES))
    if unknown:
        raise ValueError(f"unknown stage status(es) {unknown}; valid: {', '.join(_STATUSES)}")
    if "differs" in statuses:
        return "differs"
    return "exact" if all(s == "exact" for s in statuses) else "statistical"


def check_report(
    results: Mapping[str, Mapping],
    reference: Mapping,
    platform: Mapping,
    tolerances: Mapping[str, Mapping[str, tuple[float, float]]] | None = None,
) -> dict:
    """The verdict of ``results`` (stage name -> :meth:`StageResult.to_json`) against a loaded
    ``reference``; ``tolerances`` (stage -> summary -> ``(abs, rel)``) default to
    :data:`~ipbench.eval.repro.digests.STAGES`'. ``complete`` is false when the reference has
    stages that were not run (``--stages``); the verdict covers the stages run."""
    if tolerances is None:
        tolerances = {name: stage.tolerances for name, stage in STAGES.items()}
    ref_stages = reference["stages"]
    stages = {
        name: compare_stage(result, ref_stages.get(name), tolerances.get(name, {}))
        for name, result in results.items()
    }
    verdict = verdict_of(s["status"] for s in stages.values())
    ref_platform = dict(reference.get("platform", {}))
    differences = {
        k: {"here": platform.get(k), "reference": ref_platform.get(k)}
        for k in sorted(set(platform) | set(ref_platform))
        if platform.get(k) != ref_platform.get(k)
    }
    return {
        "verdict": verdict,
        "meaning": MEANINGS[verdict],
        "complete": set(ref_stages) <= set(results),
        "stages": stages,
        "platform": dict(platform),
        "reference_platform": ref_platform,
        "platform_differences": differences,
    }


def _note(name: str, stage: Mapping, stages: Mapping[str, Mapping]) -> str:
    """One line on why a stage is not exact."""
    if stage["status"] == "exact":
        return ""
    notes = []
    if stage["parts_differing"]:
        notes.append("bits differ in " + ", ".join(stage["parts_differing"]))
    for key, bad in stage["out_of_tolerance"].items():
        if isinstance(bad, str):
            notes.append(bad)
        elif isinstance(bad["tolerance"], str):
            notes.append(f"{key} {bad['tolerance']}")
        else:
            a, r = bad["tolerance"]
            tol = f"±{a:g}" if not r else (f"±{r:.1%}" if not a else f"±({a:g} + {r:.1%})")
            notes.append(f"{key} {bad['value']:.6g} vs {bad['reference']:.6g} ({tol})")
    if stage["status"] == "close":
        notes.append("summaries within tolerance")
    spec = STAGES.get(name)
    upstream = [
        d for d in (spec.depends_on if spec else ()) if stages.get(d, {}).get("status") != "exact"
    ]
    if upstream:
        notes.append("its input differs: " + ", ".join(upstream))
    return "; ".join(notes)


def format_report(report: Mapping) -> str:
    """The human-readable report: a line per stage, the verdict and what it means, and how the
    platform differs from the reference's."""
    ref = report["reference_platform"]
    lines = [
        f"ipbench check against the reference of {ref.get('cpu', '?')} "
        f"(ipbench {ref.get('ipbench', '?')}, mujoco {ref.get('mujoco', '?')}):",
        f"  {'stage':<16} {'status':<8} {'time':>7}  notes",
    ]
    stages = report["stages"]
    for name, stage in stages.items():
        seconds = stage.get("seconds")
        took = f"{seconds:6.1f}s" if isinstance(seconds, int | float) else "      -"
        line = f"  {name:<16} {stage['status']:<8} {took}  {_note(name, stage, stages)}"
        lines.append(line.rstrip())
    if not report["complete"]:
        lines.append("  (only some stages were run: the verdict covers those)")
    lines.append(f"verdict: {report['verdict']} - {report['meaning']}")
    diffs = report["platform_differences"]
    if diffs:
        lines.append("platform differences from the reference:")
        lines += [f"  {k}: {v['here']!r} here, {v['reference']!r} there" for k, v in diffs.items()]
    else:
        lines.append("platform: the same as the reference's")
    lines.append(_REPORTING)
    return "\n".join(lines)


# -- the command --------------------------------------------------------------------------------
def add_check_parser(sub) -> argparse.ArgumentParser:
    """Register the ``check`` sub-command on ``sub`` (an ``add_subparsers()`` object)."""
    parser = sub.add_parser(
        "check",
        help="does this platform reproduce the reference results: exactly, statistically, not?",
        description="Runs the pipeline's stages on fixed inputs (model compile, layouts, "
        "physics, rendering, depth noise, segmentation and FPFH, codebook, GP training, two "
        "short oracle episodes; about 30 s on one core), compares their SHA-256 digests and "
        "summaries with the reference shipped with ipbench and prints per stage exact / close "
        "/ differs and a verdict: exact (episodes reproduce bit for bit), statistical (compare "
        "aggregates with confidence intervals only) or differs (not comparable: report the "
        "platform). Exit status 0 for exact and statistical, 1 for differs, 2 when the "
        "reference cannot be read.",
    )
    add_json_option(
        parser, "write the report as one JSON object to FILE; with no FILE, print only the JSON"
    )
    parser.add_argument(
        "--reference",
        type=Path,
        default=REFERENCE_FILE,
        metavar="FILE",
        help="reference file to compare with (default: %(default)s, shipped with ipbench)",
    )
    parser.add_argument(
        "--write-reference",
        type=Path,
        default=None,
        metavar="FILE",
        help="run the stages and write their digests and this platform to FILE as a new "
        "reference, instead of comparing",
    )
    parser.add_argument(
        "--stages",
        default=None,
        help=f"comma-separated stages to run (default: all): {', '.join(STAGES)}",
    )
    return parser


def _stage_names(text: str | None) -> list[str] | None:
    if text is None:
        return None
    names = [n.strip() for n in text.split(",") if n.strip()]
    bad = [n for n in names if n not in STAGES]
    if bad or not names:
        raise SystemExit(
            f"ipbench: unknown stage(s) {', '.join(bad) or '(none)'}; valid: {', '.join(STAGES)}"
        )
    return names


def main_check(args: argparse.Namespace) -> int:
    """Run ``ipbench check`` with parsed ``args`` (see :func:`add_check_parser`); the exit
    status (0 exact or statistical, 1 differs, 2 unreadable reference)."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    names = _stage_names(args.stages)
    progress: Callable[[str], None] = lambda line: print(f"  {line}", file=sys.stderr)  # noqa: E731
    if args.write_reference is not None:
        results = run_stages(names, progress)
        try:
            path = write_reference(args.write_reference, results, platform_info())
        except CheckError as err:
            print(f"ipbench: {err}", file=sys.stderr)
            return 2
        print(f"reference of {len(results)} stages written to {path}", file=sys.stderr)
        return 0
    try:
        reference = load_reference(args.reference)
    except CheckError as err:
        print(f"ipbench: {err}", file=sys.stderr)
        return 2
    results = run_stages(names, progress)
    report = check_report({n: r.to_json() for n, r in results.items()}, reference, platform_info())
    text = json.dumps(report, indent=1)
    if args.json == "-":
        print(text)
    else:
        if args.json is not None:
            Path(args.json).write_text(text + "\n")
        print(format_report(report))
    return 1 if report["verdict"] == "differs" else 0


# python -m ipbench.eval.repro.check [options] is the same as ipbench check
if __name__ == "__main__":
    _parser = argparse.ArgumentParser(prog="ipbench")
    add_check_parser(_parser.add_subparsers(dest="command", required=True))
    sys.exit(main_check(_parser.parse_args(["check", *sys.argv[1:]])))
