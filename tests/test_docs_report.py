"""``ipbench report docs``: results pages rendered from results files, reproducible from the
data copies they keep, and the README's headline block."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ipbench.eval.markdown import GENERATED_MARK
from ipbench.eval.report.docs import PAGES, render_docs, report_docs
from ipbench.eval.report.readme import END, START
from ipbench.eval.report.runs import DocsReportError, discover

REPO = Path(__file__).resolve().parent.parent
SEEDS = [0, 1, 2, 3, 4]
PNG = b"\x89PNG\r\n\x1a\n not a real figure"


def _cell(mean: float, low: float, high: float, correct: int, objects: int) -> dict:
    return {
        "accuracy_mean": mean,
        "ci_low": low,
        "ci_high": high,
        "n": len(SEEDS),
        "seeds": SEEDS,
        "objects": objects,
        "correct": correct,
        "inspections_per_object": 0.0,
    }


def _sorting_run(folder: Path, curve: bool = True) -> None:
    """A sorting run: random vs GP-IPM on 5 seeds; GP-IPM is 0.2 better on 4 of them."""
    folder.mkdir(parents=True)
    summary = {
        "uncluttered": {
            "gp-ipm": _cell(0.7766666666666667, 0.7466666666666666, 0.8066666666666666, 39, 50),
            "random": _cell(0.7766666666666668, 0.75, 0.8033333333333333, 39, 50),
        },
        "cluttered": {
            "gp-ipm": _cell(0.86, 0.78, 0.9, 60, 70),
            "random": _cell(0.7095238095238096, 0.6785714285714287, 0.738095238095238, 50, 70),
        },
    }
    run = {
        "fingerprint": "f00dfeed",
        "policy_version": 7,
        "thresholds": {"gp": 0.85},
        "validated_thresholds": {
            "gp": {
                "threshold": 0.85,
                "rule": "logistic-precision",
                "target_precision": 0.95,
                "decisions": 994,
                "data": "the first views of the validation seeds",
                "used": True,
            }
        },
        "model_keys": {"gp": "aaaa1111", "svm": None},
        "perception_key": "bbbb2222",
        "dataset_version": 3,
        "config": {
            "scenes": ["uncluttered", "cluttered"],
            "policies": ["random", "gp-ipm"],
            "seeds": SEEDS,
            "validation_seeds": list(range(1000, 1040)),
            "threshold": None,
            "n_views": 3,
            "fusion": "majority",
            "steps_per_object": 6,
            "extrinsics": "true",
            "perception": {"dataset": {"env_id": "ipbench/Sorting-v2"}, "classifiers": ["gp"]},
        },
    }
    random_acc = [0.6, 0.7, 0.7, 0.6, 0.7]
    gp_acc = [0.8, 0.9, 0.7, 0.8, 0.9]
    records = [
        {"scene": scene, "policy": policy, "seed": s, "accuracy": acc[i]}
        for scene in ("uncluttered", "cluttered")
        for policy, acc in (("random", random_acc), ("gp-ipm", gp_acc))
        for i, s in enumerate(SEEDS)
    ]
    records.append({"scene": "cluttered", "policy": "oracle", "seed": 0, "accuracy": 1.0})
    (folder / "summary.json").write_text(json.dumps(summary, indent=2))
    (folder / "run.json").write_text(json.dumps(run, indent=2))
    (folder / "episodes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    if curve:
        score = {
            "mean": 0.04312169312169313,
            "ci_low": -0.021075837742504377,
            "ci_high": 0.11027667548500876,
            "p_vs_random_inspect": 0.2578125,
            "normalized": 0.3535201868535202,
            "n": 10,
            "x_range": [0.0, 1.1571428571428573],
            "note": None,
        }
        point = {
            "policy": "gp-ipm@0.8",
            "threshold": 0.8,
            "validated": False,
            "inspections_per_object": 0.5571428571428572,
            "accuracy_mean": 0.7714285714285715,
            "ci_low": 0.7214285714285714,
            "ci_high": 0.8214285714285714,
            "n": 10,
        }
        curve_data = {"cluttered": {"gp-ipm": {"points": [point], "score": score}}}
        (folder / "curve.json").write_text(json.dumps(curve_data, indent=2))
        (folder / "curve.png").write_bytes(PNG)


def _perception_run(folder: Path) -> None:
    folder.mkdir(parents=True)
    gp = {"n": 3276, "accuracy": 0.7967032967032966, "log_loss": 0.5578052676848855}
    gp |= {"ece": 0.07465270185980831, "cluttered": {"accuracy": 0.79}}
    metrics = {
        "5class": {"gp": gp},
        "splits": {
            "novel": {
                "gp": {
                    "n": 2016,
                    "accuracy": 0.6825396825396826,
                    "log_loss": 0.78244,
                    "ece": 0.0492,
                }
            }
        },
        "fusion": {
            "in_hand": {"gp": {"accuracy_by_views": [0.68029, 0.71319], "runs_by_views": [9, 8]}}
        },
    }
    (folder / "metrics.json").write_text(json.dumps(metrics, indent=2))
    segmentation = {"cluttered": {"scenes": 10, "precision": 0.8032, "recall": 0.6335164835164835}}
    (folder / "segmentation.json").write_text(json.dumps(segmentation | {}))
    (folder / "perception.md").write_text(
        "# Perception\n\nCodebook: 256. Dataset key: `0123abcd`.\n"
    )
    (folder / "confusion_5class_gp.png").write_bytes(PNG)


def _check(path: Path) -> None:
    report = {
        "verdict": "statistical",
        "meaning": "compare aggregate results only",
        "complete": True,
        "stages": {"model": {"status": "close"}, "codebook": {"status": "exact"}},
        "platform": {"cpu": "Test CPU 9000", "cores": 2, "blas": ["openblas A", "openblas B"]},
        "platform_differences": {"cpu": {"here": "Test CPU 9000", "reference": "Other CPU"}},
    }
    path.write_text(json.dumps(report, indent=1))


@pytest.fixture
def results(tmp_path: Path) -> Path:
    root = tmp_path / "results"
    _sorting_run(root / "sorting")
    _perception_run(root / "perception")
    _check(root / "check.json")
    (root / "cache" / "models").mkdir(parents=True)
    (root / "cache" / "models" / "gp.npz").write_bytes(b"")
    return root


def _pages(out: Path) -> dict[str, str]:
    return {name: (out / name).read_text() for name in PAGES}


def test_sorting_page_shows_the_runs_numbers_rounded(results, tmp_path):
    out = tmp_path / "docs"
    report_docs(results, out)
    page = (out / "sorting.md").read_text()
    assert "| uncluttered | `random` | 77.7 % | [75.0, 80.3] % | 5 | 39/50 |" in page
    assert "| cluttered | `gp-ipm` | 86.0 % | [78.0, 90.0] % | 5 | 60/70 |" in page
    assert "12/14 (86 %)" in page  # the thesis' Table 5.1 total beside ours
    # paired over the 5 seeds: +0.2 on four of them; exact sign-flip p = 4 / 32
    assert "| cluttered | `gp-ipm` − `random` | +16.0 |" in page
    assert "| 0.1250 | 5 |" in page
    assert (
        "| cluttered | `gp-ipm` | +4.3 | [-2.1, +11.0] | 0.2578 | 10 | 0.000–1.157 | 35 % |" in page
    )
    assert "| gp-ipm | `gp-ipm@0.8` | 0.8 | 0.557 | 77.1 % | [72.1, 82.1] % | 10 |" in page
    assert "](curve-sorting.png)" in page
    assert (out / "curve-sorting.png").read_bytes() == PNG
    assert "--seeds 0:5" in page and "--env ipbench/Sorting-v2" in page


def test_perception_and_index_pages(results, tmp_path):
    out = tmp_path / "docs"
    report = report_docs(results, out)
    assert report.notes == ("skipped `cache`: no results of a known kind",)
    perception = (out / "perception.md").read_text()
    assert "| novel | `gp` | 0.683 | 0.782 | 0.049 | 2016 |" in perception
    assert "| 5 classes | `gp` | 0.797 | 0.558 | 0.075 | 3276 | 0.790 |" in perception
    assert "| cluttered | 10 | 0.803 | 0.634 |" in perception
    assert "| in_hand, gp | majority | 0.680 | 0.713 |" in perception
    assert "dataset key `0123abcd`" in perception
    index = (out / "index.md").read_text()
    for text in (
        "`ipbench/Sorting-v2`",
        "Policy code version: 7",
        "gp 0.85, validated by rule `logistic-precision`",
        "at least 95 %; on 994 decisions",
        "Test seeds: 0–4 (5)",
        "1000–1039 (40)",
        "trained models: gp `aaaa1111`;",
        "verdict: **statistical**",
        "| cpu | Test CPU 9000 |",
        "| blas | openblas A; openblas B |",
        "Dataset key: `0123abcd`",
    ):
        assert text in index, text
    for name, page in _pages(out).items():
        assert page.startswith(GENERATED_MARK + "\n"), name
        assert "Do not edit this page by hand" in page
    data = sorted(p.relative_to(out).as_posix() for p in (out / "data").rglob("*") if p.is_file())
    assert data == [
        "data/check.json",
        "data/perception/dataset.json",
        "data/perception/metrics.json",
        "data/perception/segmentation.json",
        "data/sorting/accuracy_per_seed.json",
        "data/sorting/curve.json",
        "data/sorting/curve.png",
        "data/sorting/run.json",
        "data/sorting/summary.json",
    ]
    per_seed = json.loads((out / "data/sorting/accuracy_per_seed.json").read_text())
    assert per_seed["cluttered"]["gp-ipm"] == {"0": 0.8, "1": 0.9, "2": 0.7, "3": 0.8, "4": 0.9}
    assert "oracle" not in per_seed["cluttered"]  # not a policy of the run's configuration


def test_pages_regenerate_byte_for_byte_from_their_data(results, tmp_path):
    first, second = tmp_path / "first", tmp_path / "second"
    report_docs(results, first)
    report_docs(first / "data", second)

    def tree(root: Path) -> dict[str, bytes]:
        return {
            p.relative_to(root).as_posix(): p.read_bytes() for p in root.rglob("*") if p.is_file()
        }

    assert tree(first) == tree(second)
    again = report_docs(first / "data", first)  # in place: the data are their own source
    assert not again.written and not again.removed and tree(first) == tree(second)


def test_a_run_gone_from_the_results_leaves_the_pages(results, tmp_path):
    out = tmp_path / "docs"
    report_docs(results, out)
    (results / "sorting" / "curve.json").unlink()
    report = report_docs(results, out)
    assert {p.name for p in report.removed} == {"curve.json", "curve.png", "curve-sorting.png"}
    assert (
        not (out / "curve-sorting.png").exists()
        and "curve-sorting" not in (out / "sorting.md").read_text()
    )


def test_stale_files_are_removed_only_from_generated_pages(results, tmp_path):
    out = tmp_path / "elsewhere"
    (out / "data").mkdir(parents=True)
    (out / "data" / "mine.json").write_text("{}")
    report_docs(results, out)
    assert (out / "data" / "mine.json").exists()  # out held no generated pages before
    assert report_docs(results, out).removed == (out / "data" / "mine.json",)


def test_committed_pages_match_their_data():
    """docs/results is what `ipbench report docs --from docs/results/data` renders."""
    out = REPO / "docs" / "results"
    files = render_docs(discover(out / "data"))
    assert set(PAGES) <= set(files)
    for name, content in files.items():
        assert (out / name).read_bytes() == content, f"docs/results/{name} drifted from its data"
    on_disk = {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()}
    assert on_disk == set(files), "files under docs/results that no data renders"


def test_readme_block_replaces_only_the_marked_region(results, tmp_path):
    readme = tmp_path / "README.md"
    before = "# ipbench\r\n\r\nIntro, untouched.\r\n\r\n"
    after = "\r\n\r\n## Next\r\n\r\nAlso untouched.\r\n"
    readme.write_bytes(f"{before}{START}\r\nold text\r\n{END}{after}".encode())
    report_docs(results, tmp_path / "docs" / "results", readme=readme)
    text = readme.read_bytes().decode()
    assert text.startswith(before + START + "\r\n") and text.endswith(END + after)
    block = text[len(before) + len(START) : -len(END + after)]
    assert "old text" not in block and "\n" not in block.replace("\r\n", "")
    assert "| cluttered | 71.0 % [67.9, 73.8] | 86.0 % [78.0, 90.0] | – | +16.0 " in block
    assert "p = 0.1250 | +4.3 [-2.1, +11.0], p = 0.2578 |" in block
    stamps = ("`ipbench/Sorting-v2`", "policy version 7", "dataset version 3", "`bbbb2222`")
    for stamp in (*stamps, "gp 0.85 (validated"):
        assert stamp in block, stamp
    assert "seeds 0–4 (5)" in block and "`ipbench check`: statistical" in block
    assert "(docs/results/index.md)" in block
    report_docs(results, tmp_path / "docs" / "results", readme=readme)
    assert readme.read_bytes().decode() == text  # idempotent


def test_missing_markers_is_a_clear_error_and_writes_nothing(results, tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text("# ipbench\n\nNo markers here.\n")
    out = tmp_path / "docs"
    with pytest.raises(DocsReportError, match="has no headline markers") as err:
        report_docs(results, out, readme=readme)
    assert START in str(err.value) and END in str(err.value)
    assert not out.exists() and readme.read_text() == "# ipbench\n\nNo markers here.\n"


def test_empty_or_missing_from_is_a_clear_error(tmp_path):
    with pytest.raises(DocsReportError, match="does not exist.*ipbench eval sorting"):
        report_docs(tmp_path / "nowhere", tmp_path / "docs")
    (tmp_path / "empty" / "junk").mkdir(parents=True)
    with pytest.raises(DocsReportError, match="(?s)holds no results.*summary.json.*skipped `junk`"):
        report_docs(tmp_path / "empty", tmp_path / "docs")
    assert not (tmp_path / "docs").exists()


def test_headline_needs_random_and_gp_ipm(tmp_path):
    root = tmp_path / "results"
    _perception_run(root / "perception")
    readme = tmp_path / "README.md"
    readme.write_text(f"{START}\n{END}\n")
    with pytest.raises(DocsReportError, match="needs a sorting run with both `random`"):
        report_docs(root, tmp_path / "docs", readme=readme)
    report_docs(root, tmp_path / "docs")  # without --readme the pages say there is no run
    assert "No sorting run among the results" in (tmp_path / "docs" / "sorting.md").read_text()


def test_cli_help_ends_with_an_example(capsys):
    from ipbench.eval.cli import main

    with pytest.raises(SystemExit) as exit_info:
        main(["report", "docs", "--help"])
    assert exit_info.value.code == 0
    help_text = capsys.readouterr().out
    assert help_text.rstrip().splitlines()[-1].strip().startswith("ipbench report docs")


def test_the_verdict_sentence_reads_the_score_interval():
    from ipbench.eval.report.readme import verdict

    scores = {
        "uncluttered": {
            "mean": 0.017,
            "ci_low": 0.001,
            "ci_high": 0.033,
            "p_vs_random_inspect": 0.04,
        },
        "cluttered": {
            "mean": 0.011,
            "ci_low": -0.01,
            "ci_high": 0.031,
            "p_vs_random_inspect": 0.29,
        },
        "pile": {"mean": -0.05, "ci_low": -0.08, "ci_high": -0.02, "p_vs_random_inspect": 0.001},
        "edge": {"mean": 0.013, "ci_low": 0.0001, "ci_high": 0.027, "p_vs_random_inspect": 0.052},
    }
    sentence = verdict(scores)
    assert "uncluttered scene it pays (+1.7 points [+0.1, +3.3]" in sentence
    assert "cluttered scene it gains nothing measurable (+1.1 points" in sentence
    assert "pile scene it costs (-5.0 points" in sentence
    assert "edge scene it is at the margin of measurable (+1.3 points [+0.0, +2.7]" in sentence
    assert verdict({}) == ""


def test_a_run_on_an_id_under_development_says_so(results, tmp_path):
    out = tmp_path / "docs"
    report_docs(results, out)
    assert "under development" not in (out / "index.md").read_text()  # a released id's run
    run_json = results / "sorting" / "run.json"
    run_json.write_text(
        json.dumps({**json.loads(run_json.read_text()), "env_status": "under development"})
    )
    report_docs(results, out)
    assert "(under development when the run was made" in (out / "index.md").read_text()
