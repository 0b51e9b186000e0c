"""Semantic visualisation for videos: detections drawn over the overview camera's frames.

It mimics the thesis' semantic visualisation (ch. 5/6, the figures of segmented scenes): each
object a policy has perceived is tinted with the colour of its predicted class, outlined and
labelled ``"<class> <confidence>"``; objects the policy has inspected are marked with ``*``
and a white-edged outline. A label sits above (or below) its object; where that would cover
another object or label, as over a cluttered pile, it goes to the nearest free place around
the object, with a leader line to it, so labels neither overlap nor hide the pile. The
wrist camera's colour image and a colour-mapped depth image are inset in the top-right corner
(labels keep off them).

* :func:`overlay_detections` draws detections (anything matching :class:`DetectionLike`:
  world-frame points, a label and a confidence) on a frame, given the camera's intrinsics and
  world-from-camera pose (OpenCV convention: x right, y down, z forward).
* :func:`compose_frame` adds the wrist insets.
* :class:`SemanticVideoRecorder` records an episode's video like
  :class:`~ipbench.eval.video.VideoRecorder`, with the detections of the policy; the
  evaluation calls :meth:`SemanticVideoRecorder.update` after each step.
* :class:`SemanticRender` is a Gymnasium wrapper whose ``render()`` returns the composed
  frame (for ``gymnasium.wrappers.RecordVideo`` and the like).

Regions: a detection's points are projected into the image, rasterised into a mask, closed
with a disk whose radius follows the projected point spacing (so sparse points become a
solid blob; holes inside are filled) and dilated by one pixel. Frames are RGB (H, W, 3)
uint8, as ``SortingEnv.render()`` returns them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import cv2
import gymnasium as gym
import numpy as np

from ipbench.assets.objects import CATEGORIES
from ipbench.envs.sensors import camera_pose, intrinsics
from ipbench.eval.sorting.labels import Box, draw_labels
from ipbench.eval.video import VideoRecorder

__all__ = [
    "DetectionLike",
    "SemanticRender",
    "SemanticVideoRecorder",
    "class_colors",
    "compose_frame",
    "overlay_detections",
    "project_points",
]

OKABE_ITO = {
    "orange": (230, 159, 0),
    "sky_blue": (86, 180, 233),
    "bluish_green": (0, 158, 115),
    "yellow": (240, 228, 66),
    "blue": (0, 114, 178),
    "vermillion": (213, 94, 0),
    "reddish_purple": (204, 121, 167),
}
"""The Okabe-Ito colour-blind-friendly palette (Okabe & Ito 2008), RGB 0-255."""
_CLASS_COLOURS = dict(
    zip(
        CATEGORIES,  # juice_bottle, milk_carton, bowl, mug, juice_box
        ("orange", "sky_blue", "bluish_green", "vermillion", "reddish_purple"),
        strict=True,
    )
)
UNKNOWN_COLOR = (153, 153, 153)
"""RGB colour of labels that are not a category (grey)."""
_NEAR = 1e-6  # m: points closer to the camera plane than this count as behind it


@runtime_checkable
class DetectionLike(Protocol):
    """What the overlay needs of a detection (e.g. a policy's segmented, classified object).

    Attributes
    ----------
    points : (N, 3) float, the object's points in the world frame (m).
    label : the predicted class, a category name (others are drawn grey).
    confidence : the predicted class' probability, in [0, 1].
    inspected : optional bool; ``True`` marks objects the policy has inspected (a ``*`` after
        the label and a white-edged outline). Missing counts as ``False``.
    """

    @property
    def points(self) -> np.ndarray: ...

    @property
    def label(self) -> str: ...

    @property
    def confidence(self) -> float: ...


def class_colors() -> dict[str, tuple[int, int, int]]:
    """RGB colour (0-255) of each category, from the Okabe-Ito colour-blind-friendly palette.

    ``juice_bottle`` orange (230, 159, 0), ``milk_carton`` sky blue (86, 180, 233), ``bowl``
    bluish green (0, 158, 115), ``mug`` vermillion (213, 94, 0), ``juice_box`` reddish purple
    (204, 121, 167). Labels that are not a category are drawn in grey (153, 153, 153).

    Returns
    -------
    dict
        Category name -> (r, g, b), in bin order (a new dict on each call).
    """
    return {category: OKABE_ITO[name] for category, name in _CLASS_COLOURS.items()}


def project_points(
    points: np.ndarray, K: np.ndarray, world_from_camera: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Pinhole projection of world points into an image (OpenCV convention).

    A camera-frame point (x, y, z) (x right, y down, z forward) lands at pixel
    ``(u, v) = (K @ (x, y, z))[:2] / z``, ``u`` the column and ``v`` the row, pixel centres at
    integer coordinates (as :class:`~ipbench.envs.sensors.CameraIntrinsics`).

    Parameters
    ----------
    points : (N, 3) float, world frame (m).
    K : (3, 3) float, camera matrix (px).
    world_from_camera : (4, 4) float, the camera's pose (m), OpenCV convention.

    Returns
    -------
    uv : (N, 2) float64
        Pixel coordinates (u, v); NaN for points not in front of the camera.
    in_front : (N,) bool
        The point is finite and in front of the camera (z > 1e-6 m). Points in front may
        still fall outside the image.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    pose = np.asarray(world_from_camera, dtype=np.float64)
    rot, t = pose[:3, :3], pose[:3, 3]
    cam = (pts - t) @ rot  # R^T (p - t), row-wise
    in_front = np.isfinite(cam).all(axis=1) & (cam[:, 2] > _NEAR)
    uv = np.full((len(pts), 2), np.nan)
    if in_front.any():
        pix = cam[in_front] @ np.asarray(K, dtype=np.float64).T
        uv[in_front] = pix[:, :2] / pix[:, 2:3]
    return uv, in_front


def _region_mask(uv: np.ndarray, height: int, width: int) -> tuple[np.ndarray, tuple] | None:
    """Solid mask of projected points: (mask of the ROI, (row0, row1, col0, col1)) or None."""
    uv = uv[np.isfinite(uv).all(axis=1)]
    cols, rows = np.rint(uv[:, 0]), np.rint(uv[:, 1])
    inside = (cols >= 0) & (cols < width) & (rows >= 0) & (rows < height)
    if not inside.any():
        return None
    px = np.unique(np.stack([cols[inside], rows[inside]], axis=1).astype(np.int32), axis=0)
    # Closing radius: about the mean spacing of the points over their convex hull, so gaps
    # up to ~4x the mean nearest-neighbour distance close; clipped to 2-4% of the image.
    area = cv2.contourArea(cv2.convexHull(px)) if len(px) >= 3 else 0.0
    r_max = max(2, round(0.04 * max(height, width)))
    radius = int(np.clip(math.ceil(math.sqrt(area / len(px))), 2, r_max))
    pad = radius + 2
    c0, r0 = max(px[:, 0].min() - pad, 0), max(px[:, 1].min() - pad, 0)
    c1, r1 = min(px[:, 0].max() + pad + 1, width), min(px[:, 1].max() + pad + 1, height)
    mask = np.zeros((r1 - r0, c1 - c0), np.uint8)
    mask[px[:, 1] - r0, px[:, 0] - c0] = 255
    disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
    mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, disk)
    mask = cv2.dilate(mask, np.ones((3, 3), np.uint8))
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    cv2.drawContours(mask, contours, -1, 255, cv2.FILLED)  # fill holes
    return mask, (r0, r1, c0, c1)


def overlay_detections(
    frame: np.ndarray,
    detections: Iterable[DetectionLike],
    K: np.ndarray,
    world_from_camera: np.ndarray,
    alpha: float = 0.45,
    keep_clear: Sequence[Box] = (),
) -> np.ndarray:
    """A copy of ``frame`` with each detection tinted by its class colour, outlined, labelled.

    Each detection's points are projected (:func:`project_points`), rasterised and closed
    into a solid region (see the module docstring), which is blended with the class colour
    (:func:`class_colors`) as ``(1 - alpha) * frame + alpha * colour``, outlined (2 px, class
    colour; inspected: the same line with 1 px white edges either side) and labelled
    ``"<label> <confidence:.2f>"`` (``" *"`` appended if inspected) on a dark box above the
    region, else below it; where both would cover another object or label (a pile), around
    it, with a leader line to the object: labels never cover each other or an object while
    the frame has room. Detections are drawn in the given order (later ones on top); labels
    last.
    Points behind the camera, non-finite or outside the image are ignored; a detection
    with none left is skipped.

    Parameters
    ----------
    frame : (H, W, 3) uint8, RGB; not modified.
    detections : objects with ``points`` ((N, 3) world frame, m), ``label``, ``confidence``
        and optionally ``inspected``.
    K : (3, 3) camera matrix of ``frame`` (px).
    world_from_camera : (4, 4) pose of ``frame``'s camera (m), OpenCV convention.
    alpha : opacity of the tint, in [0, 1].
    keep_clear : image boxes (top, bottom, left, right), px, that labels do not cover (e.g.
        where :func:`compose_frame` puts its insets).

    Returns
    -------
    np.ndarray
        (H, W, 3) uint8, a new array.
    """
    frame = np.asarray(frame)
    if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
        raise ValueError(f"frame must be (H, W, 3) uint8, got {frame.shape} {frame.dtype}")
    if not 0.0 <= alpha <= 1.0:
        raise ValueError(f"alpha must be in [0, 1], got {alpha}")
    out = frame.copy()
    height, width = out.shape[:2]
    colours = class_colors()
    labels = []
    for det in detections:
        uv, _ = project_points(det.points, K, world_from_camera)
        region = _region_mask(uv, height, width)
        if region is None:
            continue
        mask, (r0, r1, c0, c1) = region
        colour = colours.get(det.label, UNKNOWN_COLOR)
        roi = out[r0:r1, c0:c1]  # a view: drawing on it draws on out
        sel = mask > 0
        tinted = (1.0 - alpha) * roi[sel] + alpha * np.asarray(colour, np.float64)
        roi[sel] = np.clip(np.rint(tinted), 0, 255).astype(np.uint8)
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        inspected = bool(getattr(det, "inspected", False))
        if inspected:
            cv2.drawContours(roi, contours, -1, (255, 255, 255), 4, cv2.LINE_AA)
            cv2.drawContours(roi, contours, -1, colour, 2, cv2.LINE_AA)
        else:
            cv2.drawContours(roi, contours, -1, colour, 2, cv2.LINE_AA)
        rows, cols = np.nonzero(sel)
        box = (r0 + rows.min(), r0 + rows.max(), c0 + cols.min(), c0 + cols.max())
        box = tuple(int(b) for b in box)
        text = f"{det.label} {float(det.confidence):.2f}" + (" *" if inspected else "")
        labels.append((text, box, _anchor(sel, r0, c0), colour))
    draw_labels(out, labels, keep_clear)
    return out


def _anchor(mask: np.ndarray, row0: int, col0: int) -> tuple[int, int]:
    """(column, row) of a region's pixel for its leader line: its centroid if that is on it,
    else its pixel nearest the centroid (``mask`` a boolean ROI at ``row0``, ``col0``)."""
    rows, cols = np.nonzero(mask)
    r, c = rows.mean(), cols.mean()
    k = int(np.argmin((rows - r) ** 2 + (cols - c) ** 2))
    return int(col0 + cols[k]), int(row0 + rows[k])


def _colorize_depth(depth: np.ndarray) -> np.ndarray:
    """(H, W) depth (m, 0 = none) -> (H, W, 3) uint8 RGB, turbo near-to-far, holes black."""
    depth = np.asarray(depth, dtype=np.float32)
    valid = np.isfinite(depth) & (depth > 0)
    norm = np.zeros(depth.shape, np.uint8)
    if valid.any():
        lo, hi = np.percentile(depth[valid], (1, 99))
        scaled = (depth[valid] - lo) / max(hi - lo, 1e-6)
        norm[valid] = np.clip(np.rint(255 * scaled), 0, 255).astype(np.uint8)
    rgb = cv2.cvtColor(cv2.applyColorMap(norm, cv2.COLORMAP_TURBO), cv2.COLOR_BGR2RGB)
    rgb[~valid] = 0
    return rgb


def compose_frame(
    overview: np.ndarray,
    wrist_rgb: np.ndarray | None = None,
    wrist_depth: np.ndarray | None = None,
    inset_scale: float = 0.25,
) -> np.ndarray:
    """The overview frame with the wrist images inset in its top-right corner.

    The wrist colour image is on top, the depth (normalised between its 1st and 99th
    percentile, ``cv2.COLORMAP_TURBO``: blue near, red far; no depth black) below it, each
    ``inset_scale`` times the overview's width (aspect kept; shrunk if both would not fit
    the height) with a 1 px white border.

    Parameters
    ----------
    overview : (H, W, 3) uint8 RGB; not modified.
    wrist_rgb : (h, w, 3) uint8 RGB, or None.
    wrist_depth : (h, w) float depth (m, 0 = no depth), or None.
    inset_scale : inset width as a fraction of the overview's width, in (0, 0.5].

    Returns
    -------
    np.ndarray
        (H', W', 3) uint8: the overview's size rounded up to even (libx264/yuv420p need even
        sizes; the last row/column is repeated), i.e. (H, W, 3) for even sizes such as
        the default 480x640.
    """
    overview = np.asarray(overview)
    if overview.ndim != 3 or overview.shape[2] != 3 or overview.dtype != np.uint8:
        raise ValueError(f"overview must be (H, W, 3) uint8, got {overview.shape}")
    if not 0.0 < inset_scale <= 0.5:
        raise ValueError(f"inset_scale must be in (0, 0.5], got {inset_scale}")
    height, width = overview.shape[:2]
    out = np.pad(overview, ((0, height % 2), (0, width % 2), (0, 0)), mode="edge")
    insets = []
    if wrist_rgb is not None:
        insets.append((np.asarray(wrist_rgb, np.uint8), cv2.INTER_AREA))
    if wrist_depth is not None:
        insets.append((np.asarray(wrist_depth, np.float32), cv2.INTER_NEAREST))
    if not insets:
        return out
    places = _inset_places(height, width, insets[0][0].shape[:2], len(insets), inset_scale)
    for (image, interp), (y0, x0, h_in, w_in) in zip(insets, places, strict=True):
        small = cv2.resize(image, (w_in, h_in), interpolation=interp)
        if small.ndim == 2:
            small = _colorize_depth(small)
        out[y0 : y0 + h_in, x0 : x0 + w_in] = small
        cv2.rectangle(out, (x0 - 1, y0 - 1), (x0 + w_in, y0 + h_in), (255, 255, 255), 1)
    return out


def _inset_places(
    height: int, width: int, inset_shape: tuple[int, int], n: int, inset_scale: float
) -> list[tuple[int, int, int, int]]:
    """(row, column, height, width) px of :func:`compose_frame`'s ``n`` insets of images
    ``inset_shape`` (rows, columns) on a ``height`` x ``width`` overview, top to bottom."""
    margin = max(2, round(0.01 * width))
    ih, iw = inset_shape
    w_in = max(2, round(inset_scale * width))
    h_in = max(2, round(w_in * ih / iw))
    room = (height - margin * (n + 1)) // n
    if h_in > room:  # keep them inside the frame
        h_in = max(2, room)
        w_in = max(2, round(h_in * iw / ih))
    x0 = width - margin - w_in
    return [(margin + k * (h_in + margin), x0, h_in, w_in) for k in range(n)]


def _semantic_frame(
    frame: np.ndarray | None,
    env: Any,
    camera: str,
    detections: Sequence[DetectionLike],
    observation: dict | None,
    alpha: float,
    inset_scale: float,
) -> np.ndarray | None:
    """Composed ``frame`` (``camera``'s render of the unwrapped sorting ``env``) or None."""
    if frame is None:
        return None
    obs = observation or {}
    wrist = [obs.get("wrist_rgb"), obs.get("wrist_depth")]
    if detections:
        height, width = frame.shape[:2]
        K = intrinsics(env.model, camera, width, height).K
        pose = camera_pose(env.model, env.data, camera)
        shown = [np.shape(image)[:2] for image in wrist if image is not None]
        insets = _inset_places(height, width, shown[0], len(shown), inset_scale) if shown else []
        # labels stay off the insets (1 px border included)
        clear = [(y - 1, y + h, x - 1, x + w) for y, x, h, w in insets]
        frame = overlay_detections(frame, detections, K, pose, alpha, keep_clear=clear)
    return compose_frame(frame, wrist[0], wrist[1], inset_scale)


class SemanticVideoRecorder(VideoRecorder):
    """Records an episode's overview video with the policy's detections and wrist insets.

    Like :class:`~ipbench.eval.video.VideoRecorder` it subscribes to the env's frame listener
    (a frame every 1/``fps`` simulated seconds while skills run, from ``reset`` on); each
    frame is ``compose_frame(overlay_detections(env.render(), detections, K, pose), wrist)``
    with the overview camera's intrinsics and pose of the current episode, the detections
    and the wrist images of the last :meth:`update`. Call :meth:`update` after each step.

    Parameters
    ----------
    env : a ``SortingEnv`` (wrapped or not) made with ``render_mode="rgb_array"``.
    fps : frames per simulated second; also the video's frame rate.
    camera : the camera the frames come from (``env.render()``'s, ``"overview"``).
    alpha : tint opacity, see :func:`overlay_detections`.
    inset_scale : inset size, see :func:`compose_frame`.

    Attributes
    ----------
    frames : list of (H, W, 3) uint8 RGB frames (about 0.9 MB each at 480x640).
    observation : the last observation given to :meth:`update` (or None).
    detections : the detections drawn (a list).
    """

    def __init__(
        self,
        env: gym.Env,
        fps: float = 30.0,
        camera: str = "overview",
        alpha: float = 0.45,
        inset_scale: float = 0.25,
    ) -> None:
        self.camera, self.alpha, self.inset_scale = camera, alpha, inset_scale
        self.observation: dict | None = None
        self.detections: list[DetectionLike] = []
        super().__init__(env, fps)

    def update(
        self,
        observation: dict | None = None,
        detections: Iterable[DetectionLike] | None = None,
    ) -> None:
        """Set what is drawn from now on, then capture a frame (the state between skills).

        Parameters
        ----------
        observation : the env's observation (its ``wrist_rgb`` and ``wrist_depth`` are
            inset); None keeps the previous one.
        detections : the policy's current detections (copied into a list); None keeps the
            previous ones, ``[]`` clears them.
        """
        if observation is not None:
            self.observation = observation
        if detections is not None:
            self.detections = list(detections)
        self.capture()

    def capture(self) -> None:
        """Append the composed frame of the env's current state (the frame listener)."""
        frame = _semantic_frame(
            self.env.render(),
            self.env,
            self.camera,
            self.detections,
            self.observation,
            self.alpha,
            self.inset_scale,
        )
        if frame is None:
            raise ValueError(
                "SemanticVideoRecorder needs an env made with render_mode='rgb_array', reset"
            )
        self.frames.append(frame)

    def save(self, path: str | Path) -> Path:
        """Write :attr:`frames` as an H.264 MP4 at ``fps`` (:func:`write_mp4`); the path."""
        return super().save(path)


class SemanticRender(gym.Wrapper):
    """Makes ``render()`` return the semantic frame: detections and wrist insets.

    Wraps any ipbench sorting env made with ``render_mode="rgb_array"``; ``render()`` is
    ``compose_frame(overlay_detections(overview, detections_fn(), K, pose), wrist)`` of the
    current state, the wrist images from the last observation of ``reset``/``step``. Works
    with ``gymnasium.wrappers.RecordVideo`` (which needs moviepy). ``render()`` returns None
    before the first ``reset`` (the env has no frame yet).

    Parameters
    ----------
    env : the env to wrap.
    detections_fn : callable returning the current detections (a list of
        :class:`DetectionLike`); None draws no overlay, only the wrist insets.
    camera, alpha, inset_scale : see :class:`SemanticVideoRecorder`.
    """

    def __init__(
        self,
        env: gym.Env,
        detections_fn: Callable[[], Sequence[DetectionLike]] | None = None,
        camera: str = "overview",
        alpha: float = 0.45,
        inset_scale: float = 0.25,
    ) -> None:
        super().__init__(env)
        self.detections_fn = detections_fn
        self.camera, self.alpha, self.inset_scale = camera, alpha, inset_scale
        self.last_observation: dict | None = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        self.last_observation = obs
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.last_observation = obs
        return obs, reward, terminated, truncated, info

    def render(self) -> np.ndarray | None:
        """(H, W, 3) uint8 composed frame of the current state, or None (no frame yet)."""
        detections = list(self.detections_fn()) if self.detections_fn is not None else []
        return _semantic_frame(
            self.env.render(),
            self.env.unwrapped,
            self.camera,
            detections,
            self.last_observation,
            self.alpha,
            self.inset_scale,
        )
