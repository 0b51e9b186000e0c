"""Labels beside objects in a video frame: each ``"<class> <confidence>"`` box sits above (or
below) its object; where that would cover another object or label, as over a cluttered pile,
it goes to the nearest free place around the object, with a leader line to it, so labels
neither overlap nor hide the pile (:mod:`ipbench.eval.sorting.overlay` draws the objects)."""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import cv2
import numpy as np

__all__ = ["Box", "draw_labels", "label_style", "place_labels"]

Box = tuple[int, int, int, int]
"""An image box (top, bottom, left, right), inclusive pixel rows and columns."""

_TEXT_BG = (24, 24, 24)  # label box (RGB)
_TEXT_FG = (255, 255, 255)
_FONT = cv2.FONT_HERSHEY_SIMPLEX
_LABEL_MARGIN = 2  # px kept free between a label and other labels or objects
_RING_DIRECTIONS = 24  # directions tried around an object for a label that cannot sit next to it


def label_style(height: int) -> tuple[float, int, int]:
    """Font scale, stroke thickness and padding (px) of labels on a frame ``height`` px high."""
    return max(0.3, 0.42 * height / 480), max(1, round(height / 480)), 2


def _overlap_area(boxes: np.ndarray, others: np.ndarray, margin: int) -> np.ndarray:
    """(M,) pixels of each (M, 4) box (top, bottom, left, right) inside the (N, 4) ``others``
    grown by ``margin`` (summed over them)."""
    if len(others) == 0:
        return np.zeros(len(boxes))
    b, o = boxes[:, None, :], others[None, :, :]
    rows = np.minimum(b[..., 1], o[..., 1] + margin) - np.maximum(b[..., 0], o[..., 0] - margin)
    cols = np.minimum(b[..., 3], o[..., 3] + margin) - np.maximum(b[..., 2], o[..., 2] - margin)
    return (np.clip(rows + 1, 0, None) * np.clip(cols + 1, 0, None)).sum(axis=1)


