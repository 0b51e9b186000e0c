"""``ipbench bench eval``: sorting episodes per minute, 1 and 2 workers, and v1, v2, v3 episodes.

Each rate runs ``episodes`` cluttered episodes (seeds 0, 1, ...) of one policy on the
benchmark's id (:data:`ipbench.envs.LATEST`, with the models trained on its views: what
``make eval`` runs) through the same executors as ``ipbench eval sorting`` — serially, then in
2 worker processes — with models and thresholds from the cache. Keys:

- ``<policy>_w1_episodes_per_min``, ``<policy>_w2_episodes_per_min`` for each policy asked
  for, and ``episodes_per_min_1``, ``episodes_per_min_2`` (GP-IPM's, always measured) with
  ``speedup_2_workers`` = their ratio (2 on 2 cores is perfect scaling), and where the rest
  goes: ``slowdown_2_workers``, GP-IPM's mean episode wall time with 2 workers over that with
  one (the cores slowing each other: shared cache and memory bandwidth, anything else running),
  and ``busy_2_workers``, the share of the 2-worker run's wall time x 2 that the workers spent
  in episodes (the rest: starting the pool, loading models, waiting on the last long episode).
  ``speedup_2_workers`` ~= 2 x ``busy_2_workers`` / ``slowdown_2_workers``;
- ``episode_s_v1``, ``episode_s_v2``, ``episode_s_v3``: mean wall seconds of the same
  cluttered ``oracle`` episodes (true labels: no threshold, the same segmentation and grasping
  code) on ``ipbench/Sorting-v1``, ``-v2`` and ``-v3``, one worker, measured one after the
  other in this run; ``episode_speedup_v2`` = v1 / v2 and ``episode_speedup_v3`` = v2 / v3.
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

from ipbench.envs import LATEST
from ipbench.eval.perception.evaluate import PerceptionEvalConfig
from ipbench.eval.sorting.evaluate import (
    SortingEvalConfig,
    SortingEvalError,
    Task,
    _executor,
    prepare_models,
)

__all__ = ["bench_eval", "check_bench_eval"]

_VERSIONS = {"v1": "ipbench/Sorting-v1", "v2": "ipbench/Sorting-v2", "v3": "ipbench/Sorting-v3"}


def check_bench_eval(policies: tuple[str, ...], episodes: int) -> SortingEvalConfig:
    """The configuration :func:`bench_eval` measures, checked before any work.

    Raises :class:`~ipbench.eval.sorting.evaluate.SortingEvalError` (saying what is valid) for
    unknown policies, or ``episodes`` outside 1 .. the first validation seed (the episodes run seeds
    0 .. ``episodes`` - 1, which must not be validation seeds)."""
    first_validation = min(SortingEvalConfig().validation_seeds)
    if not 1 <= episodes <= first_validation:
        raise SortingEvalError(
            f"episodes must be between 1 and {first_validation} (seeds 0 .. episodes - 1, below "
            f"the validation seeds), got {episodes}"
        )
    SortingEvalConfig(scenes=("cluttered",), policies=tuple(policies))  # names checked
    wanted = tuple(dict.fromkeys((*policies, "gp-ipm", "oracle")))
    return SortingEvalConfig(
        scenes=("cluttered",),
        policies=wanted,
        seeds=tuple(range(episodes)),
        perception=PerceptionEvalConfig.for_env(LATEST),
    )


def _with_env(config: SortingEvalConfig, env_id: str) -> SortingEvalConfig:
    """``config`` whose episodes run on ``env_id`` (its own objects and sensor)."""
    perception = config.perception
    dataset = replace(perception.dataset, env_id=env_id, depth_noise=None)
    return replace(config, perception=replace(perception, dataset=dataset))


def _run(config: SortingEvalConfig, tasks: list[Task], models) -> tuple[float, float]:
    """Wall minutes of the run, and the sum of its episodes' own wall seconds."""
    t0 = time.perf_counter()
    inside = sum(r["wall_time_s"] for r in _executor(config)(tasks, models, config))
    return (time.perf_counter() - t0) / 60.0, float(inside)


def bench_eval(
    cache: Path, policies: tuple[str, ...] = ("random", "gp-ipm"), episodes: int = 4
) -> dict[str, float]:
    """The figures of the module docstring; bad settings raise before any work
    (:func:`check_bench_eval`)."""
    base = check_bench_eval(policies, episodes)
    models, _ = prepare_models(cache, replace(base, workers=2))  # views and models: 2 workers
    figures: dict[str, float] = {}
    seeds = range(episodes)
    inside: dict[int, float] = {}
    for policy in dict.fromkeys((*policies, "gp-ipm")):
        tasks = [Task("cluttered", policy, seed) for seed in seeds]
        for workers in (1, 2):
            config = replace(base, policies=(policy,), workers=workers)
            minutes, episode_s = _run(config, tasks, models)
            rate = round(episodes / minutes, 2)
            if policy in policies:
                figures[f"{policy}_w{workers}_episodes_per_min"] = rate
            if policy == "gp-ipm":
                figures[f"episodes_per_min_{workers}"] = rate
                inside[workers] = episode_s
                if workers == 2:
                    figures["busy_2_workers"] = round(episode_s / (2 * 60.0 * minutes), 3)
    figures["speedup_2_workers"] = round(
        figures["episodes_per_min_2"] / figures["episodes_per_min_1"], 2
    )
    figures["slowdown_2_workers"] = round(inside[2] / inside[1], 3)
    oracle = [Task("cluttered", "oracle", seed) for seed in seeds]
    for tag, env_id in _VERSIONS.items():
        config = _with_env(replace(base, policies=("oracle",), workers=1), env_id)
        minutes, _ = _run(config, oracle, models)
        figures[f"episode_s_{tag}"] = round(60.0 * minutes / episodes, 2)
    figures["episode_speedup_v2"] = round(figures["episode_s_v1"] / figures["episode_s_v2"], 2)
    figures["episode_speedup_v3"] = round(figures["episode_s_v2"] / figures["episode_s_v3"], 2)
    return figures
