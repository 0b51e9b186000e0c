"""Longest-first scheduling of episode tasks, single-threaded workers that end with their main."""

import os
import subprocess
import sys
import time

from ipbench.eval.schedule import COST_FACTOR, longest_first, task_cost


def test_longest_first_orders_by_decreasing_cost_and_keeps_ties_in_order():
    tasks = [("uncluttered", "random", s) for s in range(3)]
    tasks += [("cluttered", "gp-ipm", s) for s in range(3)]
    tasks += [("cluttered", "random", s) for s in range(3)]
    n_objects = {"uncluttered": 5, "cluttered": 14}
    order = longest_first(tasks, lambda t: task_cost(n_objects[t[0]], t[1]))
    assert order[:3] == [("cluttered", "gp-ipm", s) for s in range(3)]
    assert order[3:6] == [("cluttered", "random", s) for s in range(3)]
    assert order[6:] == [("uncluttered", "random", s) for s in range(3)]
    # a pure function of the list: the same input gives the same schedule
    assert order == longest_first(list(tasks), lambda t: task_cost(n_objects[t[0]], t[1]))


def test_inspecting_policies_cost_more_than_random_and_unknown_ones_have_a_default():
    assert COST_FACTOR["gp-ipm"] > COST_FACTOR["random"]
    assert task_cost(14, "random") > task_cost(5, "gp-ipm")
    assert task_cost(10, "some-new-policy") == 15.0


def test_single_thread_worker_limits_opencv_and_llvmpipe():
    code = (
        "import os, cv2\n"
        "from ipbench.eval.schedule import single_thread_worker\n"
        "cv2.setNumThreads(2)\n"
        "single_thread_worker()\n"
        "print(cv2.getNumThreads(), os.environ['LP_NUM_THREADS'])\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["1", "1"]


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    stat = f"/proc/{pid}/stat"  # a zombie waiting for its reaper counts as gone
    return not (os.path.exists(stat) and open(stat).read().split(") ")[1].startswith("Z"))


def test_pool_workers_end_when_the_main_process_is_killed():
    code = (
        "import multiprocessing as mp, os, time\n"
        "from concurrent.futures import ProcessPoolExecutor\n"
        "from ipbench.eval.schedule import pool_worker\n"
        "if __name__ == '__main__':\n"
        "    pool = ProcessPoolExecutor(1, mp_context=mp.get_context('spawn'),"
        " initializer=pool_worker)\n"
        "    print(pool.submit(os.getpid).result(), flush=True)\n"
        "    pool.submit(time.sleep, 120)\n"
        "    time.sleep(120)\n"
    )
    main = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    worker = int(main.stdout.readline())
    assert _alive(worker)
    main.kill()  # SIGKILL: no cleanup in the main process at all
    main.wait()
    deadline = time.monotonic() + 10
    while _alive(worker) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _alive(worker), "the worker went on after its main process was killed"
