"""Grasp planning in clutter: the free-grasp check and the split of merged segments."""

from __future__ import annotations

import numpy as np
import pytest

from ipbench.perception.cloud import PerceptionError
from ipbench.perception.segmentation import make_segment
from ipbench.perception.split import ObjectEnvelope, fits_one_object, split_merged, split_segment
from ipbench.policies.envelopes import object_envelopes
from ipbench.policies.grasping.free import check_grasp, tip_height
from ipbench.policies.grasping.segments import grasp_target, rim_circle

TABLE = 0.72
UP, OFFSET = np.array([0.0, 0.0, 1.0]), -TABLE  # the table plane z = TABLE


def _box(centre_xy, size, step=0.003) -> np.ndarray:
    """Points on the top and the four sides of an axis-aligned box standing on the table."""
    (cx, cy), (sx, sy, sz) = centre_xy, size
    xs = np.arange(-sx / 2, sx / 2 + 1e-9, step)
    ys = np.arange(-sy / 2, sy / 2 + 1e-9, step)
    zs = np.arange(0.0, sz + 1e-9, step)
    top = np.array([(x, y, sz) for x in xs for y in ys])
    sides = [(x, s * sy / 2, z) for x in xs for z in zs for s in (-1, 1)]
    sides += [(s * sx / 2, y, z) for y in ys for z in zs for s in (-1, 1)]
    pts = np.vstack([top, np.array(sides)])
    return pts + np.array([cx, cy, TABLE])


def _cylinder(centre_xy, radius, height, step=0.003) -> np.ndarray:
    """Points on the top disc and the wall of an upright cylinder on the table."""
    r = np.arange(0.0, radius + 1e-9, step)
    disc = [
        (ri * np.cos(a), ri * np.sin(a), height)
        for ri in r
        for a in np.linspace(0, 2 * np.pi, max(6, int(2 * np.pi * ri / step)), endpoint=False)
    ]
    angles = np.linspace(0, 2 * np.pi, int(2 * np.pi * radius / step), endpoint=False)
    wall = [
        (radius * np.cos(a), radius * np.sin(a), z)
        for a in angles
        for z in np.arange(0, height, step)
    ]
    return np.vstack([disc, wall]) + np.array([centre_xy[0], centre_xy[1], TABLE])


def _segment(points: np.ndarray):
    return make_segment(points, np.arange(len(points)), UP, OFFSET)


def test_tip_height_follows_the_skill_and_the_gripper() -> None:
    # grasp_depth 2 cm below the target, tips 3.5 cm below the TCP; never below 4 cm + table
    assert tip_height(TABLE + 0.15, TABLE) == pytest.approx(TABLE + 0.15 - 0.02 - 0.035)
    assert tip_height(TABLE + 0.03, TABLE) == pytest.approx(TABLE + 0.04 - 0.035)


def test_a_jaw_landing_on_the_neighbour_is_rejected_and_the_clear_side_taken() -> None:
    """A 6 x 10 cm box with a second box 2 cm beyond its narrow side: closing across the
    narrow side (along x) puts a finger on the neighbour; closing along y is clear."""
    target = _box((1.0, 0.0), (0.06, 0.10, 0.20))
    neighbour = _box((1.0 + 0.03 + 0.02 + 0.04, 0.0), (0.08, 0.08, 0.20))
    position = np.array([1.0, 0.0, TABLE + 0.10])
    across_x = check_grasp(position, 0.0, 0.06 + 0.05, target, neighbour, TABLE)
    assert not across_x.free and across_x.landing_hits > 0
    across_y = check_grasp(position, np.pi / 2, 0.10 + 0.05, target, neighbour, TABLE)
    assert across_y.free and across_y.closing_hits == 0
    # grasp planning takes the clear side
    alone = grasp_target(_segment(target))
    assert abs(np.cos(alone.yaw)) == pytest.approx(1.0, abs=1e-6)  # narrow side: along x
    crowded = grasp_target(_segment(target), neighbour)
    assert crowded.free
    assert abs(np.sin(crowded.yaw)) == pytest.approx(1.0, abs=1e-6)  # turned to close along y
    # with the neighbour on both sides nothing is free, and that is reported
    boxed = np.vstack([neighbour, _box((1.0, 0.13), (0.08, 0.08, 0.20))])
    assert not grasp_target(_segment(target), boxed).free


