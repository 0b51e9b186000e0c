"""A calibration target plate held rigidly by the gripper (thesis ch. 4: the robot presents a
24 mm checkerboard to its cameras; the thesis used the arm to automate the sampling).

The plate is a thin box (visual only: no contacts, no mass, as the room's posters of
:mod:`ipbench.assets.room`) with a textured quad on its front face, fixed to the body that
carries ``parent_site`` (by default the gripper's tool centre point ``left_gripper_tcp``). This
module does not know what the texture shows: the caller passes the image and the size in
metres it spans (for the checkerboard, ``Checkerboard.render_texture`` and
``Checkerboard.size_m`` of :mod:`ipbench.perception.calibration.target`) and where the
target's own frame sits on it.

Frames (``a_to_b`` maps frame ``a``'s coordinates to frame ``b``'s, as
:mod:`ipbench.perception.calibration.poses`):

- **plate frame**: origin at the top-left corner of the face (the texture's pixel edge
  ``(u, v) = (-0.5, -0.5)``), x along the texture's columns (u, right), y along its rows
  (v, down), z into the plate (away from a viewer of the face). This is OpenCV's target
  convention, so a target whose origin is at ``origin_m = (x0, y0)`` on the face (metres from
  the top-left corner) has ``plate_from_board`` = a pure translation by ``(x0, y0, 0)``.
- **in the parent site's frame** (the gripper TCP: +z out of the gripper, jaws closing along
  +-x): the plate lies in the TCP's y-z plane, its face looking along +x (the plate is centred
  on the jaws' plane, the face ``thickness_m / 2`` ahead of it), extending from
  ``standoff_m`` to ``standoff_m + height`` along +z, centred in y; the texture's rows run
  towards the gripper (plate y = TCP -z) and its columns along TCP +y. So plate x = TCP +y,
  plate y = TCP -z, plate z = TCP -x.

``standoff_m`` (default 0.03 m) keeps the fingers (which reach about 0.02 m past the TCP)
off the printed area: the plate is held by a clamp on a short stem, a rigid mount, as a
target should be. Its thickness (default 4 mm) is that of a typical rigid target board
(aluminium composite or glass); neither value enters any measurement except through the
returned transforms.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ipbench.assets.quads import add_textured_quad

__all__ = ["TargetPlate", "TargetPlateError", "add_target_plate"]

_VISUAL_GROUP = 2  # rendered by the sensors (groups 0-2), never a collision geom
_FACE_GAP = 2e-4  # the box's front face sits this far behind the textured quad (m): no z-fight


class TargetPlateError(ValueError):
    """Bad arguments to :func:`add_target_plate`; the message says which and how to fix them."""


@dataclass(frozen=True, eq=False)
class TargetPlate:
    """A target plate added to a spec.

    Attributes
    ----------
    body : str
        Name of the plate's body (child of the parent site's body, no joint).
    parent_site : str
        The site it is fixed to.
    size_m : (float, float)
        (width, height) of the face, m.
    thickness_m : float
        Plate thickness, m.
    plate_from_board : (4, 4) float64 array
        Target (board) frame to plate frame, m (module docstring).
    site_from_plate : (4, 4) float64 array
        Plate frame to the parent site's frame, m.
    """

    body: str
    parent_site: str
    size_m: tuple[float, float]
    thickness_m: float
    plate_from_board: np.ndarray
    site_from_plate: np.ndarray

    @property
    def site_from_board(self) -> np.ndarray:
        """(4, 4) target frame to the parent site's frame, m."""
        return self.site_from_plate @ self.plate_from_board


