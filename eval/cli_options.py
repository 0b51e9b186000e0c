"""What several ``ipbench`` commands share, defined once: the ``--json`` option, the parsing of
seeds, thresholds and comma-separated names, output folders checked before any work, and
running a command to its printed summary with errors as one-line exits."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path

__all__ = [
    "add_json_option",
    "parse_names",
    "parse_seeds",
    "parse_thresholds",
    "print_figures",
    "run_to_summary",
    "writable",
]

FIGURES_HELP = "also write the figures as one JSON object (to FILE, or stdout with no FILE)"


def add_json_option(parser: argparse.ArgumentParser, help: str = FIGURES_HELP) -> None:
    """``--json [FILE]``: ``args.json`` is None without it, ``"-"`` (stdout) with no FILE."""
    parser.add_argument("--json", nargs="?", const="-", default=None, metavar="FILE", help=help)


def parse_names(
    text: str, valid: Iterable[str], what: str, valid_label: str = "valid"
) -> tuple[str, ...]:
    """Comma-separated names, each one of ``valid``; else exit saying which are unknown and
    listing the valid ones (``what``: e.g. ``"scene(s)"``)."""
    valid = tuple(valid)
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    bad = [n for n in names if n not in valid]
    if bad or not names:
        raise SystemExit(
            f"ipbench: unknown {what} {', '.join(bad) or '(none)'}; "
            f"{valid_label}: {', '.join(valid)}"
        )
    return names


def parse_seeds(text: str) -> tuple[int, ...]:
    """``--seeds``: ``A:B`` (A .. B-1) or a comma-separated list of integers >= 0."""
    try:
        if ":" in text:
            a, b = (int(v) for v in text.split(":"))
            seeds = tuple(range(a, b))
        else:
            seeds = tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        seeds = ()
    if not seeds or min(seeds) < 0:
        raise SystemExit(
            f"ipbench: bad --seeds {text!r}; give A:B with 0 <= A < B (e.g. 0:30) or a "
            "comma-separated list of non-negative integers"
        )
    return seeds


def parse_size(text: str, option: str = "--head-size") -> tuple[int, int]:
    """An image size ``HxW`` (height and width in pixels, e.g. ``3264x4928``) as (H, W)."""
    parts = text.lower().split("x")
    if len(parts) == 2 and all(p.strip().isdigit() and int(p) > 0 for p in parts):
        return int(parts[0]), int(parts[1])
    raise SystemExit(
        f"ipbench: bad {option} {text!r}; give HEIGHTxWIDTH in pixels, both > 0 "
        "(e.g. 680x1024, 1632x2464 or 3264x4928)"
    )


def parse_thresholds(text: str | None) -> tuple[float, ...]:
    """``--thresholds`` as floats in [0, 1] (None: none given)."""
    if text is None:
        return ()
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        values = ()
    if not values or not all(0.0 <= v <= 1.0 for v in values) or len(set(values)) < len(values):
        raise SystemExit(
            f"ipbench: bad --thresholds {text!r}; give distinct comma-separated confidences in "
            "[0, 1], e.g. 0.5,0.8,1.0"
        )
    return values


def writable(path: Path, option: str) -> None:
    """Create folder ``path`` (given as ``option``) or exit with a one-line reason and fix."""
    from ipbench.eval.files import ensure_writable

    path = Path(path)
    blocker = next((p for p in (path, *path.parents) if p.exists() and not p.is_dir()), None)
    if blocker is not None:
        what = "it is a file" if blocker == path else f"{blocker} is a file"
        raise SystemExit(
            f"ipbench: cannot write to {option} {path}: {what}, not a folder; pass a folder "
            "(created if missing), or move the file away"
        )
    try:
        ensure_writable(path)
    except OSError as err:
        raise SystemExit(
            f"ipbench: cannot write to {option} {path}: {err.strerror or err}; pass a folder "
            "you can write to"
        ) from err


def print_figures(figures: dict, json_arg: str | None, report: Callable) -> None:
    """Print ``report(figures, path)`` (``path``: ``--json FILE``, else None) and, with a bare
    ``--json``, the figures as one JSON line."""
    path = None if json_arg in (None, "-") else Path(json_arg)
    print(report(figures, path))
    if json_arg == "-":
        print(json.dumps(figures))


def run_to_summary(
    run: Callable[[], Mapping],
    rows: Callable[[Mapping], Iterable[str]],
    written: str,
    errors: tuple[type[Exception], ...] = (),
) -> int:
    """A command's run, then its summary: ``run()`` checks the configuration and does the
    work; an error of ``errors`` exits with its one-line message (``ipbench: ...``); then
    every line of ``rows(result)`` and ``written`` (where the output went) are printed.
    Returns 0."""
    try:
        result = run()
    except errors as err:
        raise SystemExit(f"ipbench: {err}") from err
    for line in rows(result):
        print(line)
    print(written)
    return 0
