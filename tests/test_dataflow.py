"""Data flows one way: assets -> envs -> observation -> perception -> policies -> eval.

Perception reads observations only; the capture rigs that render its training data with the
simulator live in :mod:`ipbench.eval`. This checks the imports of every source file.
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


def test_the_check_sees_a_violation(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("from ipbench.envs.sorting import SortingEnv\nimport ipbench.policies\n")
    assert {"ipbench.envs.sorting", "ipbench.policies"} <= _imports(bad)