@lru_cache(maxsize=32)
def place_labels(
    sizes: tuple[tuple[int, int], ...],
    regions: tuple[Box, ...],
    anchors: tuple[tuple[int, int], ...],
    keep_clear: tuple[Box, ...],
    height: int,
    width: int,
) -> tuple[tuple[Box, bool], ...]:
    """Where each label goes: ``(box, next_to_its_region)`` per label, in the given order.

    Label ``i`` is ``sizes[i]`` = (width, height) px and belongs to the object in
    ``regions[i]`` (its image box) at ``anchors[i]`` = (column, row), a pixel on it. A label
    sits centred above its object, else below it, when that covers no object, no other label
    and nothing of ``keep_clear`` (all kept ``_LABEL_MARGIN`` px away); otherwise it goes to
    the nearest such free place around its object, preferring the direction away from the
    middle of all objects (so the labels of a pile ring it), and a leader line shows which
    object it names. Labels of objects far from that middle are placed first. Where no place
    is free (a frame too full), the least covered one is taken. Pure and cached: the frames of
    a video between two policy steps place the same labels once.
    """
    n = len(sizes)
    obstacles = np.array(regions + keep_clear, float).reshape(-1, 4)
    anchor = np.array(anchors, float).reshape(-1, 2)
    middle = anchor.mean(axis=0) if n else np.zeros(2)
    outward = np.arctan2(anchor[:, 1] - middle[1], anchor[:, 0] - middle[0])
    far = np.hypot(*(anchor - middle).T)
    outward[far < 1.0] = -np.pi / 2  # the middle object: upwards
    angles = 2 * np.pi * np.arange(_RING_DIRECTIONS) / _RING_DIRECTIONS
    placed: list[Box] = []
    result: dict[int, tuple[Box, bool]] = {}
    for i in sorted(range(n), key=lambda k: (-far[k], k)):
        bw, bh = sizes[i]
        top, bottom, left, right = regions[i]
        x0 = int(np.clip((left + right) // 2 - bw // 2, 0, max(width - bw, 0)))
        beside = [(top - bh - 2, x0), (bottom + 3, x0)]  # (y0, x0) above, below
        # around: label centres on rings about the anchor, a label height apart
        radii = np.arange(0.5 * bh + 4, np.hypot(height, width), bh + _LABEL_MARGIN)
        turn = np.abs(np.angle(np.exp(1j * (angles - outward[i]))))  # 0 .. pi from outward
        cx = anchor[i, 0] + np.outer(radii, np.cos(angles))
        cy = anchor[i, 1] + np.outer(radii, np.sin(angles))
        cost = np.outer(radii, 1.0 + turn / np.pi) + 1.0  # beside its object: cost 0, 0.5
        y0 = np.r_[[b[0] for b in beside], np.rint(cy - bh / 2).ravel()]
        xs = np.r_[[b[1] for b in beside], np.rint(cx - bw / 2).ravel()]
        cost = np.r_[0.0, 0.5, cost.ravel()]
        boxes = np.stack([y0, y0 + bh - 1, xs, xs + bw - 1], axis=1)
        inside = (boxes[:, 0] >= 0) & (boxes[:, 1] < height) & (boxes[:, 2] >= 0)
        inside &= boxes[:, 3] < width
        own = np.zeros(len(boxes), bool)
        own[:2] = True  # beside its own region by construction: only the others count
        others = np.delete(obstacles, i, axis=0) if i < len(regions) else obstacles
        covered = np.where(
            own,
            _overlap_area(boxes, others, _LABEL_MARGIN),
            _overlap_area(boxes, obstacles, _LABEL_MARGIN),
        )
        covered += _overlap_area(boxes, np.array(placed, float).reshape(-1, 4), _LABEL_MARGIN)
        free = inside & (covered == 0)
        if free.any():
            k = int(np.flatnonzero(free)[np.argmin(cost[free])])
        else:  # nowhere free: the least covered place inside the frame (else anywhere)
            pool = np.flatnonzero(inside) if inside.any() else np.arange(len(boxes))
            k = int(pool[np.lexsort((cost[pool], covered[pool]))[0]])
        box = tuple(int(v) for v in boxes[k])
        placed.append(box)
        result[i] = (box, k < 2)
    return tuple(result[i] for i in range(n))


def draw_labels(
    frame: np.ndarray,
    labels: list[tuple[str, Box, tuple[int, int], tuple[int, int, int]]],
    keep_clear: Sequence[Box] = (),
) -> None:
    """Draw ``(text, region box, anchor (column, row), colour)`` labels on dark boxes.

    Where each goes is :func:`place_labels`' choice (next to its object, else around it
    without covering objects or other labels); a label away from its object gets a leader
    line in the class colour from the label to a dot on the object. Lines are drawn before
    the labels, so labels stay readable where lines cross them.
    """
    height, width = frame.shape[:2]
    scale, thick, pad = label_style(height)
    sizes = []
    for text, *_ in labels:
        (tw, th), base = cv2.getTextSize(text, _FONT, scale, thick)
        sizes.append((tw + 2 * pad, th + base + 2 * pad))
    spots = place_labels(
        tuple(sizes),
        tuple(box for _, box, _, _ in labels),
        tuple(anchor for _, _, anchor, _ in labels),
        tuple(tuple(int(v) for v in b) for b in keep_clear),
        height,
        width,
    )
    for (_, _, anchor, colour), ((top, bottom, left, right), beside) in zip(
        labels, spots, strict=True
    ):
        if not beside:
            start = (int(np.clip(anchor[0], left, right)), int(np.clip(anchor[1], top, bottom)))
            cv2.line(frame, start, anchor, colour, 1, cv2.LINE_AA)
            cv2.circle(frame, anchor, 2, colour, cv2.FILLED, cv2.LINE_AA)
    for (text, _, _, colour), ((top, bottom, left, right), _) in zip(labels, spots, strict=True):
        cv2.rectangle(frame, (left, top), (right, bottom), _TEXT_BG, cv2.FILLED)
        cv2.rectangle(frame, (left, top), (right, bottom), colour, 1)
        (_, th), _ = cv2.getTextSize(text, _FONT, scale, thick)
        cv2.putText(
            frame, text, (left + pad, top + pad + th), _FONT, scale, _TEXT_FG, thick, cv2.LINE_AA
        )
