"""Recognition against eccentricity: does looking straight at an object make it recognisable?

An active observer pays off only when where it looks changes what it recognises. Per look
(each step's stereo look of the policy, :attr:`ExplorationPolicy.last_look`), every database
instance visible in the left head image is a *sighting*: its eccentricity — the angle between
the left camera's optical axis and the ray to the instance's centre, degrees — and whether the
look triangulated a candidate of its class within :func:`~ipbench.policies.exploration.
same_object_m` of it (recognised). Candidates near no instance of their class are *false
candidates*. Ground truth (positions, classes, the instance mask) comes from ``info``, read
here by the evaluation only.

Episode records carry ``sightings`` (``[eccentricity_deg, recognised, pixels]`` per sighting;
``pixels``: the instance's visible pixels at the full render's resolution) and
``false_candidates`` / ``looks``; :func:`recognition_by_eccentricity` bins them for the
report (:data:`ECCENTRICITY_BINS_DEG`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ipbench.policies.exploration import same_object_m

__all__ = [
    "ECCENTRICITY_BINS_DEG",
    "EccentricityBin",
    "LookSightings",
    "look_sightings",
    "recognition_by_eccentricity",
]

ECCENTRICITY_BINS_DEG: tuple[float, ...] = (0.0, 4.0, 8.0, 12.0, 16.0, 180.0)
"""Bin edges, degrees off the optical axis, in equal steps of 4 deg. The first bin is about the
policies' verging fovea (the central quarter of each side: ±4.8 deg across, ±3.2 deg up and
down, through the head's 1527-px focal length at 1024 px wide); the head's field reaches
±18.5 deg across and ±12.6 deg up and down, so the last bin holds the image's corners and
edges."""


@dataclass(frozen=True)
class LookSightings:
    """One look's sightings.

    Attributes
    ----------
    sightings : ``(eccentricity_deg, recognised, pixels)`` per database instance visible in
        the left image.
    false_candidates : the look's candidates near no instance of their class.
    """

    sightings: tuple[tuple[float, bool, int], ...]
    false_candidates: int


def _angle_deg(axis: np.ndarray, ray: np.ndarray) -> float:
    cos = float(ray @ axis / (np.linalg.norm(ray) * np.linalg.norm(axis)))
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))


def look_sightings(look, obs: Mapping, info: Mapping, fovea_factor: int = 1) -> LookSightings:
    """The sightings of one look (module docstring).

    Parameters
    ----------
    look : the policy's :class:`~ipbench.policies.stereo_look.Look` on ``obs`` (its
        ``candidates``: ``label``, ``position`` (3,) m); None counts nothing recognised.
    obs : the observation looked at (``head_left_pose``, 4x4 world-from-camera).
    info : its ``info`` (``objects`` and ``head_left_mask``, int32 index into ``objects``'
        order, -1 none).
    fovea_factor : the env's; a foveated mask has one pixel per f x f block of the render.
    """
    pose = np.asarray(obs["head_left_pose"], float)
    origin, axis = pose[:3, 3], pose[:3, 2]
    objects = list(info["objects"].values())
    mask = np.asarray(info["head_left_mask"])
    counts = np.bincount(mask[mask >= 0].ravel(), minlength=len(objects))
    candidates = [] if look is None else list(look.candidates)
    used: set[int] = set()
    out = []
    for k, obj in enumerate(objects):
        label = obj["class"]
        if label is None or counts[k] == 0:
            continue
        centre = np.asarray(obj["position"], float)
        hits = {
            i
            for i, c in enumerate(candidates)
            if c.label == label
            and np.linalg.norm(np.asarray(c.position) - centre) < same_object_m(label)
        }
        used |= hits
        pixels = int(counts[k]) * fovea_factor * fovea_factor
        out.append((round(_angle_deg(axis, centre - origin), 2), bool(hits), pixels))
    return LookSightings(tuple(out), len(candidates) - len(used))


@dataclass(frozen=True)
class EccentricityBin:
    """Sightings in one eccentricity bin.

    Attributes
    ----------
    low_deg, high_deg : the bin's edges, degrees.
    n : sightings.
    recognised : of them, recognised.
    """

    low_deg: float
    high_deg: float
    n: int
    recognised: int

    @property
    def rate(self) -> float | None:
        """``recognised / n``; None without sightings."""
        return self.recognised / self.n if self.n else None


def recognition_by_eccentricity(
    sightings: Iterable[Sequence], edges: Sequence[float] = ECCENTRICITY_BINS_DEG
) -> list[EccentricityBin]:
    """``sightings`` (``[eccentricity_deg, recognised, ...]``) counted per bin of ``edges``
    (each bin ``[low, high)``, increasing edges)."""
    e = np.asarray(edges, float)
    if e.ndim != 1 or e.size < 2 or np.any(np.diff(e) <= 0):
        raise ValueError(f"edges must be 2 or more increasing angles in degrees, got {list(edges)}")
    rows = [(float(s[0]), bool(s[1])) for s in sightings]
    ecc = np.array([r[0] for r in rows], float)
    hit = np.array([r[1] for r in rows], bool)
    out = []
    for lo, hi in zip(e[:-1], e[1:], strict=True):
        inside = (ecc >= lo) & (ecc < hi)
        out.append(EccentricityBin(float(lo), float(hi), int(inside.sum()), int(hit[inside].sum())))
    return out
