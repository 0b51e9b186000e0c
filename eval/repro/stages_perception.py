"""The stages of :mod:`ipbench.eval.repro.digests` that run perception on fixed synthetic
inputs: segmentation and FPFH, the codebook, the GP classifier and the threshold rule."""

from __future__ import annotations

from functools import cache

import numpy as np

from ipbench.eval.repro.stage import (
    digest_arrays,
)

__all__ = [
    "stage_codebook",
    "stage_gpc",
    "stage_perception",
    "stage_threshold",
    "synthetic_cloud",
]


def synthetic_cloud(seed: int = 0):
    """A fixed table-top :class:`~ipbench.perception.cloud.Cloud` (world frame, m): a table
    plane at z = 0.70 m (4 mm grid) and five objects (an upright carton, a bottle, a lying
    box, a bowl-like cylinder and a small box touching it), with 1.5 mm Gaussian noise (the
    Xtion's at 1 m) from ``seed``; viewed from (0.9, -0.1, 1.6)."""
    from ipbench.perception.cloud import Cloud

    table_z, step = 0.70, 0.004

    def grid(a: float, b: float) -> np.ndarray:
        u, v = np.meshgrid(np.arange(-a, a + 1e-9, step), np.arange(-b, b + 1e-9, step))
        return np.column_stack([u.ravel(), v.ravel()])

    def box(size, x, y, yaw) -> np.ndarray:
        half, faces = np.asarray(size) / 2, []
        for axis in range(3):
            i, j = (k for k in range(3) if k != axis)
            uv = grid(half[i], half[j])
            for sign in (1.0, -1.0) if axis < 2 else (1.0,):  # no bottom face
                face = np.zeros((len(uv), 3))
                face[:, [i, j]], face[:, axis] = uv, sign * half[axis]
                faces.append(face)
        return _place(np.concatenate(faces) + [0, 0, half[2]], x, y, yaw)

    def cylinder(radius, height, x, y) -> np.ndarray:
        a, z = np.meshgrid(np.arange(0, 2 * np.pi, step / radius), np.arange(0, height, step))
        side = np.column_stack([radius * np.cos(a.ravel()), radius * np.sin(a.ravel()), z.ravel()])
        top = grid(radius, radius)
        top = top[np.hypot(top[:, 0], top[:, 1]) <= radius]
        top = np.column_stack([top, np.full(len(top), height)])
        return _place(np.concatenate([side, top]), x, y, 0.0)

    def _place(local: np.ndarray, x: float, y: float, yaw: float) -> np.ndarray:
        c, s = np.cos(yaw), np.sin(yaw)
        return local @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T + [x, y, table_z]

    table = grid(0.33, 0.42) + [0.95, -0.10]
    table = np.column_stack([table, np.full(len(table), table_z)])
    points = np.concatenate(
        [
            table,
            box((0.09, 0.06, 0.20), 0.80, -0.30, 0.4),
            cylinder(0.035, 0.22, 1.00, 0.00),
            box((0.16, 0.10, 0.06), 0.85, 0.15, -0.3),
            cylinder(0.07, 0.06, 1.12, -0.25),
            box((0.05, 0.05, 0.12), 1.12, -0.145, 0.0),
        ]
    )
    points += np.random.default_rng([seed, 2024]).normal(0.0, 0.0015, points.shape)
    n = len(points)
    return Cloud(points, np.arange(n, dtype=np.int64), (1, n), np.array([0.9, -0.1, 1.6]))


@cache
def _synthetic_perception():
    """Segments of :func:`synthetic_cloud` and the FPFH descriptors of each."""
    from ipbench.perception.features import fpfh
    from ipbench.perception.segmentation import segment_scene

    cloud = synthetic_cloud()
    seg = segment_scene(cloud)
    return seg, tuple(fpfh(s.points, viewpoint=cloud.origin) for s in seg.segments)


def stage_perception() -> tuple[dict[str, str], dict[str, float]]:
    seg, descriptors = _synthetic_perception()
    segs = seg.segments
    parts = {
        "plane": digest_arrays(np.asarray(seg.normal, float), float(seg.offset)),
        "segments": digest_arrays(
            *(np.sort(s.pixels) for s in segs),
            *(np.stack([s.box_center, s.box_extent]) for s in segs),
            *(s.box_rotation for s in segs),
        ),
        "fpfh": digest_arrays(*descriptors),
    }
    all_d = np.concatenate(descriptors)
    summary = {
        "segments": float(len(segs)),
        "segment_points": float(sum(len(s.points) for s in segs)),
        "extent_mean_m": float(np.mean([s.box_extent for s in segs])),
        "height_mean_m": float(np.mean([s.height for s in segs])),
        "fpfh_rows": float(len(all_d)),
        "fpfh_peak_mean": float(all_d.max(axis=1).mean()),  # (each row sums to 600)
        "fpfh_std": float(all_d.std()),
    }
    return parts, summary


def stage_codebook() -> tuple[dict[str, str], dict[str, float]]:
    from ipbench.perception.features import Codebook

    _, descriptors = _synthetic_perception()
    all_d = np.concatenate(descriptors)
    codebook = Codebook.fit(all_d, k=32, seed=0)
    bows = np.stack([codebook.encode(d) for d in descriptors])
    words = codebook.assign(all_d)
    err = ((all_d - codebook.centers[words]) ** 2).sum(axis=1)
    parts = {"centers": digest_arrays(codebook.centers), "bow": digest_arrays(bows)}
    summary = {
        "quantisation_error": float(err.mean()),
        "words_used": float(len(np.unique(words))),
        "bow_words_mean": float((bows > 0).sum(axis=1).mean()),
    }
    return parts, summary


@cache
def _gpc_fit():
    """The synthetic split of the ``gpc`` stage, the GP fitted on it and its test
    probabilities (one fit for the ``gpc`` and ``threshold`` stages)."""
    from ipbench.perception.gpc import GPCConfig, MulticlassLaplaceGPC
    from ipbench.perception.synthetic import make_split

    X, y, X_test, y_test = make_split(300, 200, seed=0)
    gp = MulticlassLaplaceGPC(GPCConfig()).fit(X, y, 5)
    return X, y, X_test, y_test, gp, gp.predict_proba(X_test)


def stage_gpc() -> tuple[dict[str, str], dict[str, float]]:
    X, y, X_test, y_test, gp, proba = _gpc_fit()
    state = gp.get_state()
    parts = {
        "data": digest_arrays(X, y, X_test, y_test),
        "hyperparameters": digest_arrays(state["log_theta"]),
        "posterior": digest_arrays(state["a"]),
        "proba": digest_arrays(proba),
    }
    summary = {
        "log_sigma": float(state["log_theta"][0]),
        "log_ell": float(state["log_theta"][1]),
        "log_marginal_likelihood": float(gp.log_marginal_likelihood_value_),
        "accuracy": float((proba.argmax(axis=1) == y_test).mean()),
        "confidence_mean": float(proba.max(axis=1).mean()),
    }
    return parts, summary


def stage_threshold() -> tuple[dict[str, str], dict[str, float]]:
    from ipbench.policies.threshold import choose_threshold

    *_, y_test, _, proba = _gpc_fit()
    choice = choose_threshold(proba.max(axis=1), proba.argmax(axis=1) == y_test, 0.9)
    parts = {
        "fit": digest_arrays(np.array(choice.fit)),
        "threshold": digest_arrays(choice.threshold),
    }
    summary = {"threshold": choice.threshold, "fit_a": choice.fit[0], "fit_b": choice.fit[1]}
    return parts, summary
