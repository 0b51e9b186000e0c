"""Where to look next: saliency of unexplained features and inhibition of return (IOR).

Saliency (thesis ch. 3 §3.3, the rule stated here is ours): the dominant (left) eye's
keypoints that no recognised object explains (``Recognition.unmatched``) mark texture of
nothing known. Each such keypoint ``i`` scores

    ``s_i = sum_j exp(-|x_i - x_j|^2 / (2 sigma^2)) * exp(-e_i^2 / (2 e0^2))``

— the density of unexplained keypoints around it (``sigma`` = :data:`DENSITY_SIGMA_PX` =
32 px), times an eccentricity weight, ``e_i`` being its distance to the principal point and
``e0`` half the image width, so that of two equally dense places the nearer one (a shorter
saccade, better resolved now) wins. Candidate locations are the keypoints in order of score,
each suppressing the others within ``2 sigma``.

Inhibition of return keeps the gaze directions already attended, as unit vectors in an
egocentric frame (the robot's or world frame; only rotations matter, the head turns about its
pan-tilt axes), and inhibits any direction within :data:`INHIBITION_RADIUS_RAD` = 4° of one:
about a 16 cm disc at the head's 2.2-2.3 m distance to the table (one household product).
Neither value was tuned on a result.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ipbench.perception.features2d import ActiveVisionError

__all__ = [
    "DENSITY_SIGMA_PX",
    "INHIBITION_RADIUS_RAD",
    "InhibitionMap",
    "SalientLocation",
    "most_salient",
    "pixel_direction",
    "salient_locations",
]

DENSITY_SIGMA_PX = 32.0
INHIBITION_RADIUS_RAD = float(np.deg2rad(4.0))


@dataclass(frozen=True, eq=False)
class SalientLocation:
    """A place to look at: ``xy`` (2,) float64 image position, px; ``score`` >= 0 (module
    docstring); ``support`` unexplained keypoints within ``sigma``."""

    xy: np.ndarray
    score: float
    support: int


def salient_locations(
    xy: np.ndarray,
    image_size: tuple[int, int],
    principal_point: tuple[float, float] | None = None,
    sigma_px: float = DENSITY_SIGMA_PX,
    max_locations: int = 20,
) -> list[SalientLocation]:
    """Candidate locations from unexplained keypoints ``xy`` (N, 2) px, best first.

    ``image_size`` is ``(width, height)``, px; ``principal_point`` defaults to the image centre.
    """
    xy = np.asarray(xy, np.float64).reshape(-1, 2) if np.size(xy) else np.zeros((0, 2))
    width, height = image_size
    if width <= 0 or height <= 0 or sigma_px <= 0 or max_locations < 1:
        raise ActiveVisionError(
            "valid: image_size (width, height) > 0, sigma_px > 0, max_locations >= 1"
        )
    if len(xy) == 0:
        return []
    centre = np.array(
        principal_point if principal_point is not None else ((width - 1) / 2, (height - 1) / 2),
        float,
    )
    d2 = np.sum((xy[:, None, :] - xy[None, :, :]) ** 2, axis=2)
    density = np.exp(-d2 / (2 * sigma_px**2)).sum(1)
    e0 = width / 2.0
    eccentricity = np.linalg.norm(xy - centre, axis=1)
    score = density * np.exp(-(eccentricity**2) / (2 * e0**2))
    order = np.lexsort((xy[:, 0], xy[:, 1], -score))
    alive = np.ones(len(xy), bool)
    out: list[SalientLocation] = []
    for i in order:
        if not alive[i]:
            continue
        out.append(
            SalientLocation(xy[i].copy(), float(score[i]), int((d2[i] <= sigma_px**2).sum()))
        )
        if len(out) == max_locations:
            break
        alive &= d2[i] > (2 * sigma_px) ** 2
    return out


def _unit(direction) -> np.ndarray:
    v = np.asarray(direction, np.float64)
    n = np.linalg.norm(v) if v.shape == (3,) else 0.0
    if not (np.isfinite(n) and n > 1e-12):
        raise ActiveVisionError(f"direction {direction!r}; valid: a finite non-zero 3-vector")
    return v / n


def pixel_direction(xy: np.ndarray, K: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """(3,) unit gaze direction of pixel ``xy`` in the frame of the world-from-camera ``pose``
    (OpenCV camera convention; ``K^-1 (u, v, 1)`` rotated by the pose)."""
    K, pose = np.asarray(K, float), np.asarray(pose, float)
    if K.shape != (3, 3) or pose.shape != (4, 4):
        raise ActiveVisionError(f"K {K.shape}, pose {pose.shape}; valid: (3, 3) and (4, 4)")
    u, v = np.asarray(xy, float).reshape(2)
    ray = np.linalg.solve(K, np.array([u, v, 1.0]))
    return _unit(pose[:3, :3] @ ray)


class InhibitionMap:
    """Gaze directions already attended; a direction within ``radius_rad`` of one is inhibited."""

    def __init__(self, radius_rad: float = INHIBITION_RADIUS_RAD) -> None:
        if not 0 < radius_rad < np.pi:
            raise ActiveVisionError(f"radius_rad is {radius_rad}; valid: 0 < radius < pi")
        self.radius_rad = float(radius_rad)
        self._directions: list[np.ndarray] = []

    def __len__(self) -> int:
        return len(self._directions)

    @property
    def directions(self) -> np.ndarray:
        """(M, 3) unit vectors attended so far, in the order added."""
        return np.array(self._directions).reshape(-1, 3)

    def add(self, direction: np.ndarray) -> None:
        """Inhibit the neighbourhood of ``direction`` (3,), normalised here."""
        self._directions.append(_unit(direction))

    def is_inhibited(self, direction: np.ndarray) -> bool:
        """Whether ``direction`` (3,) is within ``radius_rad`` of an attended direction."""
        if not self._directions:
            return False
        cosines = self.directions @ _unit(direction)
        return bool(np.any(cosines >= np.cos(self.radius_rad)))


def most_salient(
    locations: list[SalientLocation],
    K: np.ndarray,
    pose: np.ndarray,
    inhibition: InhibitionMap,
) -> SalientLocation | None:
    """The best location whose gaze direction is not inhibited, or ``None`` if all are."""
    for location in locations:
        if not inhibition.is_inhibited(pixel_direction(location.xy, K, pose)):
            return location
    return None
