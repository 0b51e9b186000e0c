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

from ipbench.eval.sorting import (
    SortingEvalConfig,
    SortingEvalError,
    Task,
    _executor,
    prepare_models,
)

__all__ = ["bench_eval", "check_bench_eval"]


def check_bench_eval(policies: tuple[str, ...], episodes: int) -> SortingEvalConfig:
    """The configuration :func:`bench_eval` measures, checked before any work.

    Raises :class:`~ipbench.eval.sorting.SortingEvalError` (saying what is valid) for unknown
    policies, or ``episodes`` outside 1 .. the first validation seed (the episodes run seeds
    0 .. ``episodes`` - 1, which must not be validation seeds)."""
    first_validation = min(SortingEvalConfig().validation_seeds)
    if not 1 <= episodes <= first_validation:
        raise SortingEvalError(
            f"episodes must be between 1 and {first_validation} (seeds 0 .. episodes - 1, below "
            f"the validation seeds), got {episodes}"
        )
    return SortingEvalConfig(
        scenes=("cluttered",), policies=tuple(policies), seeds=tuple(range(episodes))
    )


def bench_eval(
    cache: Path, policies: tuple[str, ...] = ("random", "gp-ipm"), episodes: int = 4
) -> dict[str, float]:
    """Episodes per minute per policy and worker count (see the module docstring); bad
    settings raise before any work (:func:`check_bench_eval`)."""
    base = check_bench_eval(policies, episodes)
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
