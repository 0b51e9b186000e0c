"""The shared episode machinery (ipbench.eval.episodes): log, resume, output folder, executors."""

from __future__ import annotations

import json
import os

import pytest

from ipbench.eval.episodes import BACKENDS, EpisodeLog, check_out, run_episodes


def square_episode(task: int, offset: int) -> dict:
    """A module-level episode (it pickles by reference into worker processes)."""
    return {"task": task, "value": task * task + offset, "pid": os.getpid()}


def _key(record: dict) -> int:
    return record["task"]


def test_log_appends_resumes_after_a_cut_record_and_sorts(tmp_path, capsys):
    log = EpisodeLog(tmp_path / "episodes.jsonl", _key)
    assert log.done() == set() and log.records() == []
    seen = []
    log.append([{"task": 3}, {"task": 1}], each=seen.append)
    assert seen == [{"task": 3}, {"task": 1}]
    # a kill in the middle of a write leaves half a record: it is dropped and runs again
    with log.path.open("a") as f:
        f.write('{"task": 2, "val')
    assert log.done() == {1, 3}
    assert "dropping an unfinished last record" in capsys.readouterr().out
    log.append([{"task": 2}])
    log.sort()
    assert [r["task"] for r in log.records()] == [1, 2, 3]
    assert log.path.read_text().count("\n") == 3


def test_check_out_refuses_another_configurations_episodes(tmp_path):
    out = tmp_path / "run"
    check_out(out, "abc")  # creates it
    (out / "run.json").write_text(json.dumps({"fingerprint": "abc"}))
    (out / "episodes.jsonl").write_text('{"task": 1}\n')
    check_out(out, "abc")  # same configuration: resume
    with pytest.raises(KeyError, match="another configuration.*delete"):
        check_out(out, "xyz", KeyError)


def test_check_out_says_when_the_folder_cannot_be_written(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(ValueError, match="cannot write to the output folder.*--out"):
        check_out(blocker / "run", "abc")


def test_serial_runs_in_order_and_workers_run_longest_first(tmp_path):
    tasks = [1, 5, 2, 4]
    serial = list(run_episodes(square_episode, tasks, (10,)))
    assert [r["task"] for r in serial] == tasks
    assert [r["value"] for r in serial] == [11, 35, 14, 26]
    assert {r["pid"] for r in serial} == {os.getpid()}
    pooled = list(run_episodes(square_episode, tasks, (10,), workers=2, cost=float))
    assert sorted(r["task"] for r in pooled) == sorted(tasks)
    assert os.getpid() not in {r["pid"] for r in pooled}  # ran in worker processes
    assert {r["task"]: r["value"] for r in pooled} == {r["task"]: r["value"] for r in serial}


def test_an_unknown_backend_lists_the_valid_ones():
    with pytest.raises(RuntimeError, match="backend 'dask'; valid: " + ", ".join(BACKENDS)):
        list(run_episodes(square_episode, [1], (0,), backend="dask", error=RuntimeError))
