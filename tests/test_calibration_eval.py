"""``ipbench eval calibration`` writes its metrics and a report (small configs)."""

import json

import pytest

from ipbench.eval.calibration.evaluate import run_calibration_eval
from ipbench.eval.calibration.study import HandEyeStudyConfig
from ipbench.eval.cli import main
from ipbench.perception.calibration.hand_eye import HAND_EYE_METHODS

SMALL = HandEyeStudyConfig(pose_counts=(3, 10), trials=8, diversity_spreads_deg=(2.0, 45.0))


def test_metrics_have_every_key_and_calibration_beats_the_nominal_model(tmp_path):
    metrics = run_calibration_eval(tmp_path, seed=2, study=SMALL, poses=6, reconstructions=2)
    on_disk = json.loads((tmp_path / "metrics.json").read_text())
    assert on_disk["hand_eye"] == metrics["hand_eye"]
    for camera in ("wrist", "head_left"):
        assert set(on_disk["hand_eye"][camera]) == set(HAND_EYE_METHODS)
        for cell in on_disk["hand_eye"][camera].values():
            assert set(cell) == {"rotation_deg", "translation_mm"}
    cal = on_disk["self_calibration"]
    assert set(cal["cameras"]) == {"head_left", "head_right", "wrist"}
    for c in cal["cameras"].values():  # the seeded cell is off its nominal model; calibration
        assert c["calibrated"]["translation_mm"] < c["nominal"]["translation_mm"]
        assert c["calibrated"]["rotation_deg"] < c["nominal"]["rotation_deg"]
    rec = on_disk["reconstruction"]
    for key in ("head_dynamic_rmse_mm", "head_encoders_rmse_mm", "wrist_rmse_mm",
                "wrist_robot_rmse_mm", "wrist_robot_nominal_rmse_mm"):  # fmt: skip
        assert rec[key] is not None and rec[key] > 0
    report = (tmp_path / "calibration.md").read_text()
    assert "| wrist | tsai |" in report and "nominal model's X error" in report
    assert "| head, encoders |" in report and "wrist Xtion depth" in report
    assert "## Xtion in the robot frame (thesis Table 4.4)" in report
    assert "| calibrated X | " in report and "| nominal X (no calibration) |" in report
    assert f"{rec['wrist_robot_rmse_mm']:.2f} | 12.5 (Table 4.4) |" in report


def test_eval_calibration_rejects_a_negative_seed(tmp_path):
    with pytest.raises(SystemExit, match="valid: an int >= 0"):
        main(["eval", "calibration", "--out", str(tmp_path), "--seed", "-1"])
