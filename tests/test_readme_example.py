"""The README's Python example runs as written, and its pick succeeds.

The example is read from README.md (its first ``python`` block), never copied here, and run in
a fresh interpreter from the repository root, as a user who has run ``make test`` would: its
own ``assert`` fails unless the pick held an object.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"


def readme_example() -> str:
    """The first fenced ``python`` block of README.md."""
    found = re.search(r"^```python\n(.*?)^```", README.read_text(encoding="utf-8"), re.S | re.M)
    assert found, "README.md has no ```python block (the Gymnasium example)"
    return found.group(1)


def test_the_example_is_short_and_checks_its_pick():
    code = readme_example()
    assert "import ipbench" in code and "gym.make(" in code
    assert 'info["skills"][0]["success"]' in code, "the example must assert its pick succeeded"
    assert len(code.splitlines()) <= 20, "keep the README example short"
    assert 'info["objects"]' not in code, "a policy reads the observation, not ground truth"


def test_the_example_runs_and_its_pick_succeeds():
    env = {**os.environ, "MUJOCO_GL": "egl", "PYOPENGL_PLATFORM": "egl"}
    run = subprocess.run(
        [sys.executable, "-c", readme_example()],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, f"the README example failed:\n{run.stdout}\n{run.stderr}"
    assert "'name': 'pick'" in run.stdout and "'success': True" in run.stdout, run.stdout
