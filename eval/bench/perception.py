"""``ipbench bench perception``: how long perception takes, printed (and optionally as JSON).

Per cluttered 640x480 observation, on one core (BLAS and OpenMP pools limited to one
thread): ``segment_s`` (cloud, table plane, prism, clusters), ``features_s`` (FPFH and
bag-of-words of every segment), ``classify_s`` (GP predictive probabilities of every segment,
from a GP trained on ~1,500 vectors) and their sum ``scene_s``; and the fit time of our GP and
of scikit-learn's one-vs-rest GP on the same ~1,500 synthetic 256-d training vectors.
"""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np
from threadpoolctl import threadpool_limits

import ipbench.envs  # noqa: F401
from ipbench.perception.classifiers import make_classifier
from ipbench.perception.cloud import depth_to_points
from ipbench.perception.features import Codebook, FeatureConfig, fpfh
from ipbench.perception.segmentation import SegmentationConfig, segment_scene
from ipbench.perception.synthetic import make_split

__all__ = ["bench_perception", "TARGETS"]

TARGETS = {"scene_s": 0.5}
"""Targets on the 2-core reference machine (seconds, at most)."""


def _median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def bench_perception(seed: int = 0, n_train: int = 1500, repeats: int = 3) -> dict[str, float]:
    env = gym.make("ipbench/SortingCluttered-v0")
    obs, _ = env.reset(seed=seed)
    env.close()
    x, y, _, _ = make_split(n_train, 1, seed=seed)
    seg_cfg, feat_cfg = SegmentationConfig(), FeatureConfig()
    figures: dict[str, float] = {}
    with threadpool_limits(1):
        state: dict = {}

        def segment():
            cloud = depth_to_points(obs["wrist_depth"], obs["wrist_K"], obs["wrist_pose"])
            state["segments"] = segment_scene(cloud, seg_cfg).segments

        segment()
        eye = obs["wrist_pose"][:3, 3]
        descriptors = np.concatenate(
            [fpfh(s.points, feat_cfg, viewpoint=eye) for s in state["segments"]]
        )
        codebook = Codebook.fit(descriptors, 256, seed)

        def features():
            state["bow"] = np.stack(
                [
                    codebook.encode(fpfh(s.points, feat_cfg, viewpoint=eye))
                    for s in state["segments"]
                ]
            )

        gp = make_classifier("gp", n_classes=5, seed=seed)
        t0 = time.perf_counter()
        gp.fit(x, y)
        figures["gp_fit_s"] = round(time.perf_counter() - t0, 3)
        sk = make_classifier("sklearn_gp", n_classes=5, seed=seed)
        t0 = time.perf_counter()
        sk.fit(x, y)
        figures["sklearn_gp_fit_s"] = round(time.perf_counter() - t0, 3)
        figures["segment_s"] = round(_median_time(segment, repeats), 4)
        features()
        figures["features_s"] = round(_median_time(features, repeats), 4)
        figures["classify_s"] = round(
            _median_time(lambda: gp.predict_proba(state["bow"]), repeats), 4
        )
    figures["segments"] = len(state["segments"])
    figures["scene_s"] = round(
        figures["segment_s"] + figures["features_s"] + figures["classify_s"], 4
    )
    order = [
        "scene_s",
        "segment_s",
        "features_s",
        "classify_s",
        "gp_fit_s",
        "sklearn_gp_fit_s",
        "segments",
    ]
    return {k: figures[k] for k in order}
