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

Another exploration id (``env_id``, e.g. ``ipbench/Exploration-v1``) is measured the same
way at its own head size, database and cameras — a foveated id's pair is rendered at full
resolution and foveated, as its observation is — and its figures carry the id's version as a
suffix (``stereo_fps_v1``, ``cycle_s_sift_v1``, ``cycle_s_v1``): the targets are v0's at
its own size. Another head size than the id's adds it (``stereo_fps_256x384``,
``cycle_s_v1_1632x2464``): :func:`figure_suffix`.
"""

from __future__ import annotations

import time
from pathlib import Path

import gymnasium as gym
import numpy as np
from threadpoolctl import threadpool_limits

import ipbench.envs  # noqa: F401
from ipbench.assets.compose import HEAD_SIDES
from ipbench.envs.sensors.foveation import foveate
from ipbench.eval.capture.exploration_database import load_or_build_database
from ipbench.eval.exploration.evaluate import ENV_ID, ExplorationEvalConfig
from ipbench.perception.features2d import FEATURE_TYPES
from ipbench.policies.exploration import make_exploration_policy

__all__ = ["bench_exploration", "figure_suffix"]


def figure_suffix(env_id: str, head_size: tuple[int, int], id_size: tuple[int, int]) -> str:
    """The figures' suffix: empty for v0 at its own size, else ``_<version>`` for another id
    and ``_<H>x<W>`` for another size than the id's (``id_size``), in that order."""
    suffix = "" if env_id == ENV_ID else "_" + env_id.rsplit("-", 1)[-1]
    if tuple(head_size) != tuple(id_size):
        suffix += f"_{head_size[0]}x{head_size[1]}"
    return suffix


def bench_exploration(
    cache: Path,
    features: tuple[str, ...] = FEATURE_TYPES,
    cycles: int = 9,
    frames: int = 20,
    env_id: str = ENV_ID,
    head_size: tuple[int, int] | None = None,
) -> dict[str, float]:
    """The figures of the module docstring (databases from ``cache``, built if missing);
    ``head_size`` (H, W) px renders another size than the id's, its database captured alike.

    Raises :class:`~ipbench.eval.exploration.evaluate.ExplorationEvalError` for an id that is
    not an exploration id (the message lists them).
    """
    import cv2

    settings = ExplorationEvalConfig(env_id=env_id, head_size=head_size)  # and its fovea, prints
    f = settings.fovea_factor
    own = ExplorationEvalConfig(env_id=env_id).head_size
    suffix = figure_suffix(env_id, settings.head_size, own)
    figures: dict[str, float] = {}
    env = gym.make(env_id, scene="complex", head_size=tuple(settings.head_size))
    try:
        with threadpool_limits(1):
            cv2.setNumThreads(1)
            obs, _ = env.reset(seed=0)
            inner = env.unwrapped
            h, w = inner.config.head_size

            def render_pair() -> dict:
                pair = dict(obs)  # the reset's K and poses: the head does not move
                for side in HEAD_SIDES:
                    image = inner._renderer.render_rgb(inner.data, f"head_{side}_camera", w, h)
                    if f > 1:  # the images only; K is the reset observation's
                        eye = foveate(image, np.eye(3), f)
                        pair[f"head_{side}"], pair[f"head_{side}_fovea"] = eye.periphery, eye.fovea
                    else:
                        pair[f"head_{side}"] = image
                return pair

            render_pair()
            t0 = time.perf_counter()
            for _ in range(frames):
                render_pair()
            figures[f"stereo_fps{suffix}"] = round(frames / (time.perf_counter() - t0), 1)
            for feature in features:
                database = load_or_build_database(feature, cache, settings.database, progress=False)
                policy = make_exploration_policy("active-vision", database)
                policy.reset(0)
                policy.act(render_pair())  # warm-up
                walls = []
                for _ in range(cycles):
                    t0 = time.perf_counter()
                    policy.act(render_pair())
                    walls.append(time.perf_counter() - t0)
                figures[f"cycle_s_{feature}{suffix}"] = round(float(np.median(walls)), 3)
    finally:
        env.close()
    if f"cycle_s_sift{suffix}" in figures:
        figures[f"cycle_s{suffix}"] = figures[f"cycle_s_sift{suffix}"]
    return figures