def test_an_object_between_the_pads_blocks_the_grasp() -> None:
    target = _box((1.0, 0.0), (0.05, 0.05, 0.20))
    small = _box((1.0 + 0.045, 0.0), (0.02, 0.02, 0.15))  # inside the open jaws, beside it
    check = check_grasp(np.array([1.0, 0.0, TABLE + 0.1]), 0.0, 0.15, target, small, TABLE)
    assert not check.free and check.closing_hits > 0


def test_a_tall_neighbour_under_the_palm_blocks_a_short_target() -> None:
    """A 9 cm bowl-like cylinder (r 8.5 cm) with a 23 cm bottle 5.5 cm beyond its rim: closing
    along x keeps the fingers clear of the bottle but puts the 27 cm palm onto its top (the
    descent would stop with the pads over the rim); closing along y turns the palm away."""
    bowl = _cylinder((1.0, 0.0), 0.085, 0.09)
    bottle = _cylinder((1.0 + 0.085 + 0.055 + 0.04, 0.0), 0.04, 0.23)
    position = np.array([1.0, 0.0, TABLE + 0.09 - 0.025 + 0.02])
    along_x = check_grasp(position, 0.0, 0.21, bowl, bottle, TABLE)
    assert along_x.landing_hits == 0 and along_x.closing_hits == 0
    assert along_x.palm_hits > 0 and not along_x.free
    assert check_grasp(position, np.pi / 2, 0.21, bowl, bottle, TABLE).free
    # a short neighbour there passes under the palm
    flat = _cylinder((1.0 + 0.085 + 0.055 + 0.04, 0.0), 0.04, 0.10)
    assert check_grasp(position, 0.0, 0.21, bowl, flat, TABLE).free
    # grasp planning turns the jaws
    grasp = grasp_target(_segment(bowl), bottle)
    assert grasp.free and abs(np.cos(grasp.yaw)) < 0.9


def _bowl_view(centre_xy, rim, height, seen=(-0.6 * np.pi, 0.6 * np.pi), step=0.003):
    """What the camera sees of a bowl: its rim ring over an arc ``seen`` (rad), the inside
    below it, and a few points of a neighbour's occlusion missing."""
    angles = np.arange(seen[0], seen[1], step / rim)
    ring = [(rim * np.cos(a), rim * np.sin(a), height - z) for a in angles for z in (0, 0.004)]
    inside = [
        (r * np.cos(a), r * np.sin(a), 0.01)
        for r in np.arange(0.0, rim - 0.02, 0.006)
        for a in np.linspace(0, 2 * np.pi, 24, endpoint=False)
    ]
    return np.vstack([ring, inside]) + np.array([centre_xy[0], centre_xy[1], TABLE])


def test_a_short_round_segment_is_centred_on_its_rim() -> None:
    """A 9 cm rim seen over 216 deg: the box of the points is off the bowl's axis by a
    couple of cm, the rim circle is not, and the grasp aims at the circle's centre."""
    bowl = _segment(_bowl_view((1.0, 0.0), 0.09, 0.08))
    centre, radius = rim_circle(bowl)
    np.testing.assert_allclose(centre, [1.0, 0.0], atol=2e-3)
    assert radius == pytest.approx(0.09, abs=3e-3)
    assert np.linalg.norm(bowl.box_center[:2] - [1.0, 0.0]) > 0.01  # the box is off
    assert np.linalg.norm(grasp_target(bowl).position[:2] - [1.0, 0.0]) < 2e-3
    # a flat top (a lying box) is no circle: no fit, the box's centre stays
    assert rim_circle(_segment(_box((1.0, 0.0), (0.10, 0.10, 0.08)))) is None


def test_points_below_the_finger_tips_do_not_block() -> None:
    """A flat neighbour (2 cm high) under where a finger lands on a tall object is passed."""
    target = _box((1.0, 0.0), (0.06, 0.06, 0.25))
    flat = _box((1.0 + 0.08, 0.0), (0.06, 0.08, 0.02))
    position = np.array([1.0, 0.0, TABLE + 0.125])  # tips at 0.125 - 0.055 = 7 cm
    assert check_grasp(position, 0.0, 0.11, target, flat, TABLE).free


def test_size_prior_says_which_segments_hold_more_than_one_object() -> None:
    envelopes = object_envelopes()
    assert len(envelopes) > 10
    assert fits_one_object(_segment(_cylinder((1.0, 0.0), 0.04, 0.23)), envelopes)
    pair = np.vstack([_cylinder((1.0, 0.0), 0.04, 0.23), _cylinder((1.08, 0.0), 0.04, 0.23)])
    assert not fits_one_object(_segment(pair), envelopes)  # 16 x 8 x 23 cm: no object
    with pytest.raises(PerceptionError, match="at least one"):
        fits_one_object(_segment(pair), ())
    with pytest.raises(PerceptionError, match="long >= short"):
        ObjectEnvelope(0.05, 0.1, 0.1)


