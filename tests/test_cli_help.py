"""Every ``ipbench`` command's ``--help``: exit 0, each default shown, one example at the end.

The commands are found by walking the parser, so a new subcommand is checked without being
listed here.
"""

from __future__ import annotations

import argparse

import pytest

from ipbench.eval.cli import build_parser, main


def _commands(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()):
    """``(path, parser)`` of ``parser`` and of every subcommand under it, depth first."""
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _commands(sub, (*path, name))


COMMANDS = dict(_commands(build_parser()))


def test_the_walk_finds_the_nested_commands():
    assert {(), ("eval", "sorting"), ("bench", "sim"), ("calibrate",)} <= set(COMMANDS)


def _shown(default) -> bool:
    return default not in (None, argparse.SUPPRESS) and not isinstance(default, bool)


@pytest.mark.parametrize("path", list(COMMANDS), ids=lambda p: " ".join(("ipbench", *p)))
def test_help_shows_defaults_and_ends_with_an_example(path, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")  # long default paths are not broken across lines
    with pytest.raises(SystemExit) as exit_:
        main([*path, "--help"])
    assert exit_.value.code == 0
    text = capsys.readouterr().out
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    assert lines[-2] == "example:", f"ipbench {' '.join(path)} --help ends without an example"
    assert lines[-1].startswith("ipbench "), lines[-1]
    assert lines[-1].startswith(" ".join(("ipbench", *path))), lines[-1]
    flat = " ".join(text.split())
    for action in COMMANDS[path]._actions:
        if action.option_strings and _shown(action.default):
            assert f"default: {action.default}" in flat, (path, action.option_strings)
