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
from ipbench.perception.pointnet import PointNetConfig, PointNetEnsemble
from ipbench.perception.segmentation import segment_scene
from ipbench.perception.viewset import sample_points
from ipbench.policies import PolicyModels
from ipbench.policies.oracle import true_category


def small_models(
    seeds: tuple[int, ...], words: int, threshold: float, **env_kwargs
) -> PolicyModels:
    """GP and SVM models from the uncluttered Sorting-v1 scenes of ``seeds`` (a ``words``-word
    codebook) and a tiny PointNet ensemble on the same segments' points, with ``threshold``
    for every classifier; ``env_kwargs`` go to ``gym.make``."""
    env = gym.make("ipbench/Sorting-v1", scene="uncluttered", **env_kwargs)
    views, labels, clouds = [], [], []
    for seed in seeds:
        obs, info = env.reset(seed=seed)
        cloud = depth_to_points(obs["wrist_depth"], obs["wrist_K"], obs["wrist_pose"])
        for s in segment_scene(cloud).segments:
            truth = true_category(s.pixels, info)
            if truth is not None:
                views.append(fpfh(s.points, viewpoint=obs["wrist_pose"][:3, 3]))
                clouds.append(sample_points(s.points, 64, np.random.default_rng(len(clouds))))
                labels.append(CATEGORIES.index(truth))
    env.close()
    codebook = Codebook.fit(np.concatenate(views), words, seed=0)
    X = np.stack([codebook.encode(v) for v in views])
    y = np.array(labels)
    gp = make_classifier("gp", 5).fit(X, y).model_
    svm = make_classifier("svm", 5).fit(np.concatenate([X] * 3), np.concatenate([y] * 3))
    tiny = PointNetConfig(members=2, n_points=64, widths=(16, 32), head=16, epochs=3)
    deep = PointNetEnsemble(5, tiny, CATEGORIES, "test-pointnet").fit(np.stack(clouds), y)
    area = tuple(float(v) for v in workcell_places().inspection_area.center)
    return PolicyModels(
        gp=PerceptionModel(CATEGORIES, codebook, gp, "test-gp"),
        svm=PerceptionModel(CATEGORIES, codebook, svm, "test-svm"),
        pointnet_ensemble=deep,
        inspection_area=area,
        thresholds={"gp": threshold, "svm": threshold, "pointnet_ensemble": threshold},
    )
