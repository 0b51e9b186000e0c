"""Finding the runs under ``ipbench report docs --from DIR`` and the data kept of each.

A run is a folder recognised by its files:

* **sorting** (``ipbench eval sorting``): ``summary.json`` and ``run.json`` (with the
  perception model keys); also read: ``curve.json``, ``curve.png`` and ``episodes.jsonl``;
* **perception** (``ipbench eval perception``): ``metrics.json`` with per-split metrics; also
  read: ``segmentation.json`` and the dataset key of ``perception.md``;
* **calibration** (``ipbench eval calibration --seeds A:B``): ``metrics.json`` with ``seeds``
  and distributions over them; also read: ``spread.png``;
* **exploration** (``ipbench eval exploration``): ``summary.json`` and ``run.json`` with the
  recognition ``databases``; also read: ``seed_sets.json`` and ``recall.png``;
* single-seed calibration runs are recognised, and skipped with a note;

and an ``ipbench check --json FILE`` report is any JSON file outside the runs with a
``verdict``, ``stages`` and ``platform``. Folders are searched up to :data:`MAX_DEPTH` levels
deep (``results/headline/gp-a``); a run's name is its path under ``DIR``.

Each run keeps the small files its pages are rendered from (:attr:`Run.files`): byte copies,
plus two extracts that replace bulky or non-JSON sources: ``accuracy_per_seed.json`` (the
per-seed accuracies of ``episodes.jsonl`` the paired tests need) and ``dataset.json`` (the
dataset key of ``perception.md``). Written to ``docs/results/data/<run>/``, they are a
``--from`` folder themselves: the pages regenerate from the repository alone.
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from ipbench.eval.report.calibration_data import calibration_files

__all__ = [
    "EXPECTED",
    "MAX_DEPTH",
    "CheckFile",
    "Discovery",
    "DocsReportError",
    "Run",
    "discover",
]

MAX_DEPTH = 4
"""How many folder levels under ``--from`` are searched for runs."""
EXPECTED = (
    "run folders of `ipbench eval sorting` or `exploration` (summary.json + run.json), "
    "`ipbench eval perception` or `calibration --seeds` (metrics.json), and optionally an "
    "`ipbench check --json` report"
)
"""What ``--from`` should hold, in words (for the errors)."""
_MAX_CHECK_BYTES = 2_000_000
_DATASET_KEY = re.compile(r"Dataset key: `([0-9a-f]+)`")


class DocsReportError(ValueError):
    """Input ``ipbench report docs`` cannot render: the message says what was wrong."""


@dataclass(frozen=True)
class Run:
    """A recognised run: ``kind``, ``name`` (its path under ``--from``, ``/``-separated) and
    ``files``, the data kept of it (file name -> bytes)."""

    kind: str
    name: str
    files: Mapping[str, bytes] = field(default_factory=dict)

    def json(self, name: str) -> dict | None:
        """The parsed JSON file ``name`` of :attr:`files`, None when the run has none."""
        if name not in self.files:
            return None
        return json.loads(self.files[name])

    @property
    def sources(self) -> list[str]:
        """Its data files as paths relative to the results pages (``data/<run>/<file>``)."""
        return [f"data/{self.name}/{f}" for f in self.files]


@dataclass(frozen=True)
class CheckFile:
    """An ``ipbench check --json`` report: ``name`` (its path under ``--from``), ``content``
    (bytes) and ``report`` (parsed)."""

    name: str
    content: bytes
    report: Mapping

    @property
    def source(self) -> str:
        """Its path relative to the results pages (``data/<name>``)."""
        return f"data/{self.name}"


@dataclass(frozen=True)
class Discovery:
    """Everything found under ``--from``: the runs (sorted by name), the check report (None
    without one) and one-line notes on what was skipped."""

    runs: tuple[Run, ...]
    check: CheckFile | None
    notes: tuple[str, ...]

    def of_kind(self, kind: str) -> tuple[Run, ...]:
        """The runs of ``kind`` (``sorting``, ``exploration``, ``perception``,
        ``calibration``)."""
        return tuple(r for r in self.runs if r.kind == kind)


def _load(path: Path) -> dict:
    try:
        data = json.loads(path.read_bytes())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise DocsReportError(f"cannot read {path}: {err}; is the run complete?") from err
    if not isinstance(data, dict):
        raise DocsReportError(f"{path} holds a {type(data).__name__}, expected a JSON object")
    return data


def _dumps(data) -> bytes:
    return (json.dumps(data, indent=1, allow_nan=False) + "\n").encode()


def _accuracy_per_seed(folder: Path, run: Mapping) -> bytes | None:
    """``{scene: {policy: {seed: accuracy}}}`` of the run's episodes (those of its
    configuration, as its report counts them), or the kept extract; None without either."""
    kept = folder / "accuracy_per_seed.json"
    log = folder / "episodes.jsonl"
    if not log.is_file():
        return kept.read_bytes() if kept.is_file() else None
    from ipbench.eval.episodes import load_episodes

    config = run.get("config", {})
    scenes, policies = config.get("scenes", []), config.get("policies", [])
    seeds = set(config.get("seeds", []))
    out: dict[str, dict[str, dict[str, float]]] = {}
    try:
        records = load_episodes(log)
    except ValueError as err:
        raise DocsReportError(f"cannot read {log}: {err}") from err
    chosen = {}
    for r in records:
        if r.get("scene") in scenes and r.get("policy") in policies and r.get("seed") in seeds:
            chosen[r["scene"], r["policy"], int(r["seed"])] = float(r["accuracy"])
    for scene in scenes:
        for policy in policies:
            cell = {s: a for (sc, p, s), a in chosen.items() if sc == scene and p == policy}
            if cell:
                out.setdefault(scene, {})[policy] = {str(s): cell[s] for s in sorted(cell)}
    return _dumps(out)


def _sorting_files(folder: Path, run: Mapping) -> dict[str, bytes]:
    files = {name: (folder / name).read_bytes() for name in ("summary.json", "run.json")}
    if (folder / "curve.json").is_file():
        files["curve.json"] = (folder / "curve.json").read_bytes()
        if (folder / "curve.png").is_file():
            files["curve.png"] = (folder / "curve.png").read_bytes()
    per_seed = _accuracy_per_seed(folder, run)
    if per_seed is not None:
        files["accuracy_per_seed.json"] = per_seed
    return files


def _dataset(folder: Path, metrics: Mapping) -> bytes | None:
    """``{"dataset_key": ...}`` from metrics.json, perception.md or the kept extract."""
    key = metrics.get("dataset_key")
    if key is None and (folder / "perception.md").is_file():
        found = _DATASET_KEY.search((folder / "perception.md").read_text("utf-8"))
        key = found.group(1) if found else None
    if key is not None:
        return _dumps({"dataset_key": key})
    kept = folder / "dataset.json"
    return kept.read_bytes() if kept.is_file() else None


def _perception_files(folder: Path, metrics: Mapping) -> dict[str, bytes]:
    files = {"metrics.json": (folder / "metrics.json").read_bytes()}
    if (folder / "segmentation.json").is_file():
        files["segmentation.json"] = (folder / "segmentation.json").read_bytes()
    dataset = _dataset(folder, metrics)
    if dataset is not None:
        files["dataset.json"] = dataset
    return files


def _exploration_files(folder: Path) -> dict[str, bytes]:
    files = {name: (folder / name).read_bytes() for name in ("summary.json", "run.json")}
    for name in ("seed_sets.json", "recall.png"):
        if (folder / name).is_file():
            files[name] = (folder / name).read_bytes()
    if "seed_sets.json" in files:
        try:
            rows = json.loads(files["seed_sets.json"])
        except (UnicodeDecodeError, json.JSONDecodeError) as err:
            raise DocsReportError(f"cannot read {folder / 'seed_sets.json'}: {err}") from err
        if not isinstance(rows, list):
            raise DocsReportError(
                f"{folder / 'seed_sets.json'} holds a {type(rows).__name__}, expected a list of "
                "rows (as `ipbench eval exploration` writes)"
            )
    return files


def _skipped(name: str, kind: str) -> str:
    return (
        f"skipped `{name}`: {kind} (the pages render sorting, exploration, perception and "
        "calibration runs)"
    )


def _classify(folder: Path, name: str) -> tuple[Run | None, str | None] | None:
    """``(run, None)`` for a run rendered, ``(None, note)`` for one recognised and skipped,
    None for a folder that is no run (search inside it)."""
    has = {p.name for p in folder.iterdir() if p.is_file()}
    if {"summary.json", "run.json"} <= has:
        run = _load(folder / "run.json")
        _load(folder / "summary.json")
        if "databases" in run or "exploration.md" in has:
            return Run("exploration", name, _exploration_files(folder)), None
        return Run("sorting", name, _sorting_files(folder, run)), None
    if "metrics.json" in has:
        metrics = _load(folder / "metrics.json")
        if "splits" in metrics or "5class" in metrics:
            return Run("perception", name, _perception_files(folder, metrics)), None
        if (calibration := calibration_files(folder, metrics)) is not None:
            return Run("calibration", name, calibration), None
        if "calibration.md" in has or "hand_eye_study" in metrics:
            return None, _skipped(name, "a single-seed calibration run, made without `--seeds`")
        return None, _skipped(name, "a metrics.json of another kind")
    if "run.json" in has and "episodes.jsonl" in has:
        return None, f"skipped `{name}`: a run without summary.json (unfinished?)"
    return None


def _check_file(path: Path, name: str) -> CheckFile | None:
    if path.stat().st_size > _MAX_CHECK_BYTES:
        return None
    content = path.read_bytes()
    try:
        report = json.loads(content)
    except (UnicodeDecodeError, json.JSONDecodeError):
        return None
    if isinstance(report, dict) and {"verdict", "stages", "platform"} <= set(report):
        return CheckFile(name, content, report)
    return None


@dataclass
class _Found:
    """What a folder's subtree holds; ``known``: anything recognised (a run, a check report,
    a run skipped by kind), else its notes collapse into one."""

    runs: list[Run] = field(default_factory=list)
    checks: list[CheckFile] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    known: bool = False

    def add(self, other: _Found) -> None:
        self.runs += other.runs
        self.checks += other.checks
        self.notes += other.notes
        self.known = self.known or other.known


def _walk(folder: Path, name: str, depth: int) -> _Found:
    """Runs, check reports and notes under ``folder`` (named ``name``; ``""`` for the root)."""
    if name:
        classified = _classify(folder, name)
        if classified is not None:
            run, note = classified
            return _Found([run] if run else [], [], [note] if note else [], True)
    found = _Found()
    for child in sorted(folder.iterdir()):
        child_name = f"{name}/{child.name}" if name else child.name
        if child.name.startswith("."):
            continue
        if child.is_file() and child.suffix == ".json":
            check = _check_file(child, child_name)
            if check is not None:
                found.add(_Found(checks=[check], known=True))
        elif child.is_dir() and depth >= MAX_DEPTH:
            found.notes.append(f"skipped `{child_name}`: deeper than {MAX_DEPTH} levels")
        elif child.is_dir():
            sub = _walk(child, child_name, depth + 1)
            if sub.known:
                found.add(sub)
            else:
                found.notes.append(f"skipped `{child_name}`: no results of a known kind")
    return found


def discover(root: str | Path) -> Discovery:
    """The runs and check report under ``root`` (see the module's docstring).

    Raises
    ------
    DocsReportError
        When ``root`` is missing or not a folder, holds nothing of a known kind, holds two
        check reports, or a recognised run's JSON cannot be read.
    """
    root = Path(root)
    if not root.is_dir():
        what = "does not exist" if not root.exists() else "is not a folder"
        raise DocsReportError(f"--from {root} {what}; pass the folder holding {EXPECTED}")
    classified = _classify(root, root.name)  # --from may name one run folder
    if classified is not None and classified[0] is None:
        raise DocsReportError(f"--from {root}: {classified[1]}; pass a folder holding {EXPECTED}")
    found = _Found([classified[0]]) if classified is not None else _walk(root, "", 0)
    runs, checks, notes = found.runs, found.checks, found.notes
    if len(checks) > 1:
        names = ", ".join(c.name for c in checks)
        raise DocsReportError(
            f"--from {root} holds {len(checks)} `ipbench check` reports ({names}); keep the "
            "one of the platform the runs were made on"
        )
    if not runs and not checks:
        skipped = "".join(f"\n  {n}" for n in notes)
        raise DocsReportError(f"--from {root} holds no results: expected {EXPECTED}{skipped}")
    runs.sort(key=lambda r: r.name)
    return Discovery(tuple(runs), checks[0] if checks else None, tuple(notes))
