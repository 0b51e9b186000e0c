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


def test_single_thread_worker_limits_opencv_llvmpipe_and_the_loaded_blas():
    code = (
        "import os, cv2, numpy, scipy.linalg\n"
        "from threadpoolctl import threadpool_info\n"
        "from ipbench.eval.schedule import single_thread_worker\n"
        "cv2.setNumThreads(2)\n"
        "blas = [p for p in threadpool_info() if p['user_api'] == 'blas']\n"
        "before = max(p['num_threads'] for p in blas)\n"
        "single_thread_worker()\n"
        "after = max(p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas')\n"
        "print(cv2.getNumThreads(), os.environ['LP_NUM_THREADS'], before, after, len(blas))\n"
    )
    # a BLAS loaded before the call (numpy and scipy are, in a spawned worker) starts with as
    # many threads as cores; the variables alone would not limit it any more
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env
    )
    cv_threads, lp_threads, before, after, n_blas = out.stdout.split()
    assert (cv_threads, lp_threads, after) == ("1", "1", "1")
    assert int(n_blas) >= 1
    if (os.cpu_count() or 1) > 1:
        assert int(before) > 1  # the limit did something


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
