"""``ipbench calibrate``: writes a file that loads, refuses to overwrite, rejects bad options."""

import pytest

from ipbench.envs.cell.calibration_file import CalibrationFile
from ipbench.eval.cli import main


def test_calibrate_writes_a_file_that_loads_and_keeps_an_existing_one(tmp_path, capsys):
    out = tmp_path / "calib.json"
    assert main(["calibrate", "--out", str(out), "--cameras", "wrist", "--poses", "5"]) == 0
    loaded = CalibrationFile.load(out, expect_cameras=["wrist"])
    assert loaded.hand_eye["wrist"].setup == "eye_in_hand"
    assert dict(loaded.cell) == {"robot_seed": 0}  # the envs' default cell
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


def test_the_default_calibration_is_accepted_by_an_env_of_the_default_cell(tmp_path):
    """``ipbench calibrate --out FILE`` then ``gym.make(..., extrinsics="calibrated",
    calibration=FILE)`` (both at their default robot seed) is the same cell; ``--robot-seed
    none`` calibrates the nominal cell, which that env refuses."""
    import gymnasium as gym

    import ipbench.envs  # noqa: F401
    from ipbench.envs.cell.extrinsics import ExtrinsicsError

    out = tmp_path / "c.json"
    assert main(["calibrate", "--out", str(out), "--cameras", "wrist", "--poses", "5"]) == 0
    kw = {"extrinsics": "calibrated", "cameras": ("wrist",)}
    env = gym.make("ipbench/Sorting-v2", calibration=str(out), **kw)
    env.close()
    nominal = tmp_path / "n.json"
    args = ["--cameras", "wrist", "--poses", "5", "--robot-seed", "none"]
    assert main(["calibrate", "--out", str(nominal), *args]) == 0
    assert dict(CalibrationFile.load(nominal).cell) == {"robot_seed": None}
    with pytest.raises(ExtrinsicsError, match="measured in the nominal cell"):
        gym.make("ipbench/Sorting-v2", calibration=str(nominal), **kw)
    with pytest.raises(SystemExit):
        main(["calibrate", "--out", str(tmp_path / "x.json"), "--robot-seed", "-2"])


def test_eval_calibration_takes_a_seed_range_and_a_single_seed():
    from ipbench.eval.cli import build_parser
    from ipbench.eval.cli_options import parse_seeds

    parser = build_parser()
    default = parser.parse_args(["eval", "calibration"])
    assert parse_seeds(default.seeds) == tuple(range(20)) and default.robot_seed == 1
    one = parser.parse_args(["eval", "calibration", "--seed", "3", "--robot-seed", "none"])
    assert parse_seeds(one.seeds) == (3,) and one.robot_seed is None