def test_a_merged_two_object_segment_is_split_into_graspable_parts() -> None:
    """A 23 cm bottle-like cylinder touching a 10 cm mug-like one: one Euclidean cluster, two
    parts after the split, each one object's points, and a grasp on the tall one that aims
    at its own centre instead of the pair's."""
    tall = _cylinder((1.0, 0.0), 0.04, 0.23)
    short = _cylinder((1.0 + 0.04 + 0.045, 0.0), 0.045, 0.10)
    merged = _segment(np.vstack([tall, short]))
    owner = np.r_[np.zeros(len(tall), int), np.ones(len(short), int)]
    parts = split_segment(merged, (UP, OFFSET), object_envelopes())
    assert len(parts) == 2
    for part in parts:
        share = np.bincount(owner[part.pixels], minlength=2) / len(part.pixels)
        assert share.max() > 0.95
        assert fits_one_object(part, object_envelopes())
    assert sum(len(p.points) for p in parts) == len(merged.points)  # no point lost
    tall_part = max(parts, key=lambda p: p.height)
    assert np.linalg.norm(tall_part.box_center[:2] - [1.0, 0.0]) < 0.01
    grasp = grasp_target(tall_part, short)
    assert np.linalg.norm(grasp.position[:2] - [1.0, 0.0]) < 0.01
    # a segment that fits one object is kept whole
    single = _segment(tall)
    assert split_merged([single], (UP, OFFSET), object_envelopes()) == (single,)


def test_splitting_halves_the_merged_segments_of_a_cluttered_view() -> None:
    """On real cluttered Sorting-v2 views, segments holding more than one object (more than
    10 % of the pixels of a second one, by the ground-truth mask) become at least 40 % fewer,
    and the object count stays close to what is visible."""
    import gymnasium as gym

    import ipbench.envs  # noqa: F401
    from ipbench.perception.cloud import depth_to_points
    from ipbench.perception.segmentation import segment_scene

    def merged(segments, mask) -> int:
        n = 0
        for s in segments:
            ids = mask[s.pixels]
            ids = ids[ids >= 0]
            n += ids.size > 0 and int((np.bincount(ids) > 0.1 * ids.size).sum()) > 1
        return n

    before = after = parts = visible = 0
    with gym.make("ipbench/Sorting-v2", scene="cluttered", cameras=("wrist",)) as env:
        for seed in (3, 4, 5):
            obs, info = env.reset(seed=seed)
            mask = info["wrist_mask"].reshape(-1)
            found = segment_scene(
                depth_to_points(obs["wrist_depth"], obs["wrist_K"], obs["wrist_pose"])
            )
            split = split_merged(found.segments, found.plane, object_envelopes())
            before += merged(found.segments, mask)
            after += merged(split, mask)
            parts += len(split)
            visible += len(np.unique(mask[mask >= 0]))
    assert before >= 3 and after <= 0.6 * before
    assert parts <= 1.15 * visible


def test_a_pile_too_long_for_one_segment_is_kept_aside_and_split() -> None:
    """Five touching 10 cm boxes in a row (50 cm: over the 40 cm size rule) are no segment
    but one ``oversized`` cluster, which the split cuts into graspable parts."""
    from ipbench.perception.cloud import Cloud
    from ipbench.perception.segmentation import segment_scene

    xs, ys = np.meshgrid(np.arange(0.6, 1.3, 0.004), np.arange(-0.5, 0.3, 0.004))
    table = np.column_stack([xs.ravel(), ys.ravel(), np.full(xs.size, TABLE)])
    heights = (0.20, 0.12, 0.22, 0.10, 0.18)
    boxes = [_box((0.75 + 0.1 * k, 0.0), (0.1, 0.08, h)) for k, h in enumerate(heights)]
    points = np.vstack([table, *boxes])
    cloud = Cloud(points, np.arange(len(points)), (1, len(points)), np.array([0.5, 0.0, 1.5]))
    found = segment_scene(cloud)
    assert found.segments == () and len(found.oversized) == 1
    parts = split_merged(found.oversized, found.plane, object_envelopes())
    assert len(parts) >= 4 and all(fits_one_object(p, object_envelopes()) for p in parts)
