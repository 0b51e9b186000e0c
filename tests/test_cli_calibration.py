"""``ipbench calibrate``: writes a file that loads, refuses to overwrite, rejects bad options."""

import pytest

from ipbench.envs.calibration_file import CalibrationFile
from ipbench.eval.cli import main


def test_calibrate_writes_a_file_that_loads_and_keeps_an_existing_one(tmp_path, capsys):
    out = tmp_path / "calib.json"
    assert main(["calibrate", "--out", str(out), "--cameras", "wrist", "--poses", "5"]) == 0
    loaded = CalibrationFile.load(out, expect_cameras=["wrist"])
    assert loaded.hand_eye["wrist"].setup == "eye_in_hand"
    assert "calibration written to" in capsys.readouterr().out
    before = out.read_text()
    with pytest.raises(SystemExit, match="--overwrite"):
        main(["calibrate", "--out", str(out), "--cameras", "wrist", "--poses", "5"])
    assert out.read_text() == before  # nothing lost


@pytest.mark.parametrize(
    ("options", "message"),
    [(["--cameras", "nose"], "head"), (["--poses", "2"], "3")],
)
def test_calibrate_rejects_bad_options_with_the_valid_ones(tmp_path, options, message):
    with pytest.raises(SystemExit, match=message):
        main(["calibrate", "--out", str(tmp_path / "c.json"), *options])
    assert not (tmp_path / "c.json").exists()
