"""ipbench: a MuJoCo benchmark for robotic interactive perception on the CloPeMa dual-arm
work cell.

Importing the package registers every Gymnasium id of :data:`ipbench.envs.ALL_IDS`::

    import gymnasium as gym
    import ipbench

    gym.register_envs(ipbench)  # optional: tells linters the import is used
    env = gym.make("ipbench/Sorting-v2")

``gym.make("ipbench:ipbench/Sorting-v2")`` needs no import: Gymnasium imports the module
named before the colon. (Gymnasium 1.0 dropped the plugin entry points with which older
releases registered installed packages' ids on ``import gymnasium``.)

The subpackages are the repository's top-level folders: ``assets``, ``envs``, ``perception``,
``policies`` and ``eval`` (the ``ipbench`` command, also run as ``python -m ipbench``).

Rendering is headless: on Linux, ``MUJOCO_GL`` and ``PYOPENGL_PLATFORM`` default to ``egl``
(as in the ``ipbench`` command) when unset, since MuJoCo picks its OpenGL backend when it is
first imported, which registering the ids does.
"""

import os
import sys
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

__all__ = ["__version__"]

_here = Path(__file__).resolve().parent
if not (_here / "envs").is_dir() and (_here.parent / "envs" / "__init__.py").is_file():
    # Imported from the source tree (e.g. Python started at the repository root, whose
    # ipbench/ comes first on sys.path): the subpackages are the folders beside this one, as
    # pyproject.toml maps them, whichever way ipbench is installed.
    __path__.append(str(_here.parent))

if sys.platform.startswith("linux"):
    os.environ.setdefault("MUJOCO_GL", "egl")
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

from ipbench import envs  # noqa: E402, F401  (registers the ids)

try:
    __version__: str = version("ipbench")
    """The installed distribution's version (``pyproject.toml``)."""
except PackageNotFoundError:  # a source tree that was never installed
    __version__ = "0+unknown"
