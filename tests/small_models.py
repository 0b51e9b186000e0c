"""A small real perception model for tests: a codebook and classifiers fitted to the segments
of a few wrist views (labelled by the ground-truth masks), instead of the full dataset."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

import ipbench.envs  # noqa: F401  (registers the ids)
from ipbench.assets.objects import CATEGORIES
from ipbench.envs.sorting import workcell_places
from ipbench.perception.classifiers import make_classifier
from ipbench.perception.cloud import depth_to_points
from ipbench.perception.features import Codebook, fpfh
from ipbench.perception.model import PerceptionModel
from ipbench.perception.segmentation import segment_scene
from ipbench.policies import PolicyModels
from ipbench.policies.oracle import true_category


def small_models(
    seeds: tuple[int, ...], words: int, threshold: float, **env_kwargs
) -> PolicyModels:
    """GP and SVM models from the uncluttered Sorting-v1 scenes of ``seeds`` (a ``words``-word
    codebook), with ``threshold`` for both classifiers; ``env_kwargs`` go to ``gym.make``."""
    env = gym.make("ipbench/Sorting-v1", scene="uncluttered", **env_kwargs)
    views, labels = [], []
    for seed in seeds:
        obs, info = env.reset(seed=seed)
        cloud = depth_to_points(obs["wrist_depth"], obs["wrist_K"], obs["wrist_pose"])
        for s in segment_scene(cloud).segments:
            truth = true_category(s.pixels, info)
            if truth is not None:
                views.append(fpfh(s.points, viewpoint=obs["wrist_pose"][:3, 3]))
                labels.append(CATEGORIES.index(truth))
    env.close()
    codebook = Codebook.fit(np.concatenate(views), words, seed=0)
    X = np.stack([codebook.encode(v) for v in views])
    y = np.array(labels)
    gp = make_classifier("gp", 5).fit(X, y).model_
    svm = make_classifier("svm", 5).fit(np.concatenate([X] * 3), np.concatenate([y] * 3))
    area = tuple(float(v) for v in workcell_places().inspection_area.center)
    return PolicyModels(
        gp=PerceptionModel(CATEGORIES, codebook, gp, "test-gp"),
        svm=PerceptionModel(CATEGORIES, codebook, svm, "test-svm"),
        inspection_area=area,
        thresholds={"gp": threshold, "svm": threshold},
    )
