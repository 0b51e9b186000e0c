"""Semantic visualisation: projection, detection overlay, wrist insets, video recording."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import gymnasium as gym
import imageio.v2 as imageio
import numpy as np
import pytest

import ipbench.envs  # noqa: F401  (registers the environments)
from ipbench.assets.objects import CATEGORIES
from ipbench.envs.sensors import camera_pose, intrinsics
from ipbench.eval.sorting.overlay import (
    DetectionLike,
    SemanticRender,
    SemanticVideoRecorder,
    class_colors,
    compose_frame,
    overlay_detections,
    project_points,
)
from ipbench.policies.scripted import GroundTruthSorter

H, W = 480, 640
K = np.array([[500.0, 0.0, 319.5], [0.0, 500.0, 239.5], [0.0, 0.0, 1.0]])


@dataclass
class Det:
    points: np.ndarray
    label: str
    confidence: float
    inspected: bool = False


def _pose() -> np.ndarray:
    """A camera at (1, 2, 3), rotated 30 degrees about its world z then 20 about x."""
    a, b = np.radians(30), np.radians(20)
    rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    pose = np.eye(4)
    pose[:3, :3] = rz @ rx
    pose[:3, 3] = [1.0, 2.0, 3.0]
    return pose


def _world(pose: np.ndarray, cam_points) -> np.ndarray:
    """Camera-frame points (OpenCV convention) to the world frame."""
    return np.asarray(cam_points, float) @ pose[:3, :3].T + pose[:3, 3]


def _square(pose: np.ndarray, half: float = 0.04, z: float = 2.0, n: int = 15) -> np.ndarray:
    """A grid of n x n points, 2 half wide, centred on the optical axis at depth z."""
    g = np.linspace(-half, half, n)
    xy = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    return _world(pose, np.c_[xy, np.full(len(xy), z)])


def _ball(center, radius: float = 0.05, n: int = 400, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    d *= radius * rng.random((n, 1)) ** (1 / 3) / np.linalg.norm(d, axis=1, keepdims=True)
    return np.asarray(center, float) + d


# -- pure functions ------------------------------------------------------------------------------
def test_class_colors_distinct_per_category():
    colors = class_colors()
    assert list(colors) == list(CATEGORIES)
    assert len(set(colors.values())) == len(CATEGORIES)
    assert all(len(c) == 3 and all(0 <= v <= 255 for v in c) for c in colors.values())
    assert colors["juice_bottle"] == (230, 159, 0)  # Okabe-Ito orange


def test_project_points_hand_computed():
    pose = _pose()
    points = _world(pose, [[0, 0, 2.0], [0.1, -0.2, 2.0], [0.3, 0.1, -1.0], [0, 0, 0]])
    uv, in_front = project_points(points, K, pose)
    np.testing.assert_allclose(uv[0], [319.5, 239.5], atol=1e-9)  # optical axis -> (cx, cy)
    np.testing.assert_allclose(uv[1], [319.5 + 500 * 0.05, 239.5 - 500 * 0.1], atol=1e-9)
    assert in_front.tolist() == [True, True, False, False]  # behind, and on the camera plane
    assert np.isnan(uv[2:]).all()
    # agrees with OpenCV's own projection
    cam_from_world = np.linalg.inv(pose)
    rvec, _ = cv2.Rodrigues(cam_from_world[:3, :3])
    ref, _ = cv2.projectPoints(points[:2], rvec, cam_from_world[:3, 3], K, None)
    np.testing.assert_allclose(uv[:2], ref.reshape(-1, 2), atol=1e-6)


def test_overlay_changes_only_near_detection_and_tints():
    pose = _pose()
    frame = np.full((H, W, 3), 100, np.uint8)
    before = frame.copy()
    det = Det(_square(pose), "bowl", 0.87)
    assert isinstance(det, DetectionLike)
    out = overlay_detections(frame, [det], K, pose, alpha=0.45)
    np.testing.assert_array_equal(frame, before)  # input untouched
    assert out.shape == frame.shape and out.dtype == np.uint8
    changed = (out != frame).any(axis=2)
    uv, _ = project_points(det.points, K, pose)
    (u0, v0), (u1, v1) = uv.min(axis=0), uv.max(axis=0)  # ~ 20 px either side of centre
    rows, cols = np.nonzero(changed)
    assert changed.sum() > (u1 - u0) * (v1 - v0) * 0.9  # a solid blob, not sparse dots
    # only the blob, its outline and the label box above it (label ~ 20 px high, 110 wide)
    assert rows.min() >= v0 - 40 and rows.max() <= v1 + 5
    assert cols.min() >= u0 - 60 and cols.max() <= u1 + 60
    # the tint at the blob centre: between the original grey and the class colour
    colour = np.array(class_colors()["bowl"])
    centre = out[240, 320].astype(int)
    lo, hi = np.minimum(100, colour), np.maximum(100, colour)
    assert np.all((lo <= centre) & (centre <= hi)) and np.any(centre != 100)
    np.testing.assert_allclose(centre, 0.55 * 100 + 0.45 * colour, atol=1)


def test_overlay_ignores_points_behind_or_outside():
    pose = _pose()
    frame = np.full((H, W, 3), 100, np.uint8)
    behind = Det(_world(pose, _square(np.eye(4), z=-2.0)), "mug", 0.5)
    outside = Det(_world(pose, _square(np.eye(4)) + [5.0, 0, 0]), "mug", 0.5)  # u ~ 1570
    empty = Det(np.zeros((0, 3)), "mug", 0.5)
    out = overlay_detections(frame, [behind, outside, empty], K, pose)
    np.testing.assert_array_equal(out, frame)
    # half in front, half behind: only the front half is drawn, without error
    mixed = Det(np.r_[_square(pose), behind.points], "mug", 0.5)
    assert (overlay_detections(frame, [mixed], K, pose) != frame).any()


def test_overlay_marks_inspected_and_unknown_labels():
    pose = _pose()
    frame = np.full((H, W, 3), 100, np.uint8)
    plain = overlay_detections(frame, [Det(_square(pose), "mug", 0.9)], K, pose)
    inspected = overlay_detections(frame, [Det(_square(pose), "mug", 0.9, True)], K, pose)
    assert (plain != inspected).any()
    other = overlay_detections(frame, [Det(_square(pose), "teapot", 0.9)], K, pose)
    assert other[240, 320, 0] == other[240, 320, 1] == other[240, 320, 2]  # grey tint


def test_compose_frame_insets_in_corner():
    overview = np.zeros((H, W, 3), np.uint8)
    wrist = np.full((480, 640, 3), 200, np.uint8)
    depth = np.tile(np.linspace(0.3, 1.5, 640, dtype=np.float32), (480, 1))
    depth[:, :200] = 0  # a hole on the left
    out = compose_frame(overview, wrist, depth, inset_scale=0.25)
    assert out.shape == overview.shape and out.dtype == np.uint8
    assert not overview.any()  # input untouched
    # the wrist image (160 x 120 px) in the top-right corner, depth under it
    filled = out.any(axis=2)
    rows, cols = np.nonzero(filled)
    assert cols.min() >= W - 160 - 20 and rows.max() <= 2 * 120 + 30
    np.testing.assert_array_equal(out[20, W - 20], [200, 200, 200])
    depth_rows = rows[rows > 130]
    mid = (depth_rows.min() + depth_rows.max()) // 2
    assert out[mid, W - 15].any()  # far depth: coloured
    assert not out[mid, W - 160 + 5].any()  # hole: black
    assert not out[H // 2 :, : W // 2].any()  # the rest untouched
    # only wrist RGB; none; odd sizes come out even
    assert compose_frame(overview, wrist).shape == overview.shape
    np.testing.assert_array_equal(compose_frame(overview), overview)
    assert compose_frame(np.zeros((481, 641, 3), np.uint8), wrist).shape == (482, 642, 3)


def _pile(n: int = 15) -> list[Det]:
    """``n`` balls 3 cm in radius, 7 cm apart (~17 px at 2 m) in rows of 5 at the image centre."""
    return [
        Det(
            _ball([-0.14 + 0.07 * (k % 5), -0.07 + 0.07 * (k // 5), 2.0], 0.03, 300, k),
            CATEGORIES[k % len(CATEGORIES)],
            0.5 + k / 40,
            inspected=k % 4 == 0,
        )
        for k in range(n)
    ]


def _label_boxes(out: np.ndarray) -> list[tuple[int, int, int, int]]:
    """(x, y, w, h) of each label's dark background (nothing else in these frames is as dark;
    the holes of letters, a few pixels high, are left out)."""
    dark = np.all(out == (24, 24, 24), axis=2).astype(np.uint8)
    n, _, stats, _ = cv2.connectedComponentsWithStats(dark, connectivity=4)
    return [tuple(int(v) for v in s[:4]) for s in stats[1:n] if s[3] > 10]


def test_labels_of_a_pile_neither_overlap_nor_cover_the_objects():
    dets = _pile()
    frame = np.full((H, W, 3), 100, np.uint8)
    out = overlay_detections(frame, dets, K, np.eye(4))
    boxes = _label_boxes(out)
    # one whole background per label: a label covering another would cut or merge them
    assert len(boxes) == len(dets)
    heights = {h for _, _, _, h in boxes}
    assert len(heights) == 1  # every label whole (all texts are as high)
    expected = sorted(
        cv2.getTextSize(
            f"{d.label} {d.confidence:.2f}" + (" *" if d.inspected else ""),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.42,
            1,
        )[0][0]
        + 2
        for d in dets
    )
    assert sorted(w for _, _, w, _ in boxes) == expected
    for a, (x, y, w, h) in enumerate(boxes):  # apart, borders (1 px) included
        for xb, yb, wb, hb in boxes[a + 1 :]:
            assert (
                x + w + 1 < xb - 1
                or xb + wb + 1 < x - 1
                or y + h + 1 < yb - 1
                or yb + hb + 1 < y - 1
            )
    # no label (border included) on any pixel an object projects to
    covered = np.zeros((H, W), bool)
    for x, y, w, h in boxes:
        covered[y - 1 : y + h + 1, x - 1 : x + w + 1] = True
    for det in dets:
        uv, _ = project_points(det.points, K, np.eye(4))
        cols, rows = np.rint(uv).astype(int).T
        assert not covered[rows, cols].any(), det.label


def test_labels_stay_off_keep_clear_boxes():
    dets = _pile()
    frame = np.full((H, W, 3), 100, np.uint8)
    clear = (0, 239, 0, W - 1)  # the whole upper half
    out = overlay_detections(frame, dets, K, np.eye(4), keep_clear=[clear])
    boxes = _label_boxes(out)
    assert len(boxes) == len(dets)
    assert all(y - 1 > clear[1] for _, y, _, _ in boxes)


# -- with the real environment ------------------------------------------------------------------
def _make_env():
    return gym.make("ipbench/Sorting-v1", scene="uncluttered", render_mode="rgb_array")


@pytest.fixture(scope="module")
def env():
    env = _make_env()
    yield env
    env.close()


def _overview_camera(env, frame):
    u = env.unwrapped
    return intrinsics(u.model, "overview", frame.shape[1], frame.shape[0]).K, camera_pose(
        u.model, u.data, "overview"
    )


def _first_object_detection(info) -> Det:
    obj = info["objects"][0]
    return Det(_ball(obj["center"]), obj["category"], 0.87)


def test_overlay_on_real_object(env):
    obs, info = env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (480, 640, 3)
    k_mat, pose = _overview_camera(env, frame)
    det = _first_object_detection(info)
    uv, in_front = project_points(det.points, k_mat, pose)
    assert in_front.all()
    assert ((uv >= 0) & (uv < [640, 480])).all()  # the whole ball is in view
    out = overlay_detections(frame, [det], k_mat, pose)
    c_uv, _ = project_points(info["objects"][0]["center"][None], k_mat, pose)
    u, v = np.rint(c_uv[0]).astype(int)
    assert (out[v - 1 : v + 2, u - 1 : u + 2] != frame[v - 1 : v + 2, u - 1 : u + 2]).any()
    changed = (out != frame).any(axis=2)
    assert not changed[:, :100].any() and not changed[-100:].any()  # far away: untouched


def test_semantic_render_wrapper(env):
    dets: list[Det] = []
    wrapped = SemanticRender(env, detections_fn=lambda: dets)
    obs, info = wrapped.reset(seed=0)
    plain = env.render()
    bare = wrapped.render()  # no detections: only the insets
    np.testing.assert_array_equal(bare, compose_frame(plain, obs["wrist_rgb"], obs["wrist_depth"]))
    dets.append(_first_object_detection(info))
    frame = wrapped.render()
    assert frame.shape == (480, 640, 3)
    assert (frame != bare).any() and (frame[:, :100] == bare[:, :100]).all()
    assert SemanticRender(env).render().shape == (480, 640, 3)  # detections_fn None


def test_semantic_video_recorder(env, tmp_path):
    # last test on the shared env: its frame listener stays subscribed
    recorder = SemanticVideoRecorder(env, fps=5)
    obs, info = env.reset(seed=0)
    n_reset = len(recorder.frames)  # captured while the objects settle
    dets = [_first_object_detection(info)]
    recorder.update(obs, dets)
    assert len(recorder.frames) == n_reset + 1
    after_update = recorder.frames[-1]
    assert (after_update != env.render()).any()  # overlay and insets drawn
    action = GroundTruthSorter().act(obs, info)
    obs, _, _, _, info = env.step(action)
    n_step = len(recorder.frames)
    assert n_step > n_reset + 1  # frames while the skills ran
    recorder.update(obs, [])
    path = recorder.save(tmp_path / "x.mp4")
    assert path == tmp_path / "x.mp4" and path.stat().st_size > 0
    with imageio.get_reader(path) as reader:
        frames = list(reader.iter_data())
    assert len(frames) == len(recorder.frames)
    assert all(f.shape == (480, 640, 3) for f in frames)


def test_record_video_with_semantic_render(tmp_path):
    pytest.importorskip("moviepy")
    from gymnasium.wrappers import RecordVideo

    env = _make_env()
    dets: list[Det] = []
    wrapped = RecordVideo(
        SemanticRender(env, detections_fn=lambda: dets),
        video_folder=str(tmp_path / "videos"),
        episode_trigger=lambda e: True,
        fps=5,
    )
    _, info = wrapped.reset(seed=0)
    dets.append(_first_object_detection(info))
    wrapped.reset(seed=0)  # the same scene, now with the detection; writes episode 0
    wrapped.close()  # writes episode 1 (one frame each: the reset)
    videos = sorted((tmp_path / "videos").glob("*.mp4"))
    assert len(videos) == 2
    first, second = (imageio.get_reader(v).get_data(0) for v in videos)
    assert first.shape == second.shape == (480, 640, 3)
    assert np.abs(first.astype(int) - second.astype(int)).sum(axis=2).max() > 60  # overlay
