"""``ipbench bench eval``: sorting episodes per minute for each policy, 1 and 2 workers.

Each measurement runs ``episodes`` cluttered episodes (seeds 0, 1, ...) of one policy through
the same executors as ``ipbench eval sorting`` — serially, then in 2 worker processes — with
models and thresholds from the cache. Keys: ``<policy>_w1_episodes_per_min`` and
``<policy>_w2_episodes_per_min``.
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

from ipbench.eval.sorting import SortingEvalConfig, Task, _executor, prepare_models

__all__ = ["bench_eval"]


def bench_eval(
    cache: Path, policies: tuple[str, ...] = ("random", "gp-ipm"), episodes: int = 4
) -> dict[str, float]:
    """Episodes per minute per policy and worker count (see the module docstring)."""
    base = SortingEvalConfig(scenes=("cluttered",), policies=policies, seeds=tuple(range(episodes)))
    models, _ = prepare_models(cache, base)
    figures: dict[str, float] = {}
    for policy in policies:
        tasks = [Task("cluttered", policy, seed) for seed in range(episodes)]
        for workers in (1, 2):
            config = replace(base, policies=(policy,), workers=workers)
            t0 = time.perf_counter()
            for _ in _executor(config)(tasks, models, config):
                pass
            minutes = (time.perf_counter() - t0) / 60.0
            figures[f"{policy}_w{workers}_episodes_per_min"] = round(episodes / minutes, 2)
    return figures
