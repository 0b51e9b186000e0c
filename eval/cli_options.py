"""Command-line options that several ``ipbench`` commands share, defined once."""

from __future__ import annotations

import argparse

__all__ = ["add_json_option"]

FIGURES_HELP = "also write the figures as one JSON object (to FILE, or stdout with no FILE)"


def add_json_option(parser: argparse.ArgumentParser, help: str = FIGURES_HELP) -> None:
    """``--json [FILE]``: ``args.json`` is None without it, ``"-"`` (stdout) with no FILE."""
    parser.add_argument("--json", nargs="?", const="-", default=None, metavar="FILE", help=help)
