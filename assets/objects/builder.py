"""Add an instance to a :class:`mujoco.MjSpec` as a free body with visual and collision geoms.

Conventions other code can rely on:

* visual geoms: meshes, ``group=2``, ``contype=conaffinity=0``, zero mass;
* collision geoms: ``group=3`` (hidden by default), ``contype=conaffinity=1``,
  ``condim=3``, friction ``FRICTION``, transparent (alpha 0);
* a glazed (shiny) surface is a visual geom whose material has
  ``specular >= SPECULAR_THRESHOLD``; every other material has ``specular < 0.3``;
* the body inertia is explicit (``inst.mass`` exactly), so geoms never change it;
* a visual part with a texture (v2 catalogue) gets an RGB 2D texture ``<prefix>_tex`` (one
  per distinct image of the instance) and a white material that maps it through the mesh's
  texture coordinates; parts without one (every v1 part) are built exactly as before;
* every element is named with the body name as prefix (``<name>_...``).
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from ipbench.assets.objects.catalog import ObjectCatalogError
from ipbench.assets.objects.geometry import object_geometry
from ipbench.assets.objects.instance import ObjectInstance
from ipbench.assets.objects.object_model import RELEASED_MODEL, ObjectModel

__all__ = [
    "add_object",
    "SPECULAR_THRESHOLD",
    "FRICTION",
    "VISUAL_GROUP",
    "COLLISION_GROUP",
]

SPECULAR_THRESHOLD: float = 0.5
"""Material specular at or above which a visual geom counts as shiny (glazed)."""

FRICTION: tuple[float, float, float] = (0.8, 0.01, 0.001)
"""Sliding, torsional and rolling friction of the collision geoms."""

VISUAL_GROUP: int = 2
COLLISION_GROUP: int = 3

_SHINY = {"specular": 0.8, "shininess": 0.9}
_MATTE = {"specular": 0.15, "shininess": 0.2}
_KINDS = {
    "box": mujoco.mjtGeom.mjGEOM_BOX,
    "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
    "capsule": mujoco.mjtGeom.mjGEOM_CAPSULE,
    "mesh": mujoco.mjtGeom.mjGEOM_MESH,
}


def _quat(rot: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(rot, dtype=float).ravel())
    return q


def _add_texture(spec: mujoco.MjSpec, name: str, image: np.ndarray) -> None:
    """An RGB 2D texture from an (H, W, 3) uint8 image (row 0 at v = 0)."""
    img = np.ascontiguousarray(image, dtype=np.uint8)
    tex = spec.add_texture(
        name=name,
        type=mujoco.mjtTexture.mjTEXTURE_2D,
        width=img.shape[1],
        height=img.shape[0],
        nchannel=3,
    )
    tex.data = img.tobytes()


def add_object(
    spec: mujoco.MjSpec,
    inst: ObjectInstance,
    name: str,
    pos: Sequence[float] = (0.0, 0.0, 0.0),
    quat: Sequence[float] = (1.0, 0.0, 0.0, 0.0),
    model: ObjectModel = RELEASED_MODEL,
) -> mujoco.MjsBody:
    """Add ``inst`` to ``spec.worldbody`` as a free body called ``name``.

    Parameters
    ----------
    spec : the model being built.
    inst : the instance (:func:`~ipbench.assets.objects.get_instance`).
    name : body name, also the prefix of every mesh, material and geom it adds; the free
        joint is ``f"{name}_freejoint"``.
    pos : (3,) world position of the object frame (bottom centre), m.
    quat : (4,) world orientation (w, x, y, z).
    model : how the instance is modelled (collision geometry of hollow objects, print
        orientation); the default is the released ids' model.

    Returns
    -------
    The new body.

    Raises
    ------
    ObjectCatalogError
        If ``inst`` is not an :class:`ObjectInstance` or ``name`` is empty or already used.
    """
    if not isinstance(inst, ObjectInstance):
        raise ObjectCatalogError(f"inst must be an ObjectInstance, got {type(inst).__name__}")
    if not name or spec.body(name) is not None:
        raise ObjectCatalogError(f"body name {name!r} is empty or already used in the spec")
    geo = object_geometry(inst, model)
    body = spec.worldbody.add_body(name=name, pos=list(pos), quat=list(quat))
    body.add_freejoint(name=f"{name}_freejoint")
    body.explicitinertial = True
    body.mass = inst.mass
    body.ipos = geo.com
    i = geo.inertia
    body.fullinertia = [i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2]]

    textures: dict[int, str] = {}  # id of an image -> its texture's name
    for part in geo.visual:
        prefix = f"{name}_{part.suffix}"
        mesh = spec.add_mesh(
            name=f"{prefix}_mesh",
            uservert=part.vertices.ravel().tolist(),
            userface=part.faces.ravel().tolist(),
        )
        mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
        if part.texture is None:
            spec.add_material(
                name=f"{prefix}_mat", rgba=list(part.rgba), **(_SHINY if part.shiny else _MATTE)
            )
        else:
            mesh.usertexcoord = np.asarray(part.texcoords, float).ravel().tolist()
            texname = textures.get(id(part.texture))
            if texname is None:
                texname = textures[id(part.texture)] = f"{prefix}_tex"
                _add_texture(spec, texname, part.texture)
            material = spec.add_material(
                name=f"{prefix}_mat",
                rgba=[1.0, 1.0, 1.0, 1.0],
                **(_SHINY if part.shiny else _MATTE),
            )
            material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = texname
        body.add_geom(
            name=f"{prefix}_visual",
            type=mujoco.mjtGeom.mjGEOM_MESH,
            meshname=f"{prefix}_mesh",
            material=f"{prefix}_mat",
            group=VISUAL_GROUP,
            contype=0,
            conaffinity=0,
            mass=0.0,
        )

    for k, prim in enumerate(geo.collision):
        geom = body.add_geom(
            name=f"{name}_collision{k:02d}",
            type=_KINDS[prim.kind],
            pos=prim.pos,
            quat=_quat(prim.rot),
            group=COLLISION_GROUP,
            contype=1,
            conaffinity=1,
            condim=3,
            friction=list(FRICTION),
            rgba=[0.5, 0.5, 0.5, 0.0],
        )
        if prim.kind == "mesh":
            mesh = spec.add_mesh(
                name=f"{name}_collision{k:02d}_mesh",
                uservert=prim.mesh[0].ravel().tolist(),
                userface=prim.mesh[1].ravel().tolist(),
            )
            mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_CONVEX
            geom.meshname = mesh.name
        else:
            size = list(prim.size) + [0.0] * (3 - len(prim.size))
            geom.size = size
    return body
