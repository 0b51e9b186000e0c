"""Seeded layouts follow the thesis compositions and the placement rules."""

from __future__ import annotations

import numpy as np
import pytest

import ipbench.envs.layout as layout_module
from ipbench.assets.objects import CATEGORIES
from ipbench.envs.layout import LayoutError, _footprint, _overlaps, sample_layout
from ipbench.envs.robot import ik_model
from ipbench.envs.sorting_scenes import SCENES, STANDARD_SCENES
from ipbench.envs.world import Places


@pytest.fixture(scope="module")
def places():
    return Places.from_model(ik_model())


def _layout(places, scene, seed):
    area = places.spawn_area
    return sample_layout(scene, seed, area.center, area.half, places.table_height)


def test_exports():
    for name in layout_module.__all__:
        assert hasattr(layout_module, name)


@pytest.mark.parametrize("scene", sorted(STANDARD_SCENES))  # (the pile: test_pile_scene.py)
def test_composition_and_determinism(places, scene):
    a, b = _layout(places, scene, 7), _layout(places, scene, 7)
    assert a == b
    counts = [sum(o.instance.category == c for o in a.objects) for c in CATEGORIES]
    assert tuple(counts) == SCENES[scene].counts
    assert [o.object_id for o in a.objects] == list(range(len(a.objects)))
    c = _layout(places, scene, 8)
    assert [o.position for o in a.objects] != [o.position for o in c.objects]


@pytest.mark.parametrize("scene", sorted(STANDARD_SCENES))
def test_objects_inside_the_area_without_overlap(places, scene):
    config = SCENES[scene]
    area = places.spawn_area
    for seed in range(10):
        lay = _layout(places, scene, seed)
        rects = []
        for obj in lay.objects:
            offset, (hx, hy) = _footprint(obj.instance, obj.resting)
            c, s = np.cos(obj.yaw), np.sin(obj.yaw)
            mid = np.array(obj.position[:2]) + [
                c * offset[0] - s * offset[1],
                s * offset[0] + c * offset[1],
            ]
            extent = np.array([abs(c) * hx + abs(s) * hy, abs(s) * hx + abs(c) * hy])
            assert np.all(np.abs(mid - area.center[:2]) <= area.half[:2] - extent + 1e-9)
            rect = (mid[0], mid[1], hx, hy, obj.yaw)
            assert not _overlaps(rect, np.array(rects).reshape(-1, 5), config.gap - 1e-6)
            rects.append(rect)
            assert obj.position[2] == pytest.approx(places.table_height + obj.resting.height)


def test_known_and_unknown_instances_both_appear(places):
    for scene in STANDARD_SCENES:
        for seed in range(10):
            known = {o.instance.known for o in _layout(places, scene, seed).objects}
            assert known == {True, False}


def test_cluttered_scenes_have_objects_lying_and_packed(places):
    for seed in range(5):
        clut = _layout(places, "cluttered", seed)
        unclut = _layout(places, "uncluttered", seed)
        assert sum(o.resting.name == "side" for o in clut.objects) == 2
        assert all(o.resting.name == "upright" for o in unclut.objects)

        def mean_nn(lay):
            p = np.array([o.position[:2] for o in lay.objects])
            dist = np.linalg.norm(p[:, None] - p[None], axis=-1) + np.eye(len(p)) * 9
            return dist.min(axis=1).mean()

        assert mean_nn(clut) < mean_nn(unclut)


def test_overlap_test_against_hand_cases():
    square = (0.0, 0.0, 0.05, 0.05, 0.0)
    assert _overlaps(square, np.array([[0.09, 0.0, 0.05, 0.05, 0.0]]), 0.0)
    assert not _overlaps(square, np.array([[0.11, 0.0, 0.05, 0.05, 0.0]]), 0.0)
    assert _overlaps(square, np.array([[0.11, 0.0, 0.05, 0.05, 0.0]]), 0.02)
    # a 45-degree square reaches further along x: 0.05 * sqrt(2) ~ 0.0707
    assert _overlaps(square, np.array([[0.115, 0.0, 0.05, 0.05, np.pi / 4]]), 0.0)
    assert not _overlaps(square, np.array([[0.125, 0.0, 0.05, 0.05, np.pi / 4]]), 0.0)


def test_unknown_scene_lists_the_valid_ones(places):
    with pytest.raises(LayoutError, match="valid scenes: uncluttered, cluttered"):
        _layout(places, "kitchen", 0)
