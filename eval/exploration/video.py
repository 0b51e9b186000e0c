"""The exploration video: the left head view with what the active-vision loop sees and does.

Each frame (one per saccade) is the left head camera's image with, drawn by OpenCV on a copy:

* recognition hypotheses: their (4, 2) outline, green when the stereo pairing verified it,
  amber when not, with a short class label on a dark backing;
* places already reported: a sky-blue dot labelled with the reported class;
* inhibited directions (inhibition of return): translucent grey discs of the inhibition
  radius (4 deg, :data:`~ipbench.perception.saliency.INHIBITION_RADIUS_RAD`) at the head
  camera's focal length (its vertical field of view, ``fovy="25.1"`` in
  ``assets/head/ptu_d46.xml``);
* the fixation point: a white cross;
* a step counter in the top-left corner.

Frames are downscaled to at most ``max_width`` px wide (640 by default: a 1024 x 680 head
image becomes 640 x 424) and their sides rounded to multiples of 8 for the H.264 encoder, so
a few frames per episode stay small. :meth:`ExplorationVideoRecorder.save` writes the MP4
through :func:`ipbench.eval.video.write_mp4`. Colours are from the Okabe-Ito palette.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from ipbench.eval.video import write_mp4
from ipbench.perception.saliency import INHIBITION_RADIUS_RAD

__all__ = ["HEAD_FOVY_DEG", "ExplorationVideoError", "ExplorationVideoRecorder", "draw_frame"]

HEAD_FOVY_DEG = 25.1
"""Vertical field of view of a head camera, deg (``assets/head/ptu_d46.xml``)."""
_VERIFIED = (0, 158, 115)  # bluish green (RGB)
_UNVERIFIED = (230, 159, 0)  # orange
_REPORTED = (86, 180, 233)  # sky blue
_INHIBITED = (200, 200, 200)
_INHIBITED_ALPHA = 0.35
_FIXATION = (255, 255, 255)
_TEXT_BG = (24, 24, 24)
_TEXT_FG = (255, 255, 255)
_FONT = cv2.FONT_HERSHEY_SIMPLEX
_MACRO_BLOCK = 8


class ExplorationVideoError(ValueError):
    """A bad frame or overlay input; the message says what shape or type is expected."""


def _size(height: int, width: int, max_width: int) -> tuple[int, int]:
    """Output (height, width): scaled to at most ``max_width`` wide, multiples of 8."""
    scale = min(1.0, max_width / width)
    return (
        max(_MACRO_BLOCK, _MACRO_BLOCK * round(height * scale / _MACRO_BLOCK)),
        max(_MACRO_BLOCK, _MACRO_BLOCK * round(width * scale / _MACRO_BLOCK)),
    )


def _point(xy: object, what: str) -> np.ndarray:
    p = np.asarray(xy, float)
    if p.shape != (2,) or not np.isfinite(p).all():
        raise ExplorationVideoError(f"{what} must be a finite image point (x, y) px, got {xy!r}")
    return p


def _label(img: np.ndarray, text: str, org: tuple[int, int], colour: tuple[int, ...]) -> None:
    """``text`` at ``org`` (bottom-left) on a dark box, a colour tab on its left; kept inside."""
    scale, thick = 0.4, 1
    (tw, th), base = cv2.getTextSize(text, _FONT, scale, thick)
    h, w = img.shape[:2]
    x = int(np.clip(org[0], 0, max(0, w - tw - 6)))
    y = int(np.clip(org[1], th + 3, h - base - 2))
    cv2.rectangle(img, (x, y - th - 3), (x + tw + 6, y + base + 1), _TEXT_BG, cv2.FILLED)
    cv2.rectangle(img, (x, y - th - 3), (x + 2, y + base + 1), colour, cv2.FILLED)
    cv2.putText(img, text, (x + 4, y), _FONT, scale, _TEXT_FG, thick, cv2.LINE_AA)


def draw_frame(
    left_image: np.ndarray,
    hypotheses: Sequence[tuple[str, np.ndarray, bool]],
    fixation_xy: np.ndarray | None,
    inhibited_xy: Sequence[np.ndarray],
    reported: Sequence[tuple[str, np.ndarray]],
    step: int,
    max_width: int = 640,
) -> np.ndarray:
    """One annotated, downscaled frame (a new array; ``left_image`` is not modified).

    Parameters
    ----------
    left_image : (H, W, 3) uint8 RGB left head image.
    hypotheses : ``(label, outline, verified)``: class name, (4, 2) outline corners in
        ``left_image`` px, whether stereo pairing verified it.
    fixation_xy : (2,) fixated image point, px, or None.
    inhibited_xy : (2,) image points of inhibited directions, px.
    reported : ``(label, xy)``: reported classes and their (2,) image points, px.
    step : the counter shown in the corner.
    max_width : frames wider than this are downscaled to it (px).

    Returns
    -------
    (h, w, 3) uint8 RGB, ``w <= max(max_width, 8)`` rounded to a multiple of 8, as ``h``.
    """
    img = np.asarray(left_image)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise ExplorationVideoError(
            f"left_image must be an (H, W, 3) uint8 RGB image, got {img.shape} {img.dtype}"
        )
    H, W = img.shape[:2]
    h, w = _size(H, W, max_width)
    sx, sy = w / W, h / H
    frame = cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA) if (h, w) != (H, W) else img
    frame = np.array(frame, copy=True)  # never draw on the caller's image

    def px(p: np.ndarray) -> tuple[int, int]:
        return int(round(p[0] * sx)), int(round(p[1] * sy))

    if len(inhibited_xy):
        focal = (H / 2) / math.tan(math.radians(HEAD_FOVY_DEG) / 2)  # px of left_image
        radius = max(1, int(round(focal * math.tan(INHIBITION_RADIUS_RAD) * sy)))
        discs = frame.copy()
        for i, xy in enumerate(inhibited_xy):
            cv2.circle(discs, px(_point(xy, f"inhibited_xy[{i}]")), radius, _INHIBITED, -1)
        cv2.addWeighted(discs, _INHIBITED_ALPHA, frame, 1 - _INHIBITED_ALPHA, 0, dst=frame)
    for i, hyp in enumerate(hypotheses):
        if len(hyp) != 3:
            raise ExplorationVideoError(
                f"hypotheses[{i}] must be (label, outline (4, 2) px, verified), got {hyp!r}"
            )
        label, outline, verified = hyp
        corners = np.asarray(outline, float)
        if corners.shape != (4, 2) or not np.isfinite(corners).all():
            raise ExplorationVideoError(
                f"hypotheses[{i}] outline must be a finite (4, 2) array of corners (px), got "
                f"shape {corners.shape}"
            )
        pts = np.round(corners * (sx, sy)).astype(np.int32)
        colour = _VERIFIED if verified else _UNVERIFIED
        cv2.polylines(frame, [pts], True, colour, 2 if verified else 1, cv2.LINE_AA)
        top = pts[np.argmin(pts[:, 1])]
        _label(frame, str(label)[:14] + (" ok" if verified else " ?"), (top[0], top[1] - 4), colour)
    for i, rep in enumerate(reported):
        if len(rep) != 2:
            raise ExplorationVideoError(f"reported[{i}] must be (label, xy (2,) px), got {rep!r}")
        x, y = px(_point(rep[1], f"reported[{i}] xy"))
        cv2.circle(frame, (x, y), 5, _REPORTED, -1, cv2.LINE_AA)
        cv2.circle(frame, (x, y), 5, _TEXT_BG, 1, cv2.LINE_AA)
        _label(frame, str(rep[0])[:14], (x + 7, y + 4), _REPORTED)
    if fixation_xy is not None:
        x, y = px(_point(fixation_xy, "fixation_xy"))
        for colour, thick in ((_TEXT_BG, 3), (_FIXATION, 1)):
            cv2.drawMarker(frame, (x, y), colour, cv2.MARKER_CROSS, 18, thick, cv2.LINE_AA)
    _label(frame, f"step {step}", (4, 16), _FIXATION)
    return frame


class ExplorationVideoRecorder:
    """Collects annotated left-head frames (:func:`draw_frame`), one per :meth:`add`.

    Parameters
    ----------
    fps : frames per second of the MP4 (a frame is a saccade, not a fixed time step).
    max_width : frames are downscaled to at most this width, px.
    """

    def __init__(self, fps: float = 5.0, max_width: int = 640) -> None:
        if not fps > 0:
            raise ExplorationVideoError(f"fps must be > 0, got {fps!r}")
        if not (isinstance(max_width, int) and max_width >= 8):
            raise ExplorationVideoError(f"max_width must be an int >= 8 px, got {max_width!r}")
        self.fps, self.max_width = float(fps), max_width
        self.frames: list[np.ndarray] = []

    def add(
        self,
        left_image: np.ndarray,
        hypotheses: Sequence[tuple[str, np.ndarray, bool]],
        fixation_xy: np.ndarray | None,
        inhibited_xy: Sequence[np.ndarray],
        reported: Sequence[tuple[str, np.ndarray]],
    ) -> np.ndarray:
        """Draw and keep one frame (arguments as :func:`draw_frame`); returns it.

        Raises
        ------
        ExplorationVideoError
            On bad inputs, or a frame whose size differs from the first one's (one MP4 has
            one frame size).
        """
        frame = draw_frame(
            left_image,
            hypotheses,
            fixation_xy,
            inhibited_xy,
            reported,
            step=len(self.frames),
            max_width=self.max_width,
        )
        if self.frames and frame.shape != self.frames[0].shape:
            raise ExplorationVideoError(
                f"frame {len(self.frames)} is {frame.shape[1]}x{frame.shape[0]} px after "
                f"scaling, the first was {self.frames[0].shape[1]}x{self.frames[0].shape[0]}: "
                "feed images of one size"
            )
        self.frames.append(frame)
        return frame

    def save(self, path: str | Path) -> Path:
        """Write the frames as an H.264 MP4 at ``path`` (folders created); returns it."""
        if not self.frames:
            raise ExplorationVideoError("no frames to save: call add() at least once")
        return write_mp4(path, self.frames, self.fps)
