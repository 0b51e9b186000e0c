"""The ipbench command explains itself and rejects bad input clearly."""

from __future__ import annotations

import json

import imageio.v2 as imageio
import numpy as np
import pytest

from ipbench.eval.cli import build_parser, main
from ipbench.eval.video import write_mp4


def test_help_lists_the_commands(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    assert "demo" in out and "bench" in out and "interactive perception" in out


def test_bench_sim_help(capsys):
    with pytest.raises(SystemExit):
        main(["bench", "sim", "--help"])
    assert "stereo" in capsys.readouterr().out


def test_unknown_scene_is_rejected_with_the_valid_names():
    with pytest.raises(SystemExit, match="valid scenes: uncluttered, cluttered"):
        main(["demo", "--scenes", "kitchen", "--no-video"])


def test_unwritable_output_is_rejected(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(SystemExit, match="cannot write to"):
        main(["demo", "--out", str(blocker / "sub"), "--scenes", "uncluttered"])


def test_parser_defaults():
    args = build_parser().parse_args(["demo"])
    assert args.scenes == "uncluttered,cluttered" and args.seed == 0


def test_mp4_decodes_to_the_written_frames(tmp_path):
    frames = [np.full((48, 64, 3), 20 * i, np.uint8) for i in range(10)]
    path = write_mp4(tmp_path / "v.mp4", frames, fps=10)
    reader = imageio.get_reader(path)
    decoded = [f for f in reader]
    assert len(decoded) == 10 and decoded[0].shape == (48, 64, 3)
    assert abs(float(decoded[5].mean()) - 100) < 5


def test_demo_writes_summary_and_video(tmp_path):
    from ipbench.eval.sorting.demo import run_demo

    summary = run_demo(tmp_path, scenes=("uncluttered",), seed=1, video=True, max_steps=2)
    saved = json.loads((tmp_path / "demo_summary.json").read_text())
    assert saved == summary
    assert saved["uncluttered"]["steps"] == 2 and saved["uncluttered"]["objects"] == 10
    reader = imageio.get_reader(tmp_path / "demo_uncluttered.mp4")
    assert reader.get_data(0).shape == (480, 640, 3)


def test_unknown_env_id_is_rejected_with_the_valid_ids(tmp_path):
    for argv in (
        ["eval", "perception", "--env", "ipbench/Sorting-v9", "--out", str(tmp_path)],
        ["bench", "sim", "--env", "ipbench/Kitchen-v0"],
        ["figures", "--env", "Sorting-v2", "--out", str(tmp_path)],
    ):
        with pytest.raises(SystemExit, match="valid: ipbench/Sorting-v0.*ipbench/Sorting-v2"):
            main(argv)
    assert not any(tmp_path.iterdir())  # nothing written


def test_gallery_shows_every_family_once_on_the_table():
    from ipbench.assets.objects import FAMILIES
    from ipbench.envs.sorting import workcell_places
    from ipbench.eval.capture.figures import gallery_layout

    layout = gallery_layout("v2")
    shown = [(o.instance.category, o.instance.family) for o in layout.objects]
    assert sorted(shown) == sorted((c, f) for c, fs in FAMILIES.items() for f in fs)
    table = workcell_places().table_top
    for o in layout.objects:
        assert np.all(np.abs(np.asarray(o.position[:2]) - table.center[:2]) < table.half[:2])


def test_unknown_classifier_is_rejected_with_the_valid_ones(tmp_path):
    with pytest.raises(SystemExit, match="valid: gp, gp_mode, svm, sklearn_gp"):
        main(["eval", "perception", "--classifiers", "gp,forest", "--out", str(tmp_path)])
    assert not any(tmp_path.iterdir())
