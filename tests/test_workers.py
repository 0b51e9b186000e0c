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


def _read_after(path: str) -> str:
    """A task that needs what the caller wrote from an earlier task's result."""
    return Path(path).read_text()


def _slow_square(x: int) -> int:
    import time

    time.sleep(0.2)
    return x * x


def test_a_task_starts_only_after_the_caller_took_what_it_depends_on(tmp_path):
    note = tmp_path / "note.txt"
    tasks = [(_slow_square, 3), (_read_after, str(note)), (_slow_square, 4)]
    results = {}
    for i, result in run_tasks(_call, tasks, workers=2, after=[[], [0], []]):
        results[i] = result
        if i == 0:
            note.write_text(f"square {result}")  # what task 1 reads
    assert results == {0: 9, 1: "square 9", 2: 16}
    # without the dependency task 1 would start at once, before the note exists
    note.unlink()
    with pytest.raises(FileNotFoundError):
        list(run_tasks(_call, tasks, workers=2))


def test_dependencies_must_point_to_earlier_tasks():
    with pytest.raises(ValueError, match="valid: indices of earlier tasks"):
        list(run_tasks(_square, [(1,), (2,)], workers=2, after=[[1], []]))
    with pytest.raises(ValueError, match="one per task"):
        list(run_tasks(_square, [(1,), (2,)], workers=1, after=[[]]))


def test_serial_run_with_dependencies_keeps_the_list_order():
    tasks = [(k,) for k in range(4)]
    assert [i for i, _ in run_tasks(_square, tasks, workers=1, after=[[], [0], [0], [1, 2]])] == [
        0,
        1,
        2,
        3,
    ]


def _call(fn, *args):
    return fn(*args)
