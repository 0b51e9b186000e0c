"""Pure numpy builders of low-poly triangle meshes (no MuJoCo here).

Every builder returns ``(vertices, faces)``: ``vertices`` is an ``(N, 3)`` float array in
metres, ``faces`` an ``(M, 3)`` int array of vertex indices, wound counter-clockwise seen from
outside (right-hand normal points out of the material).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = [
    "Mesh",
    "lathe",
    "convex_polyhedron",
    "prism_sides",
    "tube",
    "cylinder_between",
    "merge",
    "mass_properties",
]

Mesh = tuple[np.ndarray, np.ndarray]
"""A triangle mesh: ``(vertices (N, 3) float, faces (M, 3) int)``."""


def lathe(profile: np.ndarray | Sequence[Sequence[float]], segments: int) -> Mesh:
    """Surface of revolution of an ``(r, z)`` polyline about the z axis.

    Parameters
    ----------
    profile : (P, 2) array of (radius, height) points, m. Traverse it counter-clockwise in the
        (r, z) half-plane (e.g. bottom outwards, up the outside, inwards at the top) for
        outward normals. Points with radius 0 become a single pole vertex.
    segments : number of angular segments (vertices at angles ``2 pi k / segments``).

    Returns
    -------
    (vertices (N, 3), faces (M, 3)); ``M = 2 * segments * (P - 1) - segments * n_poles``.
    """
    prof = np.asarray(profile, dtype=float)
    if prof.ndim != 2 or prof.shape[1] != 2 or len(prof) < 2:
        raise ValueError(f"profile must be (P >= 2, 2), got {prof.shape}")
    ang = 2.0 * np.pi * np.arange(segments) / segments
    cos, sin = np.cos(ang), np.sin(ang)
    verts: list[np.ndarray] = []
    rings: list[np.ndarray] = []  # per profile point: (segments,) vertex indices
    for r, z in prof:
        start = sum(len(v) for v in verts)
        if r <= 1e-12:
            verts.append(np.array([[0.0, 0.0, z]]))
            rings.append(np.full(segments, start))
        else:
            verts.append(np.column_stack([r * cos, r * sin, np.full(segments, z)]))
            rings.append(start + np.arange(segments))
    faces: list[list[int]] = []
    for j in range(len(prof) - 1):
        lo, hi = rings[j], rings[j + 1]
        pole_lo, pole_hi = prof[j, 0] <= 1e-12, prof[j + 1, 0] <= 1e-12
        for i in range(segments):
            a, b = lo[i], lo[(i + 1) % segments]
            c, d = hi[(i + 1) % segments], hi[i]
            if not pole_lo:
                faces.append([a, b, c])
            if not pole_hi:
                faces.append([a, c, d])
    return np.vstack(verts), np.asarray(faces, dtype=int)


def convex_polyhedron(points: np.ndarray) -> Mesh:
    """Triangulated convex hull of ``points`` (all of them should be hull vertices).

    Parameters
    ----------
    points : (N, 3) points, m.

    Returns
    -------
    (vertices (N', 3), faces (M, 3)) with outward winding.
    """
    from scipy.spatial import ConvexHull

    pts = np.asarray(points, dtype=float)
    hull = ConvexHull(pts)
    keep = np.sort(hull.vertices)
    remap = np.full(len(pts), -1)
    remap[keep] = np.arange(len(keep))
    faces = remap[hull.simplices]
    v = pts[keep]
    normal = np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]])
    flip = np.einsum("ij,ij->i", normal, hull.equations[:, :3]) < 0
    faces[flip] = faces[flip][:, ::-1]
    return v, faces


def prism_sides(polygon: np.ndarray, z0: float, z1: float) -> Mesh:
    """Side walls (no caps) of a vertical prism.

    Parameters
    ----------
    polygon : (K, 2) counter-clockwise (x, y) outline, m.
    z0, z1 : bottom and top heights, m (z1 > z0).

    Returns
    -------
    (vertices (2K, 3), faces (2K, 3)), normals pointing away from the prism.
    """
    poly = np.asarray(polygon, dtype=float)
    k = len(poly)
    verts = np.vstack([np.column_stack([poly, np.full(k, z)]) for z in (z0, z1)])
    i = np.arange(k)
    j = (i + 1) % k
    faces = np.vstack([np.column_stack([i, j, k + j]), np.column_stack([i, k + j, k + i])])
    return verts, faces


def tube(path: np.ndarray, radius: float, sides: int, up: Sequence[float] = (0, 1, 0)) -> Mesh:
    """Open tube of circular cross-section swept along a polyline.

    Parameters
    ----------
    path : (K, 3) centre-line points, m (K >= 2).
    radius : tube radius, m.
    sides : vertices per ring.
    up : a direction never parallel to the path (rings are built around ``path x up``).

    Returns
    -------
    (vertices (K * sides, 3), faces (2 * sides * (K - 1), 3)), outward winding, open ends.
    """
    p = np.asarray(path, dtype=float)
    tangent = np.gradient(p, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    n = np.cross(np.asarray(up, float), tangent)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    b = np.cross(tangent, n)  # (n, b, tangent) is right-handed: n x b = tangent
    ang = 2.0 * np.pi * np.arange(sides) / sides
    ring = np.cos(ang)[None, :, None] * n[:, None, :] + np.sin(ang)[None, :, None] * b[:, None, :]
    verts = (p[:, None, :] + radius * ring).reshape(-1, 3)
    faces = []
    for k in range(len(p) - 1):
        for i in range(sides):
            a, bb = k * sides + i, k * sides + (i + 1) % sides
            c, d = bb + sides, a + sides
            faces += [[a, bb, c], [a, c, d]]
    return verts, np.asarray(faces, dtype=int)


def cylinder_between(p0: Sequence[float], p1: Sequence[float], radius: float, sides: int) -> Mesh:
    """Closed cylinder (with caps) from point ``p0`` to ``p1`` (both (3,), m)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    axis = p1 - p0
    length = float(np.linalg.norm(axis))
    v, f = lathe([(0, 0), (radius, 0), (radius, length), (0, length)], sides)
    z = axis / length
    x = np.cross([0.0, 1.0, 0.0] if abs(z[1]) < 0.9 else [1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    rot = np.column_stack([x, np.cross(z, x), z])
    return v @ rot.T + p0, f


def merge(*meshes: Mesh) -> Mesh:
    """Concatenate meshes into one ``(vertices, faces)`` pair."""
    verts, faces, offset = [], [], 0
    for v, f in meshes:
        verts.append(np.asarray(v, float))
        faces.append(np.asarray(f, int) + offset)
        offset += len(v)
    return np.vstack(verts), np.vstack(faces)


def mass_properties(
    vertices: np.ndarray, faces: np.ndarray
) -> tuple[float, np.ndarray, np.ndarray]:
    """Volume, centroid and unit-density inertia of a closed, outward-wound mesh.

    Parameters
    ----------
    vertices : (N, 3), m.
    faces : (M, 3) vertex indices.

    Returns
    -------
    volume : m^3 (negative if the winding is inward).
    centroid : (3,), m.
    inertia : (3, 3) inertia tensor about the centroid for density 1, kg m^2 per (kg/m^3).
    """
    v = np.asarray(vertices, float)[np.asarray(faces, int)]  # (M, 3 corners, 3)
    a = v.transpose(0, 2, 1)  # columns are the corners
    det = np.linalg.det(a)
    canon = (np.ones((3, 3)) + np.eye(3)) / 120.0
    cov = np.einsum("m,mij,jk,mlk->il", det, a, canon, a)
    vol = det.sum() / 6.0
    centroid = (det[:, None] * v.sum(axis=1)).sum(axis=0) / (24.0 * vol)
    cov -= vol * np.outer(centroid, centroid)
    inertia = np.trace(cov) * np.eye(3) - cov
    return float(vol), centroid, inertia