def _positive(value, name: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise TargetPlateError(f"{name} must be a number in m, got {value!r}") from None
    if not (np.isfinite(number) and number > 0):
        raise TargetPlateError(f"{name} must be a positive length in m, got {value!r}")
    return number


def _texture(texture) -> np.ndarray:
    image = np.asarray(texture)
    if image.dtype != np.uint8:
        raise TargetPlateError(f"texture must be uint8 (0-255), got {image.dtype}")
    if image.ndim == 2:
        image = np.repeat(image[:, :, None], 3, axis=2)
    if image.ndim != 3 or image.shape[2] != 3 or min(image.shape[:2]) < 2:
        raise TargetPlateError(
            f"texture must be (H, W) grey or (H, W, 3) RGB with H, W >= 2, got {image.shape}"
        )
    return np.ascontiguousarray(image)


def add_target_plate(
    spec: mujoco.MjSpec,
    texture: np.ndarray,
    size_m: tuple[float, float],
    parent_site: str = "left_gripper_tcp",
    origin_m: tuple[float, float] = (0.0, 0.0),
    thickness_m: float = 0.004,
    standoff_m: float = 0.03,
    name: str = "calibration_target",
) -> TargetPlate:
    """Add a textured plate fixed to ``parent_site``'s body; returns its frames.

    texture : (H, W) or (H, W, 3) uint8 image printed on the face, row 0 at the top.
    size_m : (width, height) the image spans on the face, m.
    origin_m : (x, y) of the target frame's origin on the face, m from the top-left corner
        (the target's x and y axes are the plate's, see the module docstring).
    """
    image = _texture(texture)
    try:
        w, h = (_positive(v, f"size_m[{i}]") for i, v in enumerate(size_m))
    except TypeError:
        raise TargetPlateError(f"size_m must be (width, height) in m, got {size_m!r}") from None
    t = _positive(thickness_m, "thickness_m")
    standoff = float(standoff_m)
    if not (np.isfinite(standoff) and standoff >= 0):
        raise TargetPlateError(f"standoff_m must be >= 0 m, got {standoff_m!r}")
    origin = np.asarray(origin_m, dtype=np.float64)
    if origin.shape != (2,) or not np.isfinite(origin).all():
        raise TargetPlateError(f"origin_m must be (x, y) in m, got {origin_m!r}")
    site = spec.site(parent_site)
    if site is None:
        sites = sorted(s.name for s in spec.sites if s.name)
        raise TargetPlateError(f"unknown parent_site {parent_site!r}; valid: {sites}")
    if spec.body(name) is not None:
        raise TargetPlateError(f"the spec already has a body {name!r}; pass another name")

    # plate axes in the site frame (columns): x = +y_site, y = -z_site, z = -x_site
    site_from_plate = np.eye(4)
    site_from_plate[:3, :3] = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    site_from_plate[:3, 3] = (t / 2, -w / 2, standoff + h)
    plate_from_board = np.eye(4)
    plate_from_board[:2, 3] = origin

    # the plate body sits at the site's pose composed with site_from_plate
    site_rot = np.zeros(9)
    mujoco.mju_quat2Mat(site_rot, np.asarray(site.quat, np.float64))
    parent_from_site = np.eye(4)
    parent_from_site[:3, :3] = site_rot.reshape(3, 3)
    parent_from_site[:3, 3] = site.pos
    parent_from_plate = parent_from_site @ site_from_plate
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, parent_from_plate[:3, :3].ravel())

    parent = spec.body(site.parent.name) if site.parent.name else spec.worldbody
    body = parent.add_body(name=name, pos=parent_from_plate[:3, 3].tolist(), quat=quat.tolist())
    # face quad at plate z = 0, seen from the front (-z: the face looks along the plate's -z)
    corners = [(0.0, 0.0, 0.0), (w, 0.0, 0.0), (w, h, 0.0), (0.0, h, 0.0)]
    add_textured_quad(spec, body, name, image, corners, (0.0, 0.0, -1.0), _VISUAL_GROUP,
                      geom_name=f"{name}_face")  # fmt: skip
    body.add_geom(
        name=f"{name}_plate", type=mujoco.mjtGeom.mjGEOM_BOX, size=[w / 2, h / 2, t / 2],
        pos=[w / 2, h / 2, t / 2 + _FACE_GAP], rgba=[0.55, 0.57, 0.6, 1.0],
        contype=0, conaffinity=0, group=_VISUAL_GROUP, mass=0.0,
    )  # fmt: skip
    return TargetPlate(
        body=name,
        parent_site=parent_site,
        size_m=(w, h),
        thickness_m=t,
        plate_from_board=plate_from_board,
        site_from_plate=site_from_plate,
    )
