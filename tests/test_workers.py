"""Worker pools that survive a dying worker (ipbench.eval.workers)."""

import os
import signal
from pathlib import Path

import pytest

from ipbench.eval.workers import WorkerCrashError, run_tasks


def _square(x: int) -> int:
    return x * x


def _die_once(x: int, marker: str) -> int:
    """Kill this worker process the first time task 3 runs (a crash, not an exception)."""
    if x == 3 and not Path(marker).exists():
        Path(marker).touch()
        os.kill(os.getpid(), signal.SIGKILL)
    return x * x


def _always_die(x: int) -> int:
    os.kill(os.getpid(), signal.SIGKILL)
    return x


def _raise(x: int) -> int:
    raise ValueError(f"bad task {x}")


def test_serial_runs_in_order_here():
    assert list(run_tasks(_square, [(k,) for k in range(5)], workers=1)) == [
        (k, k * k) for k in range(5)
    ]


def test_every_task_finishes_once_after_a_worker_dies(tmp_path, capsys):
    marker = str(tmp_path / "died")
    results = list(run_tasks(_die_once, [(k, marker) for k in range(8)], workers=2))
    assert Path(marker).exists()  # the crash happened
    indices = [i for i, _ in results]
    assert sorted(indices) == list(range(8))  # each task exactly once
    assert dict(results) == {k: k * k for k in range(8)}
    assert "worker process died" in capsys.readouterr().err


def test_a_worker_that_always_dies_ends_in_a_clear_error():
    with pytest.raises(WorkerCrashError, match="resume.*--workers 1"):
        list(run_tasks(_always_die, [(1,), (2,)], workers=2, restarts=1, what="part"))


def test_an_exception_in_a_task_is_not_retried():
    with pytest.raises(ValueError, match="bad task"):
        list(run_tasks(_raise, [(1,)], workers=2))
