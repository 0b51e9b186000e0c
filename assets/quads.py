"""Textured quads: a flat rectangle printed with an image (posters, calibration boards).

One visual-only mesh of two triangles with texture coordinates, and its texture and material;
the caller gives the corners in its body's frame, in the order top-left, top-right,
bottom-right, bottom-left of the image, and the side the print faces.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

__all__ = ["add_textured_quad"]

_TEXCOORDS = [0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0]  # image row 0 at v = 0 (top)


def add_textured_quad(
    spec: mujoco.MjSpec,
    body: mujoco.MjsBody,
    name: str,
    image: np.ndarray,
    corners: Sequence[Sequence[float]],
    facing: Sequence[float],
    group: int,
    geom_name: str | None = None,
) -> mujoco.MjsGeom:
    """Add ``image`` (H, W, 3) uint8 RGB on the quad ``corners`` (4, 3) of ``body`` (its frame,
    m; top-left, top-right, bottom-right, bottom-left), seen from the side of the normal
    ``facing`` (3,); texture ``<name>_tex``, material ``<name>_mat``, mesh ``<name>_mesh``.
    Returns the geom ``geom_name`` (default ``<name>_visual``; visual only: no contacts, no
    mass)."""
    img = np.ascontiguousarray(image, dtype=np.uint8)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"{name}: image has shape {img.shape}; valid: (H, W, 3) uint8 RGB")
    tex = spec.add_texture(
        name=f"{name}_tex", type=mujoco.mjtTexture.mjTEXTURE_2D,
        width=img.shape[1], height=img.shape[0], nchannel=3,
    )  # fmt: skip
    tex.data = img.tobytes()
    mat = spec.add_material(name=f"{name}_mat", rgba=[1.0, 1.0, 1.0, 1.0], specular=0.0)
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = f"{name}_tex"
    c = np.asarray(corners, float).reshape(4, 3)
    # counter-clockwise seen from ``facing`` (the front face's normal points there), split
    # along the bottom-left to top-right diagonal
    ccw = np.dot(np.cross(c[1] - c[0], c[2] - c[0]), np.asarray(facing, float)) > 0
    faces = [3, 0, 1, 3, 1, 2] if ccw else [3, 2, 1, 3, 1, 0]
    spec.add_mesh(
        name=f"{name}_mesh", uservert=c.ravel().tolist(), userface=faces,
        usertexcoord=_TEXCOORDS,
    ).inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL  # fmt: skip
    return body.add_geom(
        name=geom_name or f"{name}_visual", type=mujoco.mjtGeom.mjGEOM_MESH,
        meshname=f"{name}_mesh",
        material=f"{name}_mat", contype=0, conaffinity=0, group=group, mass=0.0,
    )  # fmt: skip
