"""``ipbench eval calibration`` over seeds: distributions, the report, resuming (small configs)."""

import json
from dataclasses import replace

import pytest

from ipbench.eval.calibration.evaluate import (
    CalibrationEvalConfig,
    CalibrationEvalError,
    run_calibration_eval,
)
from ipbench.eval.calibration.study import HandEyeStudyConfig
from ipbench.eval.cli import main
from ipbench.perception.calibration.hand_eye import HAND_EYE_METHODS

SMALL = HandEyeStudyConfig(pose_counts=(3, 10), trials=8, diversity_spreads_deg=(2.0, 45.0))
CONFIG = CalibrationEvalConfig(seeds=(2, 3), study=SMALL, poses=6, reconstructions=2)
STATS = {"mean", "median", "ci_low", "ci_high", "n", "values"}


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("calibration")
    return out, run_calibration_eval(out, CONFIG, progress=False)


def test_every_figure_is_a_distribution_over_the_seeds(run):
    out, metrics = run
    on_disk = json.loads((out / "metrics.json").read_text())
    assert on_disk == metrics and on_disk["seeds"] == [2, 3]
    rec = on_disk["reconstruction"]
    for key in ("head_true_rmse_mm", "head_encoders_rmse_mm", "head_dynamic_rmse_mm",
                "wrist_robot_rmse_mm", "wrist_robot_nominal_rmse_mm"):  # fmt: skip
        assert set(rec[key]) == STATS and rec[key]["n"] == 2, key
        assert rec[key]["ci_low"] <= rec[key]["mean"] <= rec[key]["ci_high"]
    for camera in ("wrist", "head_left"):
        assert set(on_disk["hand_eye"][camera]) == set(HAND_EYE_METHODS)
        for cell in on_disk["hand_eye"][camera].values():
            assert set(cell) == {"rotation_deg", "translation_mm"}
            assert set(cell["rotation_deg"]) == STATS
    for camera, c in on_disk["self_calibration"].items():  # the seeded cell is off its model
        assert c["calibrated"]["translation_mm"]["mean"] < c["nominal"]["translation_mm"]["mean"]
        cmp = on_disk["comparisons"][f"{camera}_calibrated_minus_nominal_translation_mm"]
        assert cmp["n"] == 2 and cmp["mean"] < 0 and 0 < cmp["p_value"] <= 1
    floor = on_disk["comparisons"]["head_encoders_minus_true_rmse_mm"]
    assert floor["values"] == pytest.approx(
        [
            e - t
            for e, t in zip(
                rec["head_encoders_rmse_mm"]["values"],
                rec["head_true_rmse_mm"]["values"],
                strict=True,
            )
        ]  # fmt: skip
    )
    assert 0.0 <= rec["head_fallback_rate"]["mean"] <= 1.0


def test_the_report_shows_the_spread_beside_the_thesis_and_one_seed_in_detail(run):
    out, metrics = run
    report = (out / "calibration.md").read_text()
    assert "2 seeds (2-3), robot seed 1" in report
    true = metrics["reconstruction"]["head_true_rmse_mm"]
    row = f"| {true['mean']:.3f} [{true['ci_low']:.3f}, {true['ci_high']:.3f}] |"
    assert row in report and "0.16 (Table 4.3)" in report and "12.5 (Table 4.4)" in report
    assert "## Paired comparisons over the seeds" in report and "# Seed 2 in detail" in report
    assert "| wrist | tsai |" in report  # the first seed's hand-eye grid
    assert (out / "spread.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert len((out / "episodes.jsonl").read_text().splitlines()) == 2


def test_a_seed_gives_the_same_figures_run_to_run_and_a_run_resumes(run, tmp_path):
    out, metrics = run
    assert run_calibration_eval(out, CONFIG, progress=False) == metrics  # nothing run again
    assert len((out / "episodes.jsonl").read_text().splitlines()) == 2
    alone = run_calibration_eval(tmp_path, replace(CONFIG, seeds=(3,)), progress=False)
    assert alone["per_seed"] == [row for row in metrics["per_seed"] if row["seed"] == 3]
    with pytest.raises(CalibrationEvalError, match="another configuration"):
        run_calibration_eval(tmp_path, replace(CONFIG, seeds=(3,), poses=7), progress=False)


def test_bad_settings_are_refused_with_the_valid_ones(tmp_path):
    with pytest.raises(SystemExit, match="bad --seeds"):
        main(["eval", "calibration", "--out", str(tmp_path), "--seeds", "-1"])
    bad_settings = (
        ({"seeds": (1, 1)}, "repeat"),
        ({"seeds": ()}, ">= 0"),
        ({"poses": 2}, "valid: >= 3"),
        ({"backend": "x"}, "valid: process"),
    )
    for bad, message in bad_settings:
        with pytest.raises(CalibrationEvalError, match=message):
            CalibrationEvalConfig(**bad)
    assert not (tmp_path / "metrics.json").exists()
