"""``ipbench report docs`` on an exploration run: its own report on the exploration page,
what was run on the overview, its figure beside the page, regenerated from the data it keeps."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from exploration_records import BUDGET, sample_records

from ipbench.eval.exploration.report import write_exploration_report
from ipbench.eval.markdown import GENERATED_MARK
from ipbench.eval.report.docs import PAGES, report_docs
from ipbench.eval.report.runs import Discovery, DocsReportError, discover


def _exploration_run(
    folder: Path,
    status: str = "released",
    seeds: range = range(20),
    head_size: tuple[int, int] = (3264, 4928),
    fovea_factor: int = 4,
) -> None:
    """The synthetic records of ``seeds``; run.json as ``ipbench eval exploration`` writes it."""
    records = [r for r in sample_records(seeds, late_drop=3) if r["policy"] != "raster-scan"]
    write_exploration_report(records, folder, BUDGET, "Active exploration on a test id")
    config = {
        "scenes": ["simple"],
        "policies": ["active-vision", "random-gaze", "oracle-gaze"],
        "features": ["sift"],
        "seeds": list(seeds),
        "saccade_budget": BUDGET,
        "env_id": "ipbench/Exploration-v1",
        "head_size": list(head_size),
        "fovea_factor": fovea_factor,
    }
    database = {
        "classes": 10,
        "views": 320,
        "keypoints_per_view_min": 70,
        "keypoints_per_view_median": 440.5,
        "keypoints_per_view_max": 866,
    }
    run = {
        "fingerprint": "0123456789abcdef",
        "env": "ipbench/Exploration-v1",
        "env_status": status,
        "policy_version": 2,
        "databases": {"sift": database},
        "config": config,
    }
    (folder / "run.json").write_text(json.dumps(run))


@pytest.fixture
def results(tmp_path: Path) -> Path:
    root = tmp_path / "results"
    _exploration_run(root / "exploration" / "v1")
    return root


def _tree(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in root.rglob("*") if p.is_file()}


def test_the_exploration_page_is_the_runs_own_report(results, tmp_path):
    out = tmp_path / "docs"
    report = report_docs(results, out)
    assert "exploration.md" in PAGES and not report.notes
    page = (out / "exploration.md").read_text()
    assert page.startswith(GENERATED_MARK + "\n")
    # active-vision finds 5 + seed % 3 of 10 instances: seeds 0-19 -> 119 of 200, 59.5 %
    assert "| active-vision | 119 | 0 | 81 | 0 | 59.5 [" in page
    assert "| 3.3 | Nikon D5100 / PTU-D46 head | SIFT | 77 % | sift |" in page
    run_report = (results / "exploration" / "v1" / "exploration.md").read_text()
    section = run_report[run_report.index("## Seed sets") :]
    demoted = "\n".join(f"#{x}" if x.startswith("#") else x for x in section.splitlines())
    assert demoted in page  # every seed-set row, rebuilt from seed_sets.json alone
    assert "seed sets land apart beyond their intervals in" in page  # late_drop=3 moves rg
    assert "## `exploration/v1`: ipbench/Exploration-v1" in page
    assert "\n# " not in page.split("\n", 3)[3]  # one top heading: the page's
    assert "](exploration-exploration-v1.png)" in page
    recall = results / "exploration" / "v1" / "recall.png"
    assert (out / "exploration-exploration-v1.png").read_bytes() == recall.read_bytes()


def test_runs_of_the_same_cells_are_set_side_by_side(results, tmp_path):
    out = tmp_path / "docs"
    report_docs(results, out)
    assert "## Across runs" not in (out / "exploration.md").read_text()  # one run: nothing
    _exploration_run(
        results / "exploration" / "v1-full-frame", seeds=range(10), head_size=(1632, 2464),
        fovea_factor=1,
    )  # fmt: skip
    report_docs(results, out)
    page = (out / "exploration.md").read_text()
    section = page[page.index("## Across runs") : page.index("## `exploration/v1`")]
    assert (
        "| scene | feature | policy | `exploration/v1` (ipbench/Exploration-v1, 4928x3264, "
        "fovea 4x) | `exploration/v1-full-frame` (ipbench/Exploration-v1, 2464x1632, full "
        "frame) | same seeds |"
    ) in section
    # active-vision finds 5 + seed % 3 of 10: 59.5 % over seeds 0-19, 59 % over seeds 0-9
    row = next(x for x in section.splitlines() if x.startswith("| simple | sift | active-vision"))
    assert "| 59.5 [" in row and "(20) | 59.0 [" in row and row.endswith("(10) | no |")
    rows = [x.split(" | ")[2] for x in section.splitlines() if x.startswith("| simple")]
    assert rows == ["active-vision", "oracle-gaze", "random-gaze"]  # display order


def test_the_overview_says_what_was_run(results, tmp_path):
    out = tmp_path / "docs"
    report_docs(results, out)
    index = (out / "index.md").read_text()
    for text in (
        "## Exploration runs",
        "`ipbench eval exploration --env ipbench/Exploration-v1 --scenes simple --policies "
        "active-vision,random-gaze,oracle-gaze --features sift --seeds 0:20 --head-size "
        "3264x4928 --fovea-factor 4 --budget 4`",
        "Environment: `ipbench/Exploration-v1`\n",
        "foveated 4x: the whole field at 1232x816 px",
        "SIFT: 10 classes, 320 views, keypoints per view 70 / 440.5 / 866",
        "Run fingerprint: `0123456789abcdef`",
        "[exploration](exploration.md)",
    ):
        assert text in index, text
    _exploration_run(results / "exploration" / "dev", status="under development")
    report_docs(results, out)
    index = (out / "index.md").read_text()
    assert index.count("(under development when the run was made") == 1


def test_the_pages_regenerate_from_the_data_they_keep(results, tmp_path):
    first, second = tmp_path / "first", tmp_path / "second"
    report_docs(results, first)
    kept = sorted(p.name for p in (first / "data" / "exploration" / "v1").iterdir())
    assert kept == ["recall.png", "run.json", "seed_sets.json", "summary.json"]
    report_docs(first / "data", second)
    assert _tree(first) == _tree(second)


def test_an_unreadable_seed_sets_file_is_a_clear_error_and_writes_nothing(results, tmp_path):
    (results / "exploration" / "v1" / "seed_sets.json").write_text('{"not": "rows"}')
    out = tmp_path / "docs"
    with pytest.raises(DocsReportError, match="seed_sets.json holds a dict, expected a list"):
        report_docs(results, out)
    assert not out.exists()
    (results / "exploration" / "v1" / "seed_sets.json").write_text('[{"scene": "simple"}]')
    with pytest.raises(DocsReportError, match="ipbench eval exploration"):
        report_docs(results, out)
    assert not out.exists()


def test_the_readme_block_quotes_the_run_and_leaves_the_rest(results, tmp_path):
    from ipbench.eval.report.readme_exploration import END, START, update_readme

    found = discover(results)
    before = f"# Title\n\nhand-written\n{START}\nold\n{END}\nafter\n"
    text = update_readme(before, found, "docs/exploration.md")
    assert text.startswith("# Title\n\nhand-written\n" + START) and text.endswith(END + "\nafter\n")
    assert "old" not in text and "from the run `exploration/v1`" in text
    summary = json.loads((results / "exploration" / "v1" / "summary.json").read_text())
    cell = summary["simple"]["oracle-gaze"]["sift"]  # oracle-gaze finds 8 of 10 on every seed
    assert cell["performance_mean"] == pytest.approx(0.8) and "| 80.0 % [80.0, 80.0] |" in text
    # random-gaze finds 2 fewer than active-vision, 3 more fewer on seeds 10-19: -3.5 on average
    assert "| +35.0 [" in text and "| +3.5 [" not in text.replace("+35.0", "")
    assert "simple, SIFT, seeds 0–9 (10) and 10–19 (10): the seed sets land apart" in text
    assert "[Results: exploration](docs/exploration.md)" in text
    with pytest.raises(DocsReportError, match="exploration markers"):
        update_readme("# Title\n", found, "docs/exploration.md")
    nothing = Discovery((), None, ())
    assert update_readme(before, nothing, "x.md") == before  # no exploration run: as it was
