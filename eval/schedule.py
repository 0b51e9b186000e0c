"""Order and place episode tasks so that workers stay busy: longest first, one thread each.

With ``W`` workers and tasks handed out in submission order, the run ends when the last
worker finishes: if a long task (a cluttered episode with in-hand inspections takes ~3x an
uncluttered random one) starts last, the other workers idle meanwhile. Submitting the longest
first (LPT, Graham 1969: within 4/3 of the optimal makespan) leaves only short tasks for the
end. The expected cost of a task is the number of skills it runs: about ``steps_per_object``
per object, more for policies that inspect (:data:`COST_FACTOR`, from measured episode times of
``ipbench bench eval``); ties keep the caller's order, so the schedule is a pure function of the
task list.

Each worker process renders with one llvmpipe thread and runs OpenCV, BLAS and torch with one
thread (:func:`single_thread_worker`): ``W`` workers on ``W`` cores, not ``2 W`` threads
fighting for them. A local worker also ends itself when the process that started it is gone
(:func:`exit_with_parent`): a killed ``ipbench eval`` leaves no workers rendering for nobody.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from typing import TypeVar

__all__ = [
    "COST_FACTOR",
    "exit_with_parent",
    "longest_first",
    "pool_worker",
    "single_thread_worker",
    "task_cost",
]

T = TypeVar("T")

COST_FACTOR: dict[str, float] = {
    "random": 1.0,
    "oracle": 1.0,
    "oracle-scene": 1.0,
    "gp-ipm": 1.4,
    "svm-ipm": 1.4,
    "deep-ipm": 1.4,
    "gp-ipm-area": 1.6,
}
"""Relative cost per object of a policy's episode (inspections add skills); others: 1.5."""


def task_cost(scene_objects: int, policy: str) -> float:
    """Expected relative wall time of an episode of ``policy`` on a scene of ``scene_objects``."""
    return scene_objects * COST_FACTOR.get(policy, 1.5)


def longest_first(tasks: Iterable[T], cost: Callable[[T], float]) -> list[T]:
    """``tasks`` sorted by decreasing ``cost`` (stable: equal costs keep their order)."""
    items: Sequence[T] = list(tasks)
    order = sorted(range(len(items)), key=lambda i: (-cost(items[i]), i))
    return [items[i] for i in order]


def single_thread_worker() -> None:
    """Limit this process to one thread per library (call first in a worker process, before
    any rendering context exists: llvmpipe reads ``LP_NUM_THREADS`` when it starts).

    The BLAS libraries already loaded (numpy's and scipy's OpenBLAS are, by the time a spawned
    worker has unpickled its task) are limited by threadpoolctl for the rest of the process;
    the variables cover those that load later. Limiting only llvmpipe, OpenMP, OpenCV and torch
    is not enough: numpy's OpenBLAS would run its second thread in every worker (a third of a
    core each, spinning while it waits for work) and slow every dataset part rendered in a pool
    (episodes and trainings limit themselves)."""
    for name in ("LP_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[name] = "1"  # read when each library starts (torch: OMP_NUM_THREADS)
    import cv2
    from threadpoolctl import threadpool_limits

    _LIMITS.append(threadpool_limits(limits=1))  # kept: in effect until the process ends
    cv2.setNumThreads(1)
    torch = sys.modules.get("torch")  # already started: its pool is set, not its variable
    if torch is not None:
        torch.set_num_threads(1)


_LIMITS: list = []


def exit_with_parent(poll_s: float = 0.5) -> None:
    """End this process within ``poll_s`` seconds of its parent's end (killed, crashed or
    exited): a daemon thread watches for the re-parenting. A pool's workers otherwise go on
    with their queued tasks after ``kill`` of the main process (only Ctrl-C reaches the whole
    process group), holding the cores and writing nothing anyone reads."""
    parent = os.getppid()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(poll_s)
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


def pool_worker() -> None:
    """Initializer of a local worker process: :func:`single_thread_worker`, and
    :func:`exit_with_parent`."""
    single_thread_worker()
    exit_with_parent()
