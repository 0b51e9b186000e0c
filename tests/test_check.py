"""``ipbench check``: stage digests stable across processes, the verdict logic, the reference."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from ipbench.eval.repro.check import (
    CHECK_FORMAT,
    MEANINGS,
    REFERENCE_FILE,
    CheckError,
    add_check_parser,
    check_report,
    compare_stage,
    format_report,
    load_reference,
    main_check,
    verdict_of,
)
from ipbench.eval.repro.digests import CHEAP_STAGES, STAGES, digest_arrays

_DIGESTS = (
    "import json\n"
    "from ipbench.eval.repro.digests import CHEAP_STAGES, run_stages\n"
    "print(json.dumps({n: r.parts for n, r in run_stages(CHEAP_STAGES).items()}))\n"
)


def _cheap_digests_in_a_new_process() -> dict:
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    out = subprocess.run(
        [sys.executable, "-c", _DIGESTS], env=env, capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_cheap_stage_digests_are_equal_in_two_processes():
    assert set(CHEAP_STAGES) >= {"model", "layout", "noise_synthetic", "perception", "gpc"}
    first, second = _cheap_digests_in_a_new_process(), _cheap_digests_in_a_new_process()
    assert set(first) == set(CHEAP_STAGES)
    for name in CHEAP_STAGES:
        assert first[name] == second[name], name


def test_digest_sees_dtype_shape_and_bits():
    a = np.arange(6, dtype=np.float64)
    assert digest_arrays(a) == digest_arrays(a.copy())
    assert digest_arrays(a) != digest_arrays(a.astype(np.float32))
    assert digest_arrays(a) != digest_arrays(a.reshape(2, 3))
    b = a.copy()
    b[3] = np.nextafter(b[3], 10)  # one bit
    assert digest_arrays(a) != digest_arrays(b)
    assert digest_arrays("ab", "c") != digest_arrays("a", "bc")
    with pytest.raises(TypeError, match="object array"):
        digest_arrays(np.array([None]))


# -- the verdict logic on synthetic results ----------------------------------------------------
TOLERANCES = {"a": {"x": (0.1, 0.0), "y": (0.0, 0.01)}, "b": {}}


def _stage(digest: str, **summary: float) -> dict:
    return {"digest": digest, "parts": {"p": digest}, "summary": summary, "seconds": 1.0}


def _reference(**stages: dict) -> dict:
    return {"format": CHECK_FORMAT, "stages": stages, "platform": {"cpu": "reference cpu"}}


REF = _reference(a=_stage("a0", x=1.0, y=100.0), b=_stage("b0", n=3.0))


def _report(**results: dict) -> dict:
    return check_report(results, REF, {"cpu": "this cpu"}, TOLERANCES)


def test_every_digest_equal_is_exact():
    report = _report(a=_stage("a0", x=1.0, y=100.0), b=_stage("b0", n=3.0))
    assert report["verdict"] == "exact" and report["complete"]
    assert {s["status"] for s in report["stages"].values()} == {"exact"}
    assert report["meaning"] == MEANINGS["exact"]
    assert report["platform_differences"] == {
        "cpu": {"here": "this cpu", "reference": "reference cpu"}
    }
    assert set(report) >= {"verdict", "stages", "platform", "reference_platform"}


def test_other_bits_within_tolerance_are_statistical():
    # x within 0.1 absolute, y within 1 % relative; b exact
    report = _report(a=_stage("a1", x=1.09, y=100.9), b=_stage("b0", n=3.0))
    assert report["verdict"] == "statistical"
    a = report["stages"]["a"]
    assert a["status"] == "close" and a["parts_differing"] == ["p"] and not a["out_of_tolerance"]


@pytest.mark.parametrize(
    ("results", "why"),
    [
        ({"a": _stage("a1", x=1.2, y=100.0)}, "x"),  # beyond the absolute tolerance
        ({"a": _stage("a1", x=1.0, y=102.0)}, "y"),  # beyond the relative tolerance
        ({"a": _stage("a1", x=float("nan"), y=100.0)}, "x"),  # not a number
        ({"a": _stage("a1", x=1.0)}, "y"),  # a summary missing here
        ({"b": _stage("b1", n=4.0)}, "n"),  # a count (no tolerance) must be equal
        ({"c": _stage("c0")}, "(stage)"),  # a stage the reference does not have
    ],
)
def test_a_summary_out_of_tolerance_differs(results, why):
    report = _report(**results)
    assert report["verdict"] == "differs"
    (stage,) = report["stages"].values()
    assert stage["status"] == "differs" and why in stage["out_of_tolerance"]
    assert not report["complete"]  # only some of the reference's stages ran
    text = format_report(report)
    assert "verdict: differs" in text and "report the platform" in text


def test_one_differing_stage_makes_the_verdict_differ():
    report = _report(a=_stage("a1", x=1.0, y=100.0), b=_stage("b1", n=5.0))
    assert [s["status"] for s in report["stages"].values()] == ["close", "differs"]
    assert report["verdict"] == "differs"
    assert verdict_of(["exact", "close"]) == "statistical"
    assert verdict_of(["exact", "exact"]) == "exact"
    with pytest.raises(ValueError, match="valid: exact, close, differs"):
        verdict_of(["same"])


def test_equal_digests_are_exact_whatever_the_summaries():
    stage = compare_stage(_stage("a0", x=5.0), REF["stages"]["a"], TOLERANCES["a"])
    assert stage["status"] == "exact"


def test_the_human_report_says_what_the_verdict_means():
    for results in (
        {"a": _stage("a0", x=1.0, y=100.0), "b": _stage("b0", n=3.0)},
        {"a": _stage("a1", x=1.05, y=100.0), "b": _stage("b0", n=3.0)},
    ):
        report = _report(**results)
        text = format_report(report)
        assert f"verdict: {report['verdict']} - {report['meaning']}" in text
        assert "cpu: 'this cpu' here, 'reference cpu' there" in text
        assert "seeds" in text  # how to report a result


# -- the reference file -------------------------------------------------------------------------
def test_the_shipped_reference_covers_every_stage():
    reference = load_reference(REFERENCE_FILE)
    assert set(reference["stages"]) == set(STAGES)
    for name, stage in STAGES.items():
        summary = reference["stages"][name]["summary"]
        assert set(stage.tolerances) <= set(summary), name
    assert {"cpu", "cpu_flags", "blas", "numpy", "mujoco", "opencv", "numba", "gl"} <= set(
        reference["platform"]
    )


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="ipbench")
    add_check_parser(parser.add_subparsers(dest="command", required=True))
    return parser.parse_args(["check", *argv])


@pytest.mark.parametrize(
    ("content", "says"),
    [
        (None, "is missing"),
        ("{not json", "is unreadable"),
        (json.dumps({"format": 999, "stages": {}}), "has format 999"),
        (json.dumps([1, 2]), "has format 'list'"),
        (json.dumps({"format": CHECK_FORMAT, "stages": {}, "platform": {}}), "no stages"),
        (
            json.dumps({"format": CHECK_FORMAT, "stages": {"a": {"digest": 1}}, "platform": {}}),
            "stage 'a' lacks",
        ),
    ],
)
def test_a_bad_reference_says_how_to_regenerate(tmp_path, capsys, content, says):
    path = tmp_path / "reference.json"
    if content is not None:
        path.write_text(content)
    with pytest.raises(CheckError, match=says) as err:
        load_reference(path)
    assert f"ipbench check --write-reference {path}" in str(err.value)
    # the command stops before running any stage, with the same message and status 2
    assert main_check(_args("--reference", str(path))) == 2
    assert f"ipbench check --write-reference {path}" in capsys.readouterr().err


def test_write_reference_then_check_prints_only_json(tmp_path, capsys):
    path = tmp_path / "ref" / "reference.json"
    assert main_check(_args("--write-reference", str(path), "--stages", "noise_synthetic")) == 0
    capsys.readouterr()
    assert load_reference(path)["stages"].keys() == {"noise_synthetic"}
    assert main_check(_args("--reference", str(path), "--stages", "noise_synthetic", "--json")) == 0
    report = json.loads(capsys.readouterr().out)  # stdout is the JSON alone
    assert report["verdict"] == "exact" and report["complete"]
    assert report["stages"]["noise_synthetic"]["status"] == "exact"
    assert report["platform"] == report["reference_platform"]


def test_unknown_stage_names_list_the_valid_ones():
    with pytest.raises(SystemExit, match="unknown stage.*nosuch.*valid: model, layout"):
        main_check(_args("--stages", "nosuch"))
