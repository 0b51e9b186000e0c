"""``ipbench bench exploration``: the head's stereo rendering and the saccade cycle's cost.

Measured on the complex scene (seed 0) of ``ipbench/Exploration-v0`` at the head's default
1024x680, one core (one thread for OpenCV and BLAS, as in the evaluation's workers):

- ``stereo_fps``: stereo pairs rendered per second (the two head cameras, textured objects);
- ``cycle_s_<feature>``: wall seconds of one saccade cycle of the ``active-vision`` policy with
  that feature type — render the pair, detect both eyes' features, recognise (match against
  the database, Hough voting, RANSAC), pair and triangulate, decide — the median of
  ``cycles`` decisions (each timed alone: the median keeps a neighbour's burst on a shared
  machine out of the figure, as a mean does not); ``cycle_s`` is SIFT's (the thesis' first
  feature type). The physics of the saccade and the ground-truth masks of ``info`` are not
  part of it.
Targets: ``stereo_fps`` >= 50, ``cycle_s`` <= 0.5.
"""

from __future__ import annotations

import time
from pathlib import Path

import gymnasium as gym
import numpy as np
from threadpoolctl import threadpool_limits

import ipbench.envs  # noqa: F401
from ipbench.assets.compose import HEAD_SIDES
from ipbench.eval.capture.exploration_database import load_or_build_database
from ipbench.eval.exploration.evaluate import ENV_ID
from ipbench.perception.features2d import FEATURE_TYPES
from ipbench.policies.exploration import make_exploration_policy

__all__ = ["bench_exploration"]


def bench_exploration(
    cache: Path, features: tuple[str, ...] = FEATURE_TYPES, cycles: int = 9, frames: int = 20
) -> dict[str, float]:
    """The figures of the module docstring (databases from ``cache``, built if missing)."""
    import cv2

    figures: dict[str, float] = {}
    env = gym.make(ENV_ID, scene="complex")
    try:
        with threadpool_limits(1):
            cv2.setNumThreads(1)
            obs, _ = env.reset(seed=0)
            inner = env.unwrapped
            h, w = inner.config.head_size

            def render_pair() -> dict:
                pair = dict(obs)
                for side in HEAD_SIDES:
                    pair[f"head_{side}"] = inner._renderer.render_rgb(
                        inner.data, f"head_{side}_camera", w, h
                    )
                return pair

            render_pair()
            t0 = time.perf_counter()
            for _ in range(frames):
                render_pair()
            figures["stereo_fps"] = round(frames / (time.perf_counter() - t0), 1)
            for feature in features:
                policy = make_exploration_policy(
                    "active-vision", load_or_build_database(feature, cache, progress=False)
                )
                policy.reset(0)
                policy.act(render_pair())  # warm-up
                walls = []
                for _ in range(cycles):
                    t0 = time.perf_counter()
                    policy.act(render_pair())
                    walls.append(time.perf_counter() - t0)
                figures[f"cycle_s_{feature}"] = round(float(np.median(walls)), 3)
    finally:
        env.close()
    if "cycle_s_sift" in figures:
        figures["cycle_s"] = figures["cycle_s_sift"]
    return figures
