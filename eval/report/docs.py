"""``ipbench report docs``: the documentation's results pages, generated from results files.

ipbench report docs --from RESULTS_DIR [--out docs/results] [--readme README.md] [--headline RUN]

Numbers measured by runs are never copied into the documentation by hand. This command finds
the runs under ``--from`` (:mod:`ipbench.eval.report.runs`: sorting, exploration, perception and
multi-seed calibration run folders, an ``ipbench check --json`` report) and writes into
``--out``:

* ``index.md``: what was run, with what and on what platform (:mod:`ipbench.eval.report.index`);
* ``sorting.md`` and its curve figures ``curve-<run>.png`` (:mod:`ipbench.eval.report.sorting`);
* ``exploration.md`` and its recall figures ``exploration-<run>.png``
  (:mod:`ipbench.eval.report.exploration`);
* ``perception.md`` (:mod:`ipbench.eval.report.perception`);
* ``calibration.md`` and its spread figures ``calibration-<run>.png``
  (:mod:`ipbench.eval.report.calibration`);
* ``data/<run>/...``: the small files the pages were rendered from (and ``data/<check>.json``).

Every page says at its top that it is generated and from which files. The renderer is
deterministic and reads nothing but those files, so ``ipbench report docs --from
docs/results/data`` reproduces the pages byte for byte: the pages cannot drift from their
data. With ``--readme FILE`` the headline table (:mod:`ipbench.eval.report.readme`) replaces the
text between the README's markers, and, when there is a calibration run, the calibration table
(:mod:`ipbench.eval.report.readme_calibration`) the text between its own markers, and when
there is an exploration run, the exploration table
(:mod:`ipbench.eval.report.readme_exploration`) the text between its own; nothing else.
Everything is read and checked before anything is written; files of an earlier generation that
this one does not write (under ``data/``, ``curve-*.png``, ``exploration-*.png`` and
``calibration-*.png``) are removed, when ``--out`` holds generated pages.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from ipbench.eval.markdown import GENERATED_MARK
from ipbench.eval.report.runs import DocsReportError, discover

__all__ = [
    "DocsReport",
    "DocsReportError",
    "add_report_parser",
    "main_report",
    "render_docs",
    "report_docs",
]

PAGES: tuple[str, ...] = (
    "index.md",
    "sorting.md",
    "exploration.md",
    "perception.md",
    "calibration.md",
)
"""The pages written (each, even with no run of its kind: the site's navigation lists them)."""
_OWN_SUFFIXES = (".json", ".png")
_OWN_FIGURES = ("curve-*.png", "exploration-*.png", "calibration-*.png")


@dataclass(frozen=True)
class DocsReport:
    """What :func:`report_docs` did: ``written`` and ``removed`` files (under ``out``, or the
    README), ``unchanged`` files left as they were, and ``notes`` on what was skipped."""

    written: tuple[Path, ...]
    unchanged: tuple[Path, ...]
    removed: tuple[Path, ...]
    notes: tuple[str, ...]


def render_docs(found) -> dict[str, bytes]:
    """Every output file of the discovered runs (:class:`~ipbench.eval.report.runs.Discovery`):
    path relative to ``--out`` -> content."""
    from ipbench.eval.report.calibration import calibration_figure_name, calibration_page
    from ipbench.eval.report.calibration_data import FIGURE
    from ipbench.eval.report.exploration import exploration_figure_name, exploration_page
    from ipbench.eval.report.index import index_page
    from ipbench.eval.report.perception import perception_page
    from ipbench.eval.report.sorting import curve_figure_name, sorting_page

    sorting, calibration = found.of_kind("sorting"), found.of_kind("calibration")
    exploration = found.of_kind("exploration")
    files = {
        "index.md": index_page(found).encode(),
        "sorting.md": sorting_page(sorting).encode(),
        "exploration.md": exploration_page(exploration).encode(),
        "perception.md": perception_page(found.of_kind("perception")).encode(),
        "calibration.md": calibration_page(calibration).encode(),
    }
    for run in sorting:
        if "curve.png" in run.files and "curve.json" in run.files:
            files[curve_figure_name(run)] = run.files["curve.png"]
    for run in exploration:
        if "recall.png" in run.files:
            files[exploration_figure_name(run)] = run.files["recall.png"]
    for run in calibration:
        if FIGURE in run.files:
            files[calibration_figure_name(run)] = run.files[FIGURE]
    for run in found.runs:
        for name, content in run.files.items():
            files[f"data/{run.name}/{name}"] = content
    if found.check is not None:
        files[found.check.source] = found.check.content
    return files


def _stale(out: Path, files: Mapping[str, bytes]) -> list[Path]:
    """Files of an earlier generation in ``out`` that ``files`` does not hold: none unless
    ``out/index.md`` is a generated page (another folder's files are never touched)."""
    index = out / "index.md"
    if not (index.is_file() and index.read_text("utf-8").startswith(GENERATED_MARK)):
        return []
    keep = {out / name for name in files}
    data = out / "data"
    old = [p for p in data.rglob("*") if p.is_file()] if data.is_dir() else []
    old = [p for p in old if p.suffix in _OWN_SUFFIXES]
    old += [p for pattern in _OWN_FIGURES for p in out.glob(pattern)] if out.is_dir() else []
    return sorted(p for p in old if p not in keep)


def _write(path: Path, content: bytes) -> bool:
    """Write ``content`` to ``path`` unless it already holds it; True when written."""
    if path.is_file() and path.read_bytes() == content:
        return False
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(content)
    tmp.replace(path)
    return True


def report_docs(
    from_dir: str | Path,
    out: str | Path = "docs/results",
    readme: str | Path | None = None,
    headline: str | None = None,
) -> DocsReport:
    """Render the results pages of ``from_dir`` into ``out`` and, with ``readme``, the
    README's headline block and, when there is a calibration run, its calibration block (see
    the module's docstring).

    Raises
    ------
    DocsReportError
        On input that cannot be rendered (no results, unreadable JSON, two check reports, a
        README without the markers of a block it gets, no run for the headline): nothing is
        written then.
    """
    out = Path(out)
    found = discover(from_dir)
    files = render_docs(found)
    readme_text = None
    if readme is not None:
        from ipbench.eval.report.readme import headline_block, replace_block
        from ipbench.eval.report.readme_calibration import update_readme
        from ipbench.eval.report.readme_exploration import update_readme as update_exploration

        readme = Path(readme)
        try:
            with open(readme, encoding="utf-8", newline="") as f:
                text = f.read()
        except OSError as err:
            raise DocsReportError(f"cannot read --readme {readme}: {err.strerror or err}") from err
        link = Path(os.path.relpath(out / "index.md", readme.parent)).as_posix()
        readme_text = replace_block(text, headline_block(found, link, headline), str(readme))
        link = Path(os.path.relpath(out / "calibration.md", readme.parent)).as_posix()
        readme_text = update_readme(readme_text, found, link, str(readme))
        link = Path(os.path.relpath(out / "exploration.md", readme.parent)).as_posix()
        readme_text = update_exploration(readme_text, found, link, str(readme))
    stale = _stale(out, files)
    written, unchanged = [], []
    for name, content in files.items():
        (written if _write(out / name, content) else unchanged).append(out / name)
    if readme_text is not None:
        path = Path(readme)
        (written if _write(path, readme_text.encode("utf-8")) else unchanged).append(path)
    for path in stale:
        path.unlink()
    data = out / "data"
    folders = [p for p in data.rglob("*") if p.is_dir()] if data.is_dir() else []
    for folder in sorted(folders, reverse=True):
        if not any(folder.iterdir()):
            folder.rmdir()
    return DocsReport(tuple(written), tuple(unchanged), tuple(stale), found.notes)


def add_report_parser(sub) -> argparse.ArgumentParser:
    """Register ``report`` (and its ``docs`` target) on ``sub``, the top-level
    ``add_subparsers()`` object; returns the ``report`` parser."""
    report = sub.add_parser(
        "report",
        help="documents generated from results files (the docs' results pages)",
        description="Documents generated from the files that evaluations write.",
    )
    targets = report.add_subparsers(dest="target", required=True, metavar="TARGET")
    docs = targets.add_parser(
        "docs",
        help="render the docs' results pages (and the README's headline) from results files",
        description="Finds the run folders under --from (ipbench eval sorting and ipbench eval "
        "exploration: summary.json + run.json; ipbench eval perception and ipbench eval "
        "calibration --seeds: metrics.json; an ipbench check --json report) and writes "
        "OUT/index.md (what was run: commands, env id, policy version, perception keys, "
        "thresholds, seeds, platform and check verdict), "
        "OUT/sorting.md (accuracy with intervals, paired differences against random, the "
        "accuracy-inspection curve), OUT/exploration.md (objects found beside the thesis' "
        "Tables 3.2/3.3, search efficiency, recognition against eccentricity, comparisons on "
        "disjoint seed sets), OUT/perception.md and OUT/calibration.md (reconstruction "
        "errors over seeds beside the thesis', paired comparisons, self-calibration, hand-eye "
        "methods), each stamped as generated, and copies the files they were rendered from "
        "into OUT/data, so that --from OUT/data reproduces the pages byte for byte. --readme "
        "replaces the text between the README's results:headline:start and "
        "results:headline:end markers (HTML comments) with the headline table and, when there "
        "is a calibration run, the text between results:calibration:start and "
        "results:calibration:end with the calibration table (and likewise "
        "results:exploration:start/end with the exploration table).",
        epilog="example: ipbench report docs --from results --readme README.md",
        formatter_class=report.formatter_class,
    )
    docs.add_argument(
        "--from",
        dest="from_dir",
        type=Path,
        required=True,
        metavar="RESULTS_DIR",
        help="folder holding the run folders (e.g. results, with results/sorting)",
    )
    docs.add_argument(
        "--out", type=Path, default=Path("docs/results"), help="folder of the results pages"
    )
    docs.add_argument(
        "--readme",
        type=Path,
        default=None,
        metavar="FILE",
        help="also fill the headline table between FILE's results:headline markers (and the "
        "calibration table between its results:calibration markers)",
    )
    docs.add_argument(
        "--headline",
        default=None,
        metavar="RUN",
        help="the sorting run (its path under --from) of the README's headline (default: the "
        "one with random, GP-IPM, the oracle and a curve score, the most seeds)",
    )
    return report


def main_report(args: argparse.Namespace) -> int:
    """Run ``ipbench report docs`` with parsed ``args``; errors become one-line exits."""
    try:
        result = report_docs(args.from_dir, args.out, args.readme, args.headline)
    except DocsReportError as err:
        raise SystemExit(f"ipbench: {err}") from err
    for note in result.notes:
        print(f"ipbench: {note}")
    for path in result.removed:
        print(f"removed {path} (not in these results)")
    print(
        f"{len(result.written)} file(s) written, {len(result.unchanged)} unchanged, "
        f"{len(result.removed)} removed; pages in {Path(args.out) / 'index.md'}"
    )
    return 0
