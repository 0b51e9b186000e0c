"""Bad command lines end in one line saying what was wrong and what is valid, before any
work starts; help shows the defaults and the valid names. No episode runs here."""

from __future__ import annotations

import pytest

from ipbench.envs import ENV_IDS
from ipbench.envs.sorting_scenes import SCENES
from ipbench.eval.cli import main
from ipbench.policies import POLICIES


def _error(argv: list[str]) -> str:
    """The message ``ipbench argv`` exits with (one line, no traceback)."""
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    message = exit_info.value.code
    assert isinstance(message, str) and message.startswith("ipbench: "), message
    assert "\n" not in message and "Traceback" not in message
    return message


@pytest.fixture
def wide(monkeypatch) -> None:
    """Help lines as long as they come (argparse wraps to $COLUMNS, also at hyphens)."""
    monkeypatch.setenv("COLUMNS", "10000")


def _help(argv: list[str], capsys) -> str:
    with pytest.raises(SystemExit) as exit_info:
        main([*argv, "--help"])
    assert exit_info.value.code == 0
    return capsys.readouterr().out


def test_repeated_seeds_are_rejected_saying_which_and_how(tmp_path):
    message = _error(["eval", "sorting", "--seeds", "3,3,4", "--out", str(tmp_path / "out")])
    assert "seeds repeat: 3 given more than once" in message and "--seeds 3,4" in message
    assert not (tmp_path / "out").exists()  # nothing run, nothing written


def test_a_ray_address_needs_the_ray_backend(tmp_path):
    message = _error(["eval", "sorting", "--ray-address", "auto", "--out", str(tmp_path)])
    assert "backend is 'process'" in message and "--backend ray" in message


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["--policies", "nosuch"], "unknown policy 'nosuch'; valid: " + ", ".join(POLICIES)),
        (["--policies", ","], "no policy given; valid: "),
        (["--episodes", "0"], "episodes must be between 1 and 1000"),
        (["--episodes", "1001"], "episodes must be between 1 and 1000"),
    ],
)
def test_bench_eval_rejects_bad_settings_before_any_work(argv, expected, tmp_path):
    cache = tmp_path / "cache"
    message = _error(["bench", "eval", *argv, "--cache", str(cache)])
    assert expected in message
    assert "seeds" not in message.split("(")[0]  # about episodes, not the seeds behind them
    assert not cache.exists()  # no model trained


@pytest.mark.parametrize(
    "argv",
    [
        ["bench", "eval"],
        ["eval", "sorting"],
        ["eval", "perception"],
    ],
)
def test_a_file_in_place_of_the_cache_folder_is_explained(argv, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    out = [] if argv[0] == "bench" else ["--out", str(tmp_path / "out")]
    message = _error([*argv, *out, "--cache", str(blocker)])
    assert f"--cache {blocker}: it is a file, not a folder" in message
    assert "pass a folder" in message
    message = _error([*argv, *out, "--cache", str(blocker / "sub")])
    assert f"{blocker} is a file, not a folder" in message


def test_help_shows_defaults_and_valid_names(capsys, wide):
    sorting = _help(["eval", "sorting"], capsys)
    from ipbench.eval.sorting.evaluate import SortingEvalConfig

    seeds = SortingEvalConfig().seeds  # the CLI's default is the configuration's (30 seeds)
    assert seeds == tuple(range(seeds[0], seeds[-1] + 1)) and len(seeds) == 30
    assert f"(default: {seeds[0]}:{seeds[-1] + 1})" in sorting
    assert "(default: uncluttered,cluttered)" in sorting
    assert "(default: results/sorting)" in sorting and "(default: process)" in sorting
    assert "scenes of " + ", ".join(SCENES) in sorting
    assert all(p in sorting for p in POLICIES)
    assert "(default: None)" not in sorting and "(default: False)" not in sorting
    bench = _help(["bench", "eval"], capsys)
    assert "policies to time: " + ", ".join(POLICIES) in bench and "(default: 4)" in bench
    sim = _help(["bench", "sim"], capsys)
    assert "one of " + ", ".join(SCENES) in sim and ", ".join(ENV_IDS) in sim
    from ipbench.envs import LATEST

    assert f"(default: {LATEST})" in sim and f"(default: {LATEST})" in sorting
    assert "scenes of " + ", ".join(SCENES) in _help(["demo"], capsys)
