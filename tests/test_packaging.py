"""The installed package behaves like a Gymnasium env package: ``import ipbench`` registers
every id, ``gym.make("ipbench:<id>")`` needs no import, ``python -m ipbench`` is the
``ipbench`` command, and torch is an optional extra whose absence is named in the error.

Each check runs in a fresh interpreter (a subprocess), since registration happens once per
process. ``make install-check`` checks a plain, non-editable install the same way.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from packaging.requirements import Requirement

ROOT = Path(__file__).resolve().parents[1]


def _python(code: str, cwd: Path = ROOT) -> str:
    """Run ``code`` in a fresh interpreter of this venv; its stdout (fails on a non-zero exit)."""
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_import_ipbench_registers_every_id_once():
    out = _python(
        "import json, warnings\n"
        "import gymnasium as gym\n"
        "before = [i for i in gym.registry if i.startswith('ipbench/')]\n"
        "with warnings.catch_warnings(record=True) as caught:\n"
        "    warnings.simplefilter('always')\n"
        "    import ipbench\n"
        "    import ipbench.envs\n"
        "    gym.make('ipbench:ipbench/Sorting-v2').close()\n"
        "print(json.dumps({\n"
        "    'before': before,\n"
        "    'after': [i for i in gym.registry if i.startswith('ipbench/')],\n"
        "    'all_ids': list(ipbench.envs.ALL_IDS),\n"
        "    'warnings': [str(w.message) for w in caught if 'ipbench' in str(w.message)],\n"
        "}))\n"
    )
    result = json.loads(out)
    assert result["before"] == []
    assert sorted(result["after"]) == sorted(result["all_ids"])
    assert result["warnings"] == []  # no "Overriding environment": registered once


def test_gym_make_with_the_module_prefix_needs_no_import():
    # Gymnasium >= 1.0 loads no plugin entry points: "ipbench:" names the module to import.
    out = _python(
        "import sys\n"
        "import gymnasium as gym\n"
        "assert 'ipbench' not in sys.modules\n"
        "env = gym.make('ipbench:ipbench/Sorting-v2')\n"
        "print(type(env.unwrapped).__name__, env.spec.id)\n"
    )
    assert out.split() == ["SortingEnv", "ipbench/Sorting-v2"]


@pytest.mark.parametrize("where, editable", [("root", True), ("elsewhere", True), ("root", False)])
def test_the_package_resolves_to_the_folders_from_any_directory(where, editable, tmp_path):
    """At the repository root, ``./ipbench`` is on ``sys.path``: it is the package itself, and
    its subpackages are still the top-level folders, also without the editable install's
    finder (as with a plain install, or none)."""
    strip = (
        ""
        if editable
        else "import sys\n"
        "sys.meta_path[:] = [f for f in sys.meta_path\n"
        "                    if not getattr(f, '__module__', '').startswith('__editable__')]\n"
    )
    out = _python(
        strip + "import json\n"
        "from importlib.metadata import version\n"
        "import ipbench, ipbench.assets, ipbench.envs, ipbench.eval, ipbench.perception\n"
        "import ipbench.policies\n"
        "mods = (ipbench, ipbench.assets, ipbench.envs, ipbench.eval, ipbench.perception,\n"
        "        ipbench.policies)\n"
        "print(json.dumps({'files': [m.__file__ for m in mods],\n"
        "                  'version': [ipbench.__version__, version('ipbench')]}))\n",
        cwd=ROOT if where == "root" else tmp_path,
    )
    result = json.loads(out)
    folders = ["ipbench", "assets", "envs", "eval", "perception", "policies"]
    assert result["files"] == [str(ROOT / f / "__init__.py") for f in folders]
    assert result["version"][0] == result["version"][1]


def test_python_m_ipbench_is_the_ipbench_command(tmp_path):
    script = Path(sys.executable).with_name("ipbench")
    assert script.exists(), f"no console script {script}: is ipbench installed in this venv?"
    via_script = subprocess.run(
        [str(script), "--help"], cwd=tmp_path, capture_output=True, text=True, timeout=120
    )
    via_module = subprocess.run(
        [sys.executable, "-m", "ipbench", "--help"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert via_module.returncode == via_script.returncode == 0, via_module.stderr
    assert via_module.stdout.startswith("usage: ipbench ")
    assert via_module.stdout == via_script.stdout


def _torch_extra() -> str:
    """The optional extra of pyproject.toml that declares torch."""
    tomllib = pytest.importorskip("tomllib")
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert all(Requirement(r).name != "torch" for r in project["dependencies"])
    extras = [
        extra
        for extra, reqs in project["optional-dependencies"].items()
        if any(Requirement(r).name == "torch" for r in reqs)
    ]
    assert len(extras) == 1, f"torch in extras {extras}"
    return extras[0]


def test_missing_torch_names_the_extra():
    extra = _torch_extra()
    # Hide torch from the import system (sys.modules["torch"] = None would also break
    # scipy and sklearn, which look torch up in sys.modules).
    out = _python(
        "import sys\n"
        "class NoTorch:\n"
        "    @staticmethod\n"
        "    def find_spec(name, path=None, target=None):\n"
        "        if name.partition('.')[0] == 'torch':\n"
        "            raise ModuleNotFoundError(f'No module named {name!r}', name=name)\n"
        "sys.meta_path.insert(0, NoTorch)\n"
        "try:\n"
        "    import ipbench.perception.pointnet\n"
        "except ModuleNotFoundError as e:\n"
        "    print(e.name)\n"
        "    print(e)\n"
        "else:\n"
        "    print('imported without torch')\n"
    )
    lines = out.splitlines()
    assert lines[0] == "torch", out
    assert f"pip install 'ipbench[{extra}]'" in lines[1]
