"""Run independent tasks in local worker processes, surviving a worker that dies.

A worker can die without a Python exception: an OpenGL driver (Mesa llvmpipe) or a physics
library crashing with a signal (seen here: a render worker killed by SIGSEGV in libc after
52 of 80 dataset parts). :class:`concurrent.futures.ProcessPoolExecutor` then breaks: every
unfinished task fails with ``BrokenProcessPool`` and the run ends, although the crash is rare
and the next attempt at the same task usually succeeds. :func:`run_tasks` starts a fresh pool
and re-submits the tasks that did not finish (a task is a pure function of its arguments, so
re-running it gives the same result), up to ``restarts`` times; then it raises
:class:`WorkerCrashError`, saying what to do. Results already handed to the caller are kept
by it (the dataset's parts, the evaluation's episode log), so nothing finished is lost.

Results are yielded as ``(index, result)`` in completion order; an exception raised *inside*
a task is not a crash and propagates at once (it would fail again).

Tasks may depend on others (``after``): a task is handed to a worker only once every task it
depends on has finished *and its result has been taken by the caller* (the generator resumes
only then), so a task can read what the caller wrote from an earlier one's result, e.g. a model
trained from dataset parts the caller saved. At most ``workers`` tasks are in flight; a free
worker takes the first ready task in list order, so the list order is the priority.
"""

from __future__ import annotations

import multiprocessing
import sys
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any

__all__ = ["DEFAULT_RESTARTS", "WorkerCrashError", "run_tasks"]

DEFAULT_RESTARTS = 3
"""Fresh pools started after worker crashes before a run gives up."""


class WorkerCrashError(RuntimeError):
    """Worker processes kept dying (not a Python error in a task: a crash of the process)."""


def run_tasks(
    fn: Callable[..., Any],
    tasks: Sequence[tuple],
    workers: int,
    initializer: Callable[..., None] | None = None,
    initargs: tuple = (),
    restarts: int = DEFAULT_RESTARTS,
    what: str = "task",
    after: Sequence[Sequence[int]] | None = None,
) -> Iterator[tuple[int, Any]]:
    """``fn(*tasks[i])`` for every ``i``, in ``workers`` spawned processes (each started by
    ``initializer(*initargs)``), yielding ``(i, result)`` as each finishes.

    ``workers <= 1`` runs them here, in order. ``after[i]``: indices of the tasks that must
    finish before task ``i`` starts, each smaller than ``i`` (the list order is then always
    a valid order; see the module docstring). A pool whose worker died is replaced and the
    unfinished tasks re-submitted, in their order, at most ``restarts`` times; ``what`` names
    a task in the messages.

    Raises
    ------
    ValueError
        when ``after`` does not give one list per task of earlier task indices.
    WorkerCrashError
        when workers still die after ``restarts`` fresh pools.
    """
    needs = _dependencies(after, len(tasks))
    if workers <= 1:
        if initializer is not None:
            initializer(*initargs)
        for i, args in enumerate(tasks):
            yield i, fn(*args)
        return
    todo = list(range(len(tasks)))
    finished: set[int] = set()
    ctx = multiprocessing.get_context("spawn")  # no forked GL contexts or BLAS thread pools
    for attempt in range(restarts + 1):
        pool = ProcessPoolExecutor(
            workers, mp_context=ctx, initializer=initializer, initargs=initargs
        )
        try:
            futures: dict = {}
            waiting = list(todo)  # not yet handed to this pool, in priority order
            broken = False
            while (waiting or futures) and not broken:
                while len(futures) < workers:
                    ready = next((i for i in waiting if needs[i] <= finished), None)
                    if ready is None:
                        break
                    waiting.remove(ready)
                    futures[pool.submit(fn, *tasks[ready])] = ready
                done, _ = wait(set(futures), return_when=FIRST_COMPLETED)
                for future in sorted(done, key=futures.__getitem__):
                    i = futures.pop(future)
                    try:
                        result = future.result()
                    except BrokenProcessPool:
                        broken = True
                        continue
                    todo.remove(i)
                    yield i, result
                    finished.add(i)
        finally:  # also when the caller stops early (Ctrl-C): queued tasks are dropped
            pool.shutdown(wait=True, cancel_futures=True)
        if not todo:
            return
        if attempt < restarts:
            print(
                f"ipbench: a worker process died ({len(todo)} {what}s unfinished); starting "
                f"fresh workers for them (restart {attempt + 1} of {restarts})",
                file=sys.stderr,
                flush=True,
            )
    raise WorkerCrashError(
        f"worker processes died {restarts + 1} times; {len(todo)} {what}s did not finish. "
        "What finished is kept: run the same command again to resume, or with --workers 1 "
        "to run in this process and see the crash"
    )


def _dependencies(after: Sequence[Sequence[int]] | None, n: int) -> list[set[int]]:
    if after is None:
        return [set() for _ in range(n)]
    if len(after) != n:
        raise ValueError(f"after has {len(after)} entries for {n} tasks; valid: one per task")
    needs = [set(int(j) for j in deps) for deps in after]
    for i, deps in enumerate(needs):
        if any(not 0 <= j < i for j in deps):
            raise ValueError(
                f"task {i} depends on {sorted(deps)}; valid: indices of earlier tasks (0..{i - 1})"
            )
    return needs
