"""The README stays short and the documentation site stays whole.

README.md: at most :data:`README_MAX_LINES` lines, the two markers between which
``ipbench report docs`` writes the headline result, and relative links that resolve.
``docs/environments.md`` names every registered id; every page of the ``mkdocs.yml`` nav
exists; and, where MkDocs is installed (the ``docs`` extra), the site builds with
``mkdocs build --strict`` (no warning: no broken link, no API object that cannot be found).
"""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import ipbench.envs

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
DOCS = ROOT / "docs"
MKDOCS_YML = ROOT / "mkdocs.yml"
README_MAX_LINES = 250
HEADLINE_START = "<!-- results:headline:start -->"
HEADLINE_END = "<!-- results:headline:end -->"
DOCS_TOOLS = ("mkdocs", "material", "mkdocstrings", "mkdocstrings_handlers.python")


def _nav_pages() -> list[str]:
    """The pages (``*.md``, relative to ``docs/``) listed under ``nav:`` in mkdocs.yml, read
    as text so that no YAML library (nor mkdocs.yml's ``!relative`` tag) is needed."""
    text = MKDOCS_YML.read_text(encoding="utf-8")
    found = re.search(r"^nav:\n((?:[ \t]+.*\n?|\n)*)", text, re.M)
    assert found, "mkdocs.yml has no nav"
    return re.findall(r"^[ \t]*-[ \t]*(?:[^:\n]*:[ \t]*)?([\w./-]+\.md)[ \t]*$", found[1], re.M)


def test_readme_is_short():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES, (
        f"README.md has {len(lines)} lines (at most {README_MAX_LINES}): move details to docs/"
    )


def test_readme_has_the_headline_markers_in_order():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert lines.count(HEADLINE_START) == 1, f"README.md needs one line {HEADLINE_START}"
    assert lines.count(HEADLINE_END) == 1, f"README.md needs one line {HEADLINE_END}"
    assert lines.index(HEADLINE_START) < lines.index(HEADLINE_END)
    assert "docs/results/sorting.md" in README.read_text(encoding="utf-8")


def test_readme_links_resolve():
    text = README.read_text(encoding="utf-8")
    links = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    local = [link for link in links if not re.match(r"[a-z]+:", link)]
    assert local, "README.md links into docs/"
    missing = [link for link in local if not (ROOT / link).exists()]
    assert not missing, f"README.md links to missing files: {missing}"


def test_every_registered_id_is_documented():
    page = (DOCS / "environments.md").read_text(encoding="utf-8")
    missing = [env_id for env_id in ipbench.envs.ALL_IDS if f"`{env_id}`" not in page]
    assert not missing, f"docs/environments.md does not list {missing}"


def test_every_nav_page_exists():
    pages = _nav_pages()
    expected = {"index.md", "custom.md", "results/index.md", "results/sorting.md"}
    assert expected | {"results/perception.md", "api.md", "changelog.md"} <= set(pages)
    missing = [page for page in pages if not (DOCS / page).is_file()]
    assert not missing, f"pages in the mkdocs.yml nav that do not exist under docs/: {missing}"


@pytest.mark.parametrize(
    "path",
    ["README.md", *sorted(f"docs/{p.name}" for p in DOCS.glob("*.md") if p.name != "custom.md")],
)
def test_the_docs_name_no_machine_and_no_commit(path):
    """What ``tests/test_no_history.py`` leaves to this test: the docs describe the software on
    any machine (measured figures live on the generated results pages), and no commit."""
    text = (ROOT / path).read_text(encoding="utf-8")
    # the generated headline names its run's content keys (perception models), not a commit
    text = re.sub(
        r"<!-- results:headline:start -->.*<!-- results:headline:end -->", "", text, flags=re.S
    )
    for pattern, flags, what in [
        (r"\bthis machine\b", re.I, "a particular machine"),
        (r"(?<![\w/.-])(?=[0-9a-f]*[a-f])(?=[0-9a-f]*\d)[0-9a-f]{7,40}(?![\w/.-])", 0, "a hash"),
    ]:
        found = re.search(pattern, text, flags)
        assert not found, f"{path} names {what}: {found[0]!r}"


@pytest.mark.skipif(
    any(importlib.util.find_spec(name.split(".")[0]) is None for name in DOCS_TOOLS),
    reason="the docs tools are not installed (pip install -e '.[docs]')",
)
def test_the_site_builds_strictly(tmp_path):
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    run = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict"]
        + ["-f", str(MKDOCS_YML), "-d", str(tmp_path / "site")],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    # not --quiet: it hides the warnings that --strict counts, and the build then passes
    assert run.returncode == 0, f"mkdocs build --strict failed:\n{run.stdout}\n{run.stderr}"
    assert (tmp_path / "site" / "api" / "index.html").is_file()
