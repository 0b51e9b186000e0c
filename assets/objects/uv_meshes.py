"""Low-poly meshes with texture coordinates (pure numpy), for the v2 catalogue's textures.

Every builder returns ``(vertices (N, 3) m, faces (M, 3) int, texcoords (N, 2))``, wound
counter-clockwise seen from outside. Texture coordinates: ``u`` runs once around the object
(along the outline's perimeter, from the +x axis counter-clockwise seen from above) and the
seam's vertices are duplicated (u = 0 and u = 1), so a texture that is seamless in u wraps
without a visible joint; ``v`` runs from 0 at the first ring to 1 at the last, along the
profile's length.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = [
    "UVMesh",
    "loft",
    "lathe_uv",
    "circle",
    "rounded_square",
    "octagon",
    "octagon_u",
    "polygon_fan",
]

UVMesh = tuple[np.ndarray, np.ndarray, np.ndarray]
"""``(vertices (N, 3), faces (M, 3) int, texcoords (N, 2))``."""


def circle(radius: float, k: int) -> np.ndarray:
    """(k, 2) points of a circle of ``radius`` (m), counter-clockwise from +x."""
    a = 2 * np.pi * np.arange(k) / k
    return radius * np.column_stack([np.cos(a), np.sin(a)])


def rounded_square(half: float, corner: float, k: int) -> np.ndarray:
    """(k, 2) points where rays at angles ``2 pi i / k`` leave a square of half side ``half``
    with corners rounded to radius ``corner`` (m)."""
    a = 2 * np.pi * np.arange(k) / k
    d = np.column_stack([np.cos(a), np.sin(a)])
    c = half - corner
    out = np.empty((k, 2))
    for i, (x, y) in enumerate(d):
        t = half / max(abs(x), abs(y))  # ray hits the flat side at t
        p = t * np.array([x, y])
        if abs(p[0]) > c and abs(p[1]) > c:  # in a corner: ray meets the arc
            q = np.array([np.sign(x) * c, np.sign(y) * c])
            b = d[i] @ q
            t = b + np.sqrt(b * b - q @ q + corner * corner)
            p = t * d[i]
        out[i] = p
    return out


def octagon(width: float, depth: float, chamfer: float) -> np.ndarray:
    """(8, 2) corners of a ``width`` x ``depth`` rectangle (m, centred) whose corners are cut
    by ``chamfer`` (m), counter-clockwise from the +x face; ``chamfer`` 0 gives the rectangle
    with each corner twice (zero-length cut edges are dropped)."""
    w, d, c = width / 2, depth / 2, chamfer
    pts = [(w, -d + c), (w, d - c), (w - c, d), (-w + c, d), (-w, d - c), (-w, -d + c),
           (-w + c, -d), (w - c, -d)]  # fmt: skip
    if c <= 0:
        pts = [(w, -d), (w, d), (-w, d), (-w, -d)]
    return np.asarray(pts, float)


def octagon_u(width: float, depth: float, chamfer: float) -> np.ndarray:
    """u of the points of :func:`octagon` (and the seam copy): each flat face spans one
    quarter of u (front +x, right +y, back -x, left -y), each cut edge straddles a quarter's
    boundary."""
    if chamfer <= 0:
        return np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    cut = chamfer * np.sqrt(2) / 2
    faces = [depth - 2 * chamfer, width - 2 * chamfer] * 2
    us = []
    for q, face in enumerate(faces):
        delta = 0.25 * cut / (face + 2 * cut)
        us += [0.25 * q + delta, 0.25 * (q + 1) - delta]
    return np.array([*us, 1.0 + us[0]])


def loft(
    outlines: Sequence[np.ndarray], zs: Sequence[float], u: np.ndarray | None = None
) -> UVMesh:
    """Surface through closed outlines at heights ``zs``.

    Parameters
    ----------
    outlines : per ring a (K, 2) counter-clockwise (x, y) outline, m; all with the same K.
        An outline whose points all coincide (e.g. all zeros) is a pole (a fan closes it).
    zs : per ring its height, m. Rings go bottom to top for an outward-facing side wall.
    u : optional (K + 1,) u of the outline's points and of the seam's copy of the first
        (default: proportional to the perimeter); values past 1 wrap (textures repeat).

    Returns
    -------
    (vertices, faces, texcoords); u along the perimeter, v along the profile.
    """
    rings = [np.asarray(o, float) for o in outlines]
    k = len(rings[0])
    verts, uvs = [], []
    # v: cumulative distance between rings (mean radius and height), normalised
    mean_r = np.array([np.linalg.norm(r, axis=1).mean() for r in rings])
    steps = np.hypot(np.diff(mean_r), np.diff(np.asarray(zs, float)))
    v = np.concatenate([[0.0], np.cumsum(steps)]) / max(steps.sum(), 1e-12)
    poles = []
    for ring, z, vj in zip(rings, zs, v, strict=True):
        closed = np.vstack([ring, ring[:1]])
        seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
        pole = seg.sum() < 1e-12
        poles.append(pole)
        u = (
            (np.arange(k + 1) + 0.5) / k
            if pole
            else np.concatenate([[0], np.cumsum(seg)]) / seg.sum()
        )
        verts.append(np.column_stack([closed, np.full(k + 1, z)]))
        uvs.append(np.column_stack([u, np.full(k + 1, vj)]))
    faces = []
    for j in range(len(rings) - 1):
        lo, hi = j * (k + 1), (j + 1) * (k + 1)
        for i in range(k):
            a, b, c, d = lo + i, lo + i + 1, hi + i + 1, hi + i
            if not poles[j]:
                faces.append([a, b, c])
            if not poles[j + 1]:
                faces.append([a, c, d])
    return np.vstack(verts), np.asarray(faces, int), np.vstack(uvs)


def lathe_uv(profile: np.ndarray | Sequence[Sequence[float]], segments: int) -> UVMesh:
    """Surface of revolution of an ``(r, z)`` polyline (as :func:`.meshes.lathe`) with
    cylindrical texture coordinates (u = angle / 2 pi, v along the profile)."""
    prof = np.asarray(profile, float)
    unit = circle(1.0, segments)
    return loft([r * unit for r in prof[:, 0]], prof[:, 1])


def polygon_fan(outline: np.ndarray, z: float, up: bool) -> tuple[np.ndarray, np.ndarray]:
    """Flat convex polygon (a cap) at height ``z``: ``(vertices, faces)``, facing +z if
    ``up`` else -z."""
    pts = np.asarray(outline, float)
    verts = np.column_stack([pts, np.full(len(pts), z)])
    faces = np.array([[0, i, i + 1] for i in range(1, len(pts) - 1)], int)
    return verts, faces if up else faces[:, ::-1]
