"""FPFH bag-of-words descriptors of segmented objects (thesis ch. 5 §5.3.2).

An object view (a segment's points) is voxel-downsampled, its normals are estimated and
oriented towards the viewpoint, and every remaining point gets a 33-bin Fast Point Feature
Histogram (Rusu et al. 2009, open3d). A :class:`Codebook` of ``k`` FPFH words (mini-batch
k-means) turns the variable-size set into one fixed ``k``-vector: nearest-word assignment,
**max pooling** over the view's points (which words occur) and L2 normalisation.

Defaults: 7 mm voxels (the Xtion's depth noise and quantisation at ~1 m are 2-3 mm; a cluttered
scene's objects give ~8k voxels); normals from 2 cm / 30 neighbours (a mug's curvature is
resolved, the noise averaged); FPFH over 5 cm / 100 neighbours (the scale of a handle, a rim or
a carton's edge; at 7 mm voxels 100 neighbours reach ~4 cm on a surface, at 5 mm only ~2.8 cm);
``k = 256`` (the thesis found 256 words better than 128 and 512). 7 mm rather than 5 mm voxels
about halve the time of a cluttered scene's FPFH (``ipbench bench perception`` measures it) and
leave the accuracy of a linear classifier on the BoW vectors, a proxy for the benchmark's
classifier, unchanged within its scene-wise cross-validation error.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import open3d as o3d
from sklearn.cluster import MiniBatchKMeans
from threadpoolctl import threadpool_limits

from .cloud import PerceptionError

__all__ = ["DEFAULT_FEATURES", "FPFH_DIM", "Codebook", "FeatureConfig", "describe", "fpfh"]

FPFH_DIM = 33  # FPFH histogram length (3 angle features x 11 bins)


@dataclass(frozen=True)
class FeatureConfig:
    """Parameters of the FPFH bag of words (units in the comments; see the module docstring)."""

    voxel_size: float = 0.007  # m; downsampling before normals and FPFH
    normal_radius: float = 0.02  # m; normal estimation neighbourhood
    normal_max_nn: int = 30  # neighbours at most, normals
    fpfh_radius: float = 0.05  # m; FPFH neighbourhood
    fpfh_max_nn: int = 100  # neighbours at most, FPFH
    codebook_size: int = 256  # words k
    seed: int = 0  # k-means seed

    def __post_init__(self) -> None:
        for name in ("voxel_size", "normal_radius", "normal_max_nn", "fpfh_radius"):
            if not getattr(self, name) > 0:
                raise PerceptionError(f"FeatureConfig.{name}={getattr(self, name)!r}; valid: > 0")
        if self.fpfh_max_nn < 1 or self.codebook_size < 2:
            raise PerceptionError(
                f"FeatureConfig.fpfh_max_nn={self.fpfh_max_nn!r}, codebook_size="
                f"{self.codebook_size!r}; valid: fpfh_max_nn >= 1, codebook_size >= 2"
            )


DEFAULT_FEATURES = FeatureConfig()


def fpfh(
    points: np.ndarray, config: FeatureConfig = DEFAULT_FEATURES, viewpoint=None
) -> np.ndarray:
    """FPFH descriptors of a view, one per voxel.

    Parameters
    ----------
    points : (N, 3) array
        The object's points, m.
    config : FeatureConfig
    viewpoint : (3,) array-like, optional
        Camera centre, m (e.g. ``Cloud.origin``); normals are flipped to face it. Default:
        normals face world +z (up), ambiguous on vertical sides, so pass the camera.

    Returns
    -------
    (M, 33) float64 array
        M = number of occupied voxels (0 rows for an empty input).
    """
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3 or not np.isfinite(points).all():
        raise PerceptionError(f"points have shape {points.shape}; valid: finite (N, 3) metres")
    if len(points) == 0:
        return np.zeros((0, FPFH_DIM))
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    pcd = pcd.voxel_down_sample(config.voxel_size)
    search = o3d.geometry.KDTreeSearchParamHybrid(config.normal_radius, config.normal_max_nn)
    pcd.estimate_normals(search)
    if viewpoint is None:
        pcd.orient_normals_to_align_with_direction(np.array([0.0, 0.0, 1.0]))
    else:
        pcd.orient_normals_towards_camera_location(np.asarray(viewpoint, dtype=np.float64))
    search = o3d.geometry.KDTreeSearchParamHybrid(config.fpfh_radius, config.fpfh_max_nn)
    return np.asarray(o3d.pipelines.registration.compute_fpfh_feature(pcd, search).data).T.copy()


def _check_descriptors(descriptors) -> np.ndarray:
    d = np.asarray(descriptors, dtype=np.float64)
    if d.ndim != 2 or d.shape[1] != FPFH_DIM or not np.isfinite(d).all():
        raise PerceptionError(f"descriptors have shape {d.shape}; valid: finite (M, {FPFH_DIM})")
    return d


@dataclass(frozen=True, eq=False)
class Codebook:
    """``k`` FPFH words, ``centers`` (k, 33); encodes a view as a (k,) max-pooled BoW."""

    centers: np.ndarray

    def __post_init__(self) -> None:
        c = np.asarray(self.centers, dtype=np.float64)
        if c.ndim != 2 or c.shape[1] != FPFH_DIM or len(c) < 2 or not np.isfinite(c).all():
            raise PerceptionError(f"centers have shape {c.shape}; valid: finite (k>=2, 33)")
        object.__setattr__(self, "centers", c)

    @property
    def size(self) -> int:
        """Number of words k."""
        return len(self.centers)

    @classmethod
    def fit(cls, descriptors, k: int = 256, seed: int = 0) -> Codebook:
        """Mini-batch k-means (scikit-learn, seeded: same inputs, same words) on (M, 33).

        Runs on one OpenMP thread: the mini-batch steps are tiny, and on a busy machine
        scikit-learn's OpenMP threads spin-wait (measured 40x slower on 2 loaded cores).
        """
        d = _check_descriptors(descriptors)
        if not 2 <= k <= len(d):
            raise PerceptionError(f"k={k} words from {len(d)} descriptors; valid: 2 <= k <= M")
        kmeans = MiniBatchKMeans(k, random_state=seed, batch_size=max(1024, 4 * k), n_init=3)
        with threadpool_limits(limits=1, user_api="openmp"):
            return cls(kmeans.fit(d).cluster_centers_)

    def assign(self, descriptors) -> np.ndarray:
        """(M,) index of the nearest word of each descriptor (Euclidean)."""
        d = _check_descriptors(descriptors)
        sq = (d * d).sum(1)[:, None] - 2 * d @ self.centers.T + (self.centers**2).sum(1)
        return np.argmin(sq, axis=1)

    def encode(self, descriptors) -> np.ndarray:
        """(k,) BoW of one view: word presence (max pooling), L2-normalised (0 if empty)."""
        bow = np.zeros(self.size)
        if len(np.asarray(descriptors)):
            bow[self.assign(descriptors)] = 1.0
            bow /= np.linalg.norm(bow)
        return bow

    def to_arrays(self) -> dict[str, np.ndarray]:
        """npz-friendly ``{"centers": (k, 33)}``."""
        return {"centers": self.centers.copy()}

    @classmethod
    def from_arrays(cls, arrays) -> Codebook:
        """Inverse of :meth:`to_arrays` (a dict or an ``np.load`` result)."""
        if "centers" not in arrays:
            raise PerceptionError(f"codebook arrays {list(arrays)}; valid: a 'centers' entry")
        return cls(np.asarray(arrays["centers"]))

    def save(self, file: str | Path | io.IOBase) -> None:
        """Write an ``.npz`` file."""
        np.savez(file, **self.to_arrays())

    @classmethod
    def load(cls, file: str | Path | io.IOBase) -> Codebook:
        """Read a file written by :meth:`save`."""
        with np.load(file) as arrays:
            return cls.from_arrays(arrays)


def describe(
    points: np.ndarray, codebook: Codebook, config: FeatureConfig = DEFAULT_FEATURES, viewpoint=None
) -> np.ndarray:
    """(k,) BoW vector of one object view: :func:`fpfh` then :meth:`Codebook.encode`."""
    return codebook.encode(fpfh(points, config, viewpoint))
