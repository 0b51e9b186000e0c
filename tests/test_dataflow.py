"""Data flows one way: assets -> envs -> observation -> perception -> policies -> eval.

Perception reads observations only; the capture rigs that render its training data with the
simulator live in :mod:`ipbench.eval.capture`. Inside ``eval/`` the rooms are layered too:
the shared core (episode log, workers, statistics, files, video) imports no room; capture
imports no other room; the task families import capture and (sorting) the perception
evaluation's models, never each other; the results pages read files and the task families'
report code, never the simulator; only the command line (``cli.py``), the benchmarks and
``repro`` span rooms. This checks the
imports of every source file.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# package folder -> the ipbench subpackages it must not import
FORBIDDEN = {
    "assets": ("envs", "perception", "policies", "eval"),
    "perception": ("envs", "policies", "eval"),
    "envs": ("perception", "policies", "eval"),
    "policies": ("eval",),
}


# eval room (a sub-folder, or "core" for the files at eval/'s top) -> the rooms it may import
EVAL_ROOMS = {
    "core": (),
    "capture": ("core",),
    "perception": ("core", "capture"),
    "sorting": ("core", "capture", "perception"),
    "exploration": ("core", "capture"),
    "calibration": ("core",),
    "report": ("core", "sorting", "exploration", "perception"),
    "repro": ("core", "capture", "perception", "sorting", "exploration", "calibration"),
    "bench": ("core", "capture", "perception", "sorting", "exploration", "calibration"),
}
SPANS_ROOMS = ("cli.py",)
"""Files that may import any room: the command line registers every room's commands."""
NO_SIMULATOR = ("core", "report")
"""Rooms that never import ``ipbench.envs``."""


def _imports(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
    return names


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_no_import_against_the_data_flow(package):
    offending = []
    for path in sorted((ROOT / package).rglob("*.py")):
        for name in _imports(path):
            parts = name.split(".")
            if parts[0] == "ipbench" and len(parts) > 1 and parts[1] in FORBIDDEN[package]:
                offending.append(f"{path.relative_to(ROOT)} imports {name}")
    assert not offending, "\n".join(offending)


def _room(path: Path) -> str:
    parts = path.relative_to(ROOT / "eval").parts
    return parts[0] if len(parts) > 1 else "core"


def _eval_offences(path: Path) -> list[str]:
    room, rooms = _room(path), set(EVAL_ROOMS)
    out = []
    for name in sorted(_imports(path)):
        parts = name.split(".")
        if (
            parts[:2] == ["ipbench", "envs"]
            and room in NO_SIMULATOR
            and path.name not in SPANS_ROOMS
        ):
            out.append(f"{path.relative_to(ROOT)} ({room}) imports {name}")
        if parts[:2] != ["ipbench", "eval"] or len(parts) < 3 or path.name in SPANS_ROOMS:
            continue
        target = parts[2] if parts[2] in rooms else "core"
        if target != room and target not in EVAL_ROOMS[room]:
            out.append(f"{path.relative_to(ROOT)} ({room}) imports {name}")
    return out


def test_eval_rooms_import_down_only():
    rooms = {_room(p) for p in (ROOT / "eval").rglob("*.py")}
    assert rooms == set(EVAL_ROOMS), "every folder of eval/ has its place in EVAL_ROOMS"
    offending = [o for p in sorted((ROOT / "eval").rglob("*.py")) for o in _eval_offences(p)]
    assert not offending, "\n".join(offending)


def test_the_eval_room_check_sees_a_violation(tmp_path):
    room = tmp_path / "eval" / "capture"
    room.mkdir(parents=True)
    bad = room / "bad.py"
    bad.write_text("from ipbench.eval.sorting.evaluate import run_episode\n")
    global ROOT
    saved, ROOT = ROOT, tmp_path
    try:
        assert _eval_offences(bad) == [
            "eval/capture/bad.py (capture) imports ipbench.eval.sorting.evaluate",
            "eval/capture/bad.py (capture) imports ipbench.eval.sorting.evaluate.run_episode",
        ]
    finally:
        ROOT = saved


# envs sub-package -> the ipbench modules (prefixes) it may import: the sensor models stand
# alone (pixels from an image and a model); the cell's errors need the sensors' lenses, the
# pan-tilt units and the assets' mounting frames
ENVS_ROOMS = {
    "sensors": ("ipbench.envs.sensors",),
    "cell": ("ipbench.assets", "ipbench.envs.cell", "ipbench.envs.sensors", "ipbench.envs.ptu"),
}


@pytest.mark.parametrize("room", sorted(ENVS_ROOMS))
def test_envs_sub_packages_import_only_what_they_build_on(room):
    offending = []
    for path in sorted((ROOT / "envs" / room).rglob("*.py")):
        for name in sorted(_imports(path)):
            if name.startswith("ipbench") and not name.startswith(ENVS_ROOMS[room]):
                offending.append(f"{path.relative_to(ROOT)} imports {name}")
    assert not offending, "\n".join(offending)


def test_the_check_sees_a_violation(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("from ipbench.envs.sorting import SortingEnv\nimport ipbench.policies\n")
    assert {"ipbench.envs.sorting", "ipbench.policies"} <= _imports(bad)
