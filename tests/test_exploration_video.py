"""The exploration video: annotated frames, the MP4 read back, inputs left untouched."""

from __future__ import annotations

import imageio.v2 as imageio
import numpy as np
import pytest

from ipbench.eval.exploration.video import (
    ExplorationVideoError,
    ExplorationVideoRecorder,
    draw_frame,
)

H, W = 680, 1024  # the head's image size


def _image(value: int = 0) -> np.ndarray:
    return np.full((H, W, 3), value, np.uint8)


OUTLINE = np.array([[100.0, 100.0], [300.0, 100.0], [300.0, 260.0], [100.0, 260.0]])


def test_recorder_writes_a_readable_mp4(tmp_path):
    rng = np.random.default_rng(0)
    recorder = ExplorationVideoRecorder(fps=5)
    images = [rng.integers(0, 256, (H, W, 3), dtype=np.uint8) for _ in range(3)]
    originals = [im.copy() for im in images]
    for k, image in enumerate(images):
        recorder.add(
            image,
            [("cereal_box", OUTLINE + 20 * k, True), ("tea", OUTLINE + 400, False)],
            np.array([511.5, 339.5]),
            [np.array([700.0, 500.0]), np.array([200.0, 600.0])],
            [("cereal_box", np.array([200.0, 180.0]))] if k else [],
        )
    for image, original in zip(images, originals, strict=True):
        np.testing.assert_array_equal(image, original)  # drawing works on copies
    path = recorder.save(tmp_path / "videos" / "x.mp4")
    assert path == tmp_path / "videos" / "x.mp4" and path.stat().st_size > 0
    with imageio.get_reader(path) as reader:
        frames = list(reader.iter_data())
    assert len(frames) == 3
    assert all(f.shape == (424, 640, 3) for f in frames)  # 1024 x 680 -> 640 wide, /8


def test_overlay_marks_fixation_discs_and_outlines():
    black = _image(0)
    frame = draw_frame(
        black,
        [("cereal_box", OUTLINE, True)],
        np.array([512.0, 340.0]),
        [np.array([800.0, 500.0])],
        [],
        step=3,
    )
    assert frame.shape == (424, 640, 3) and frame.dtype == np.uint8
    assert not black.any()  # the input stays black
    sx, sy = 640 / W, 424 / H
    # the fixation cross is white at its centre
    assert (frame[round(340 * sy), round(512 * sx)] > 200).all()
    # an inhibited disc is translucent grey: 0.35 * 200 over black
    disc = frame[round(500 * sy), round(800 * sx)]
    assert 60 <= int(disc[0]) <= 80 and disc[0] == disc[1] == disc[2]
    # a verified outline is drawn in green on its left edge, the inside is left alone
    edge = frame[round(200 * sy), round(100 * sx)]
    assert edge[1] > 100 and edge[1] > edge[0]
    assert not frame[round(200 * sy), round(200 * sx)].any()


def test_small_frames_are_not_upscaled():
    frame = draw_frame(_image(50)[:120, :200], [], None, [], [], step=0)
    assert frame.shape == (120, 200, 3)


def test_bad_inputs_raise_clear_errors(tmp_path):
    recorder = ExplorationVideoRecorder()
    with pytest.raises(ExplorationVideoError, match="no frames to save"):
        recorder.save(tmp_path / "x.mp4")
    with pytest.raises(ExplorationVideoError, match=r"\(H, W, 3\) uint8"):
        recorder.add(np.zeros((H, W, 3)), [], None, [], [])
    with pytest.raises(ExplorationVideoError, match=r"outline must be a finite \(4, 2\)"):
        recorder.add(_image(), [("tea", OUTLINE[:3], True)], None, [], [])
    with pytest.raises(ExplorationVideoError, match="fixation_xy must be a finite image point"):
        recorder.add(_image(), [], np.array([1.0, 2.0, 3.0]), [], [])
    recorder.add(_image(), [], None, [], [])
    with pytest.raises(ExplorationVideoError, match="feed images of one size"):
        recorder.add(_image()[:340, :512], [], None, [], [])
    with pytest.raises(ExplorationVideoError, match="fps must be > 0"):
        ExplorationVideoRecorder(fps=0)
