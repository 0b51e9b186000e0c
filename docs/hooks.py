"""MkDocs hooks of the ipbench site (``mkdocs.yml``: ``hooks: [docs/hooks.py]``).

Two things the site needs that MkDocs cannot do by configuration alone:

* The API reference: ``pyproject.toml`` maps the package ``ipbench`` and its subpackages from
  separate top-level folders (``package-dir``), a layout that griffe, which reads the sources
  for mkdocstrings, cannot search. :func:`on_config` lays the package out as Python would see
  it, in a temporary folder of symbolic links to the real sources, and points mkdocstrings
  there. Nothing is imported, so building the docs needs neither MuJoCo nor a display.
* The docstrings' Sphinx roles (``:func:`~ipbench.envs.env_config```): :class:`SphinxRoles`,
  a griffe extension, shows them as code, as Markdown would write them.
* The pictures: :data:`IMAGES` live in ``assets/`` beside the code that draws them
  (``ipbench figures``); :func:`on_files` adds them to the site under ``img/`` instead of
  keeping copies under ``docs/``.
"""

from __future__ import annotations

import atexit
import re
import shutil
import tempfile
from pathlib import Path

import griffe
from mkdocs.config.defaults import MkDocsConfig
from mkdocs.plugins import event_priority
from mkdocs.structure.files import File, Files

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    tomllib = None

__all__ = ["IMAGES", "ROOT", "SphinxRoles", "on_config", "on_files", "package_tree", "plain_roles"]

ROOT = Path(__file__).resolve().parent.parent
"""The repository (the folder of ``mkdocs.yml`` and ``pyproject.toml``)."""
IMAGES: tuple[str, ...] = ("assets/workcell.png", "assets/objects_v2.png", "assets/depth_v2.png")
"""Pictures of the repository that the pages show, as ``img/<name>``."""

_TREE: Path | None = None
_ROLE = re.compile(r":(?:py:)?(?:attr|class|const|data|exc|func|meth|mod|obj):`(~?)([^`]+)`")


def plain_roles(text: str) -> str:
    """``text`` with Sphinx roles as code (``:func:`~a.b``` -> ```b```, ``:mod:`a.b``` ->
    ```a.b```) and reST's ``::`` before a literal block as a colon."""
    text = _ROLE.sub(lambda m: f"`{m[2].rsplit('.', 1)[-1] if m[1] else m[2]}`", text)
    return re.sub(r"(?<=\S)::$", ":", text, flags=re.M)


class SphinxRoles(griffe.Extension):
    """A griffe extension: every docstring through :func:`plain_roles` before it is parsed."""

    def on_instance(self, *, obj: griffe.Object, **kwargs) -> None:
        if obj.docstring is not None:
            obj.docstring.value = plain_roles(obj.docstring.value)


def _package_dirs(pyproject: Path) -> dict[str, Path]:
    """``[tool.setuptools] package-dir`` of ``pyproject``: package name -> its folder."""
    if tomllib is None:
        raise RuntimeError("building the docs needs Python >= 3.11 (tomllib reads pyproject.toml)")
    with pyproject.open("rb") as f:
        mapping = tomllib.load(f)["tool"]["setuptools"]["package-dir"]
    return {name: (pyproject.parent / folder).resolve() for name, folder in mapping.items()}


def package_tree(pyproject: Path, dest: Path) -> Path:
    """Lay the packages of ``pyproject``'s ``package-dir`` out under ``dest`` as importable
    folders (``dest/ipbench/envs`` -> the ``envs`` folder, ...) of symbolic links, and return
    ``dest``. A package with mapped subpackages (``ipbench`` itself) becomes a real folder
    holding links to its own ``*.py`` files, so that its subpackages can sit beside them."""
    dirs = _package_dirs(pyproject)
    for name in sorted(dirs, key=lambda n: n.count(".")):
        target = dest.joinpath(*name.split("."))
        if any(other.startswith(name + ".") for other in dirs):
            target.mkdir(parents=True, exist_ok=True)
            for source in sorted(dirs[name].glob("*.py")):
                (target / source.name).symlink_to(source)
        else:
            target.parent.mkdir(parents=True, exist_ok=True)
            target.symlink_to(dirs[name], target_is_directory=True)
    return dest


@event_priority(100)  # before mkdocstrings reads its handler options
def on_config(config: MkDocsConfig) -> MkDocsConfig:
    """Point mkdocstrings' Python handler at the package tree (made once per process)."""
    global _TREE
    if _TREE is None:
        _TREE = package_tree(ROOT / "pyproject.toml", Path(tempfile.mkdtemp(prefix="ipbench-")))
        atexit.register(shutil.rmtree, _TREE, ignore_errors=True)
    handlers = config.plugins["mkdocstrings"].config.handlers
    python = handlers.setdefault("python", {})
    python["paths"] = [str(_TREE)]
    extensions = python.setdefault("options", {}).setdefault("extensions", [])
    roles = f"{Path(__file__).resolve()}:SphinxRoles"
    if roles not in extensions:  # `mkdocs serve` calls this again on every rebuild
        extensions.append(roles)
    return config


def on_files(files: Files, config: MkDocsConfig) -> Files:
    """Add :data:`IMAGES` to the site as ``img/<name>``."""
    for image in IMAGES:
        path = ROOT / image
        files.append(File.generated(config, f"img/{path.name}", abs_src_path=str(path)))
    return files
