"""``ipbench report docs`` on a multi-seed calibration run: the calibration page shows the run's
distributions formatted from its metrics.json, gaps read ``–``, the page regenerates byte for
byte from the data it keeps, the README's calibration block is replaced between its own
markers only, and a single-seed calibration run is still skipped with a note."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from ipbench.eval.markdown import GENERATED_MARK
from ipbench.eval.report import readme as headline_readme
from ipbench.eval.report.docs import PAGES, render_docs, report_docs
from ipbench.eval.report.readme_calibration import END, START, calibration_block
from ipbench.eval.report.runs import DocsReportError, discover

REPO = Path(__file__).resolve().parent.parent
SEEDS = [0, 1, 2]
PNG = b"\x89PNG\r\n\x1a\n a spread figure"


def _d(mean, low, high, median, values=None) -> dict:
    """A distribution over the three seeds."""
    return {
        "mean": mean,
        "median": median,
        "ci_low": low,
        "ci_high": high,
        "n": len(values or SEEDS),
        "values": values or [mean] * len(SEEDS),
    }


def _c(mean, low, high, p) -> dict:
    return {**_d(mean, low, high, mean), "p_value": p}


def _metrics() -> dict:
    errors = {
        "rotation_deg": _d(0.1234, 0.1, 0.15, 0.12),
        "translation_mm": _d(1.5, 1.25, 1.75, 1.5),
    }
    nominal = {"rotation_deg": _d(2.5, 2.0, 3.0, 2.5), "translation_mm": _d(12.0, 10.0, 14.0, 12.0)}
    calibrated = {"rotation_deg": _d(0.0567, 0.04, 0.07, 0.05)}
    calibrated["translation_mm"] = _d(0.876, 0.7, 1.0, 0.8)
    no_low = {**_c(-11.1, -13.0, -9.0, 0.25), "ci_low": None}
    return {
        "seeds": SEEDS,
        "robot_seed": 1,
        "confidence": 0.95,
        "reconstruction": {
            "head_true_rmse_mm": _d(0.16213, 0.15049, 0.17533, 0.161),
            "head_encoders_rmse_mm": _d(0.91, 0.8, 1.02, 0.9),
            "head_dynamic_rmse_mm": _d(0.3456, 0.3, 0.39, 0.34),
            "head_dynamic_unchecked_rmse_mm": None,
            "head_fallback_rate": _d(0.125, 0.05, 0.2, 0.1),
            "wrist_rmse_mm": _d(3.14159, 2.9, 3.4, 3.1),
            "wrist_robot_rmse_mm": _d(11.234, 10.5, 12.0, 11.2),
            "wrist_robot_nominal_rmse_mm": _d(25.5, 24.0, 27.0, 25.0),
        },
        "hand_eye": {
            "wrist": {"tsai": errors, "park": {"rotation_deg": None, "translation_mm": None}},
            "head_left": {"tsai": errors},
        },
        "self_calibration": {
            "wrist": {"nominal": nominal, "calibrated": calibrated},
        },
        "comparisons": {
            "head_dynamic_minus_encoders_rmse_mm": _c(-0.5644, -0.7, -0.43, 0.25),
            "wrist_robot_calibrated_minus_nominal_rmse_mm": _c(-14.266, -15.0, -13.5, 0.00001),
            "wrist_calibrated_minus_nominal_translation_mm": no_low,
        },
        "head_floor": {
            "trials": 30,
            "median_rmse_mm": 0.0987,
            "p90_rmse_mm": 0.1812,
            "board_distance_m": {"min": 1.26, "max": 1.68, "spearman_rho": 0.15, "p_value": 0.04},
            "incidence_deg": {"min": 0.4, "max": 39.6, "spearman_rho": 0.81, "p_value": 6e-48},
        },
        "thesis": {"head_rmse_mm": 0.16, "head_axis_residual_max_mm": 0.3, "xtion_rmse_mm": 12.5},
        "per_seed": [{"seed": s} for s in SEEDS],
    }


def _calibration_run(folder: Path, figure: bool = True) -> None:
    folder.mkdir(parents=True)
    (folder / "metrics.json").write_text(json.dumps(_metrics(), indent=1))
    (folder / "calibration.md").write_text("# Calibration\n")
    (folder / "episodes.jsonl").write_text('{"seed": 0}\n')
    (folder / "run.json").write_text("{}")
    if figure:
        (folder / "spread.png").write_bytes(PNG)


@pytest.fixture
def results(tmp_path: Path) -> Path:
    root = tmp_path / "results"
    _calibration_run(root / "calibration")
    return root


def test_the_page_shows_the_runs_numbers_formatted(results, tmp_path):
    out = tmp_path / "docs"
    report_docs(results, out)
    page = (out / "calibration.md").read_text()
    assert page.startswith(GENERATED_MARK + "\n")
    assert "[`data/calibration/metrics.json`](data/calibration/metrics.json)" in page
    assert "`ipbench eval calibration --seeds 0:3`: seeds 0–2 (3)" in page
    assert "model-error seed 1" in page and "at 95 % confidence" in page
    for row in (
        "| head, true extrinsics | 0.162 [0.150, 0.175] | 0.161 | 3 | 0.16 (Table 4.3) |",
        "| head, encoders | 0.910 [0.800, 1.020] | 0.900 | 3 | 0.16 (Table 4.3) |",
        "| head, dynamic update (with the check) | 0.346 [0.300, 0.390] | 0.340 | 3 | 0.16 (",
        "| wrist depth (board shape) | 3.14 [2.90, 3.40] | 3.10 | 3 |  |",
        "| wrist in robot frame (calibrated X) | 11.23 [10.50, 12.00] | 11.20 | 3 | 12.5 (Table",
        "| wrist in robot frame (nominal X) | 25.50 [24.00, 27.00] | 25.00 | 3 | 12.5 (Table 4.4) ",
        "fell back to the encoders in 12.5 % [5.0, 20.0] of trials",
        "| head RMSE: dynamic update − encoders | mm | -0.564 [-0.700, -0.430] | 0.2500 | 3 |",
        "| wrist RMSE in robot frame: calibrated X − nominal X | mm | -14.27 [-15.00, -13.50] "
        "| < 0.0001 | 3 |",
        "| wrist | 2.500 [2.000, 3.000] | 0.057 [0.040, 0.070] | 12.00 [10.00, 14.00] "
        "| 0.88 [0.70, 1.00] |",
        "| wrist | `tsai` | 0.123 [0.100, 0.150] | 1.50 [1.25, 1.75] | 3 |",
        "| head_left | `tsai` | 0.123 [0.100, 0.150] | 1.50 [1.25, 1.75] | 3 |",
        "![the spread over seeds, run calibration](calibration-calibration.png)",
    ):
        assert row in page, row
    assert (out / "calibration-calibration.png").read_bytes() == PNG
    kept = sorted(p.name for p in (out / "data" / "calibration").iterdir())
    assert kept == ["metrics.json", "spread.png"]  # not episodes.jsonl, run.json, the report
    assert (out / "data/calibration/metrics.json").read_bytes() == (
        results / "calibration/metrics.json"
    ).read_bytes()
    index = (out / "index.md").read_text()
    assert "## Calibration runs" in index and "[calibration](calibration.md)" in index
    assert "Command: `ipbench eval calibration --seeds 0:3`" in index


def test_the_page_says_what_the_floor_depends_on(results, tmp_path):
    report_docs(results, tmp_path / "docs")
    page = (tmp_path / "docs" / "calibration.md").read_text()
    assert "(30 trials, the true cameras): median 0.099 mm, 90th percentile 0.181 mm" in page
    assert "incidence angle (0–40°) +0.81 (p 6e-48)" in page
    assert "with its distance (1.26–1.68 m) +0.15 (p 0.04)" in page


def test_gaps_read_as_a_dash(results, tmp_path):
    out = tmp_path / "docs"
    report_docs(results, out)
    page = (out / "calibration.md").read_text()
    assert "| head, dynamic update unchecked | – | – | – | 0.16 (Table 4.3) |" in page
    assert "| wrist | `park` | – | – | – |" in page
    # an interval with a null end: the mean alone
    assert "| wrist X translation error: calibrated − nominal | mm | -11.10 | 0.2500 | 3 |" in page


def test_a_run_of_nulls_and_missing_parts_renders(tmp_path):
    root = tmp_path / "results" / "sparse"
    root.mkdir(parents=True)
    metrics = {
        "seeds": [4, 9],
        "robot_seed": None,
        "reconstruction": {"head_true_rmse_mm": _d(0.2, None, None, None, [0.2])},
        "hand_eye": None,
        "comparisons": {"something_new_deg": None},
    }
    (root / "metrics.json").write_text(json.dumps(metrics))
    out = tmp_path / "docs"
    report_docs(root.parent, out)
    page = (out / "calibration.md").read_text()
    assert "| head, true extrinsics | 0.200 | – | 1 | – |" in page  # no thesis figures recorded
    assert "| wrist depth (board shape) | – | – | – |  |" in page
    assert "seeds 4, 9 (2), in the nominal cell" in page and "at – confidence" in page
    assert "| `something_new_deg` | ° | – | – | – |" in page
    assert "does not record how often the consistency check fell back" in page
    assert "Hand-eye methods" not in page and "![" not in page
    block = calibration_block(discover(root.parent), "docs/results/calibration.md")
    assert "| head, true extrinsics | 0.200 | 1 | – |" in block


def test_pages_regenerate_byte_for_byte_from_their_data(results, tmp_path):
    first, second = tmp_path / "first", tmp_path / "second"
    report_docs(results, first)
    report_docs(first / "data", second)

    def tree(root: Path) -> dict[str, bytes]:
        return {
            p.relative_to(root).as_posix(): p.read_bytes() for p in root.rglob("*") if p.is_file()
        }

    assert tree(first) == tree(second) and "calibration-calibration.png" in tree(first)
    assert not report_docs(first / "data", first).written


def test_a_figure_gone_from_the_run_leaves_the_pages(results, tmp_path):
    out = tmp_path / "docs"
    report_docs(results, out)
    (results / "calibration" / "spread.png").unlink()
    report = report_docs(results, out)
    assert {p.name for p in report.removed} == {"spread.png", "calibration-calibration.png"}
    assert "![" not in (out / "calibration.md").read_text()


def test_several_runs_are_sections_in_name_order(results, tmp_path):
    _calibration_run(results / "more" / "b", figure=False)
    out = tmp_path / "docs"
    report_docs(results, out)
    page = (out / "calibration.md").read_text()
    assert page.index("## Run `calibration`") < page.index("## Run `more/b`")
    assert not (out / "calibration-more-b.png").exists()


def test_a_single_seed_calibration_run_is_still_skipped(tmp_path):
    root = tmp_path / "results"
    old = root / "old-calibration"
    old.mkdir(parents=True)
    metrics = {"hand_eye_study": {}, "hand_eye": {}, "self_calibration": {"cameras": {}}}
    (old / "metrics.json").write_text(json.dumps(metrics))
    (old / "calibration.md").write_text("# Calibration\n")
    _calibration_run(root / "calibration")
    report = report_docs(root, tmp_path / "docs")
    assert report.notes == (
        "skipped `old-calibration`: a single-seed calibration run, made without `--seeds` (the "
        "pages render sorting, exploration, perception and calibration runs)",
    )
    assert "old-calibration" not in (tmp_path / "docs" / "calibration.md").read_text()
    with pytest.raises(DocsReportError, match="single-seed calibration run"):
        report_docs(old, tmp_path / "other")  # --from naming that run alone


def _readme(tmp_path: Path, calibration_markers: bool = True) -> Path:
    readme = tmp_path / "README.md"
    headline = f"{headline_readme.START}\nold headline\n{headline_readme.END}\n"
    calibration = f"{START}\r\nold calibration\r\n{END}\r\n" if calibration_markers else ""
    readme.write_bytes(
        f"# ipbench\r\n\r\n{headline}\r\nBetween.\r\n{calibration}After.\r\n".encode()
    )
    return readme


@pytest.fixture
def with_sorting(results) -> Path:
    from test_docs_report import _sorting_run

    _sorting_run(results / "sorting")
    return results


def test_the_readme_block_is_replaced_between_its_markers_only(with_sorting, tmp_path):
    readme = _readme(tmp_path)
    report_docs(with_sorting, tmp_path / "docs" / "results", readme=readme)
    text = readme.read_bytes().decode()
    before, rest = text.split(START + "\r\n")
    block, after = rest.split(END)
    assert (
        before.startswith("# ipbench\r\n\r\n" + headline_readme.START)
        and "old headline" not in before
    )
    assert before.endswith("\r\nBetween.\r\n") and after == "\r\nAfter.\r\n"
    assert "old calibration" not in block and "\n" not in block.replace("\r\n", "")
    for text_ in (
        "| head, true extrinsics | 0.162 [0.150, 0.175] | 3 | 0.16 (Table 4.3) |",
        "| head, encoders | 0.910 [0.800, 1.020] | 3 | 0.16 (Table 4.3) |",
        "| head, dynamic update (with the check) | 0.346 [0.300, 0.390] | 3 | 0.16 (Table 4.3) |",
        "| wrist in robot frame (calibrated X) | 11.23 [10.50, 12.00] | 3 | 12.5 (Table 4.4) |",
        "Mean over seeds 0–2 (3) with its 95 % bootstrap interval",
        "[Results: calibration](docs/results/calibration.md)",
    ):
        assert text_ in block, text_
    assert "unchecked" not in block and "nominal X" not in block  # the page has those
    report_docs(with_sorting, tmp_path / "docs" / "results", readme=readme)
    assert readme.read_bytes().decode() == text  # idempotent


def test_without_a_calibration_run_the_readme_block_is_left_alone(with_sorting, tmp_path):
    import shutil

    shutil.rmtree(with_sorting / "calibration")
    readme = _readme(tmp_path)
    report_docs(with_sorting, tmp_path / "docs", readme=readme)
    assert f"{START}\r\nold calibration\r\n{END}" in readme.read_bytes().decode()
    readme = _readme(tmp_path, calibration_markers=False)
    report_docs(with_sorting, tmp_path / "docs", readme=readme)  # no markers needed either
    assert START not in readme.read_text()


def test_a_calibration_run_needs_the_readme_markers(with_sorting, tmp_path):
    readme = _readme(tmp_path, calibration_markers=False)
    before = readme.read_bytes()
    out = tmp_path / "docs"
    with pytest.raises(DocsReportError, match="has no calibration markers") as err:
        report_docs(with_sorting, out, readme=readme)
    assert START in str(err.value) and END in str(err.value)
    assert not out.exists() and readme.read_bytes() == before


def test_the_committed_readme_block_is_its_rendering():
    """README.md's calibration block is what docs/results/data renders (the placeholder until
    a calibration run is committed there)."""
    text = (REPO / "README.md").read_text(encoding="utf-8")
    found = re.search(re.escape(START) + r"\n(.*)" + re.escape(END), text, re.S)
    assert found, f"README.md needs the lines {START} and {END}"
    expected = calibration_block(
        discover(REPO / "docs/results/data"), "docs/results/calibration.md"
    )
    assert found[1] == expected


def test_the_committed_calibration_page_is_in_the_site():
    assert "calibration.md" in PAGES and "calibration.md" in render_docs(
        discover(REPO / "docs/results/data")
    )
    assert "      - Calibration: results/calibration.md\n" in (REPO / "mkdocs.yml").read_text()
