"""Segments scored against a ground-truth object mask (evaluation only: the mask comes from
the simulator's ``info``, never from perception's inputs)."""

from __future__ import annotations

import numpy as np

from .cloud import PerceptionError

__all__ = ["match_segments"]


def match_segments(
    segments,
    gt_mask: np.ndarray,
    valid: np.ndarray | None = None,
    iou: float = 0.5,
    min_pixels: int = 200,
) -> dict:
    """Score segments against a ground-truth id mask, in pixel space.

    ``gt_mask``: (H, W) int object id per pixel, < 0 = none; ``valid``: (H, W) bool pixels that
    count (pass ``depth > 0``: segments can only contain pixels with depth); IoU is between a
    segment's pixels and an object's *valid* pixels. A segment and an object match at IoU >=
    ``iou``, one-to-one (greedy, best first; ``matches`` maps segment index to object id).
    Recall counts objects with >= ``min_pixels`` valid pixels (more hidden ones neither count
    nor penalise). ``merged``: segments holding >= 50 % of the valid pixels of >= 2 counted
    objects; ``split``: counted objects from which >= 2 segments each take >= 50 % of their
    own pixels. Empty denominators give 1.0.
    """
    gt = np.asarray(gt_mask).reshape(-1)
    mask = np.ones_like(gt, bool) if valid is None else np.asarray(valid, bool).reshape(-1)
    if mask.shape != gt.shape:
        raise PerceptionError(f"valid {np.shape(valid)} vs gt_mask {np.shape(gt_mask)}; same")
    gt = np.where(mask, gt, -1)  # pixels without depth belong to no object
    ids, obj_px = np.unique(gt[gt >= 0], return_counts=True)
    counted = obj_px >= min_pixels
    inter = np.zeros((len(segments), len(ids)))
    for i, seg in enumerate(segments):
        labels = gt[seg.pixels]
        pos = np.searchsorted(ids, labels[labels >= 0])
        inter[i] = np.bincount(pos, minlength=len(ids))[: len(ids)]
    seg_px = np.array([len(s.pixels) for s in segments], float).reshape(-1, 1)
    ious = inter / np.maximum(seg_px + obj_px[None, :] - inter, 1)
    matches: dict[int, int] = {}  # greedy one-to-one, best IoU first
    for i, j in zip(*np.unravel_index(np.argsort(-ious, axis=None), ious.shape), strict=True):
        if ious[i, j] < iou:
            break
        if i not in matches and int(ids[j]) not in matches.values():
            matches[int(i)] = int(ids[j])
    matched_seg = np.isin(np.arange(len(segments)), list(matches))
    matched_obj = np.isin(ids, list(matches.values()))
    n_seg, n_obj = len(segments), int(counted.sum())
    covers = (inter >= 0.5 * obj_px[None, :]) & counted[None, :]
    belongs = (inter >= 0.5 * seg_px) & counted[None, :]
    return {
        "precision": float(matched_seg.sum() / n_seg) if n_seg else 1.0,
        "recall": float((matched_obj & counted).sum() / n_obj) if n_obj else 1.0,
        "segments": n_seg,
        "objects": n_obj,
        "matched": int(matched_seg.sum()),
        "merged": int((covers.sum(axis=1) >= 2).sum()),
        "split": int((belongs.sum(axis=0) >= 2).sum()),
        "matches": matches,
    }
