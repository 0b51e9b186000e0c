"""The project speaks of itself: its docs, code, data and tests say what the software is and why,
never how it came to be. No text file tells in which round of work it was written, names a tracker
issue by number or a commit hash, or cites the facts sheets kept outside the repository (cite the
publication a number comes from instead). CHANGELOG.md keeps version history in user terms and is
not read.

On failure the message lists every ``file:line: text`` that matches.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SELF = Path(__file__).resolve()
ROOTS = ("README.md", "docs", "examples", "assets", "envs", "perception", "policies", "eval")
ROOTS += ("tests",)
"""What is read (a folder recursively; one that does not exist is skipped)."""
SUFFIXES = frozenset(
    {".py", ".md", ".rst", ".txt", ".xml", ".toml", ".yml", ".yaml", ".json", ".cfg", ".ini"}
)
"""Text files read. JSON data is read too: hex digests alone match none of the patterns."""
SKIP_DIRS = frozenset({"__pycache__", ".ipynb_checkpoints", ".pytest_cache", ".ruff_cache"})

# Built from pieces, so that this file does not match its own patterns.
_FACTS = "fa" + "cts"
PATTERNS: dict[str, re.Pattern[str]] = {
    "round of work": re.compile(r"\bsess" + r"ions?\b", re.IGNORECASE),
    "issue number": re.compile(r"\bis" + r"sue \d+", re.IGNORECASE),
    "commit hash": re.compile(r"\bcom" + r"mit [0-9a-f]{7,40}\b", re.IGNORECASE),
    "facts sheet": re.compile(
        rf"shared/{_FACTS}|\b(?:robot|sensor_and_calibration)_{_FACTS}\.md\b", re.IGNORECASE
    ),
}
"""What a project file must not say, by kind."""


def text_files(top: Path) -> list[Path]:
    """The text files at or under ``top`` (sorted; this test file excluded)."""
    if top.is_file():
        files = [top]
    elif top.is_dir():
        files = [
            p
            for p in top.rglob("*")
            if p.is_file() and not SKIP_DIRS.intersection(p.relative_to(top).parts[:-1])
        ]
    else:
        return []
    return sorted(p for p in files if p.suffix.lower() in SUFFIXES and p.resolve() != SELF)


def history_lines(path: Path) -> list[str]:
    """``file:line: [kind] text`` for every line of ``path`` that matches a pattern."""
    found = []
    text = path.read_text(encoding="utf-8", errors="replace")
    for number, line in enumerate(text.splitlines(), start=1):
        kinds = [kind for kind, pattern in PATTERNS.items() if pattern.search(line)]
        if kinds:
            where = path.relative_to(ROOT).as_posix()
            found.append(f"{where}:{number}: [{', '.join(kinds)}] {line.strip()[:160]}")
    return found


@pytest.mark.parametrize("top", ROOTS)
def test_no_development_history(top):
    path = ROOT / top
    if not path.exists():
        pytest.skip(f"{top} is not in this checkout")
    found = [hit for file in text_files(path) for hit in history_lines(file)]
    assert not found, (
        f"{len(found)} line(s) under {top} speak of how the project came to be; say what the "
        "code is and why instead:\n" + "\n".join(found)
    )


@pytest.mark.parametrize(
    "line",
    [
        "written in sess" + "ion 6",
        "see is" + "sue 14 part 5",
        "from com" + "mit d4debf9",
        "numbers of shared/" + _FACTS + "/robot_" + _FACTS + ".md",
        "(robot_" + _FACTS + ".md §2.6)",
    ],
)
def test_the_patterns_catch_history(line):
    assert any(p.search(line) for p in PATTERNS.values()), line


@pytest.mark.parametrize(
    "line",
    [
        '"head_left": "1071274d1c0a0dc7",',  # a recorded digest
        "sha256 9f2c4e1a7b3d5f60 of the committed file",
        "libfreenect2 is" + "sue #854 'a few pixels'",  # an upstream issue, cited by name
        "the D47 manual: pan speeds over 300 deg/s",
    ],
)
def test_the_patterns_spare_ordinary_text(line):
    assert not any(p.search(line) for p in PATTERNS.values()), line
