"""The simulated work cell for one layout: model building, places, and object status.

:func:`build_world` adds a layout's objects to the composed work cell and compiles it, with a
``home`` keyframe (CloPeMa home: all arm joints zero; the head gazing at the table; objects at
their layout poses). :class:`Places` reads every location the code needs from the model's
sites, so each is written once, in ``assets/scenes/workcell.xml``. :func:`object_status` is
ground truth for ``info`` and evaluation only: policies never see it.
:class:`PhysicsConfig` holds the physics options a version sets on top of the MJCF (none for
``Sorting-v0``/``-v1``; :data:`FAST_PHYSICS` for ``Sorting-v2``).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ipbench.assets.compose import HEAD_SIDES, build_workcell_spec, head_gaze
from ipbench.assets.objects import CATEGORIES, add_object
from ipbench.assets.objects.object_model import RELEASED_MODEL, ObjectModel
from ipbench.envs.layout import Layout

__all__ = [
    "Box",
    "FAST_PHYSICS",
    "PhysicsConfig",
    "Places",
    "World",
    "build_world",
    "object_status",
    "STATUSES",
]

STATUSES = ("on_table", "in_inspection_area", "in_hand", "dropped") + tuple(
    f"in_bin:{c}" for c in CATEGORIES
)
"""Every value :func:`object_status` can return."""


@dataclass(frozen=True)
class Box:
    """An axis-aligned box: ``center`` (3,) and ``half`` (3,) extents in the world (m)."""

    center: np.ndarray
    half: np.ndarray

    def contains(self, p: np.ndarray, margin: float = 0.0) -> bool:
        return bool(np.all(np.abs(np.asarray(p) - self.center) <= self.half + margin))


@dataclass(frozen=True)
class Places:
    """Locations of the work cell, from the model's sites (world frame, m)."""

    table_top: Box
    spawn_area: Box
    inspection_area: Box
    bins: dict[str, Box]
    present_point: np.ndarray
    present_view: np.ndarray
    scene_view: np.ndarray
    scene_target: np.ndarray
    inspection_view: np.ndarray
    head_target: np.ndarray

    @property
    def table_height(self) -> float:
        return float(self.table_top.center[2])

    @classmethod
    def from_model(cls, model: mujoco.MjModel) -> Places:
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)

        def point(name: str) -> np.ndarray:
            return data.site(name).xpos.copy()

        def box(name: str) -> Box:
            return Box(point(name), model.site(name).size.copy())

        return cls(
            table_top=box("work_table_top"),
            spawn_area=box("spawn_area"),
            inspection_area=box("inspection_area"),
            bins={c: box(f"bin_{c}") for c in CATEGORIES},
            present_point=point("present_point"),
            present_view=point("present_view"),
            scene_view=point("scene_view"),
            scene_target=point("scene_target"),
            inspection_view=point("inspection_view"),
            head_target=point("head_target"),
        )


@dataclass(frozen=True)
class PhysicsConfig:
    """Physics options applied on top of the work cell's MJCF (the defaults change nothing:
    the model is exactly the MJCF's, as ``Sorting-v0``/``-v1`` run it).

    Attributes
    ----------
    sleep : MuJoCo's sleeping islands (``mjENBL_SLEEP``): a kinematic tree (an object, or a
        pile of objects touching each other) whose velocities stay below ``sleep_tolerance``
        for 10 steps is frozen and left out of collision detection and the solver until
        something awake touches it, which wakes it within the same step. The robot is
        actuated and never sleeps. Objects resting on the table or in a bin then cost
        nothing while the arms move; what they do when touched is unchanged.
    sleep_tolerance : velocity below which a tree may sleep (m/s; rotations scaled by the
        tree's size); ``None`` keeps MuJoCo's default.
    """

    sleep: bool = False
    sleep_tolerance: float | None = None

    def apply_to_model(self, model: mujoco.MjModel) -> None:
        """The options of ``model.opt`` (set before any ``MjData`` of the episode is made:
        sleeping must be enabled when the data is created)."""
        if self.sleep:
            model.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_SLEEP)
            if self.sleep_tolerance is not None:
                model.opt.sleep_tolerance = self.sleep_tolerance


FAST_PHYSICS = PhysicsConfig(sleep=True, sleep_tolerance=1e-3)
"""``Sorting-v2``'s physics: objects at rest sleep (tested in ``tests/test_physics_v2.py``;
validated against v1's physics with the oracle on the cluttered scene)."""


@dataclass(frozen=True)
class World:
    """A compiled work cell with a layout's objects.

    Attributes
    ----------
    model : the compiled model (keyframe ``home``).
    layout : the layout it was built from.
    places : the work cell's locations.
    object_bodies : (n,) body id of each object, by object id.
    object_geoms : dict geom id -> object id (every geom of every object).
    """

    model: mujoco.MjModel
    layout: Layout
    places: Places
    object_bodies: np.ndarray
    object_geoms: dict[int, int]


def build_world(
    layout: Layout,
    spec: mujoco.MjSpec | None = None,
    physics: PhysicsConfig | None = None,
    objects: ObjectModel = RELEASED_MODEL,
) -> World:
    """Compile the work cell with ``layout``'s objects (``spec``: a fresh work cell spec;
    ``physics``: options on top of the MJCF, none by default; ``objects``: how the objects are
    modelled, the released ids' model by default)."""
    spec = spec if spec is not None else build_workcell_spec()
    for obj in layout.objects:
        add_object(spec, obj.instance, obj.body, pos=obj.position, quat=obj.quat, model=objects)
    spec.add_key(name="home")
    model = spec.compile()
    places = Places.from_model(model)
    _set_home_gaze(model, places.head_target)
    if physics is not None:  # after the kinematic helpers above, before the episode's data
        physics.apply_to_model(model)
    bodies = np.array([model.body(o.body).id for o in layout.objects], dtype=int)
    root_to_obj = {int(b): k for k, b in enumerate(bodies)}
    geoms = {
        g: root_to_obj[int(model.body_rootid[model.geom_bodyid[g]])]
        for g in range(model.ngeom)
        if int(model.body_rootid[model.geom_bodyid[g]]) in root_to_obj
    }
    return World(
        model=model, layout=layout, places=places, object_bodies=bodies, object_geoms=geoms
    )


def _set_home_gaze(model: mujoco.MjModel, target: np.ndarray, iterations: int = 4) -> None:
    """Point both head cameras at ``target`` in the ``home`` keyframe (qpos and ctrl).

    Starts from :func:`head_gaze` and corrects the pan and tilt by the remaining angular error
    of each camera's optical axis, measured by forward kinematics.
    """
    key = model.key("home").id
    data = mujoco.MjData(model)
    for k in range(iterations + 1):
        mujoco.mj_resetDataKeyframe(model, data, key)
        mujoco.mj_forward(model, data)  # camera frames too (mj_kinematics skips them)
        for side in HEAD_SIDES:
            base = model.body_parentid[model.body(f"head_{side}_pan_link").id]
            rot = data.xmat[base].reshape(3, 3)
            pan, tilt = head_gaze(data.xpos[base], rot, target)
            adr = [model.jnt_qposadr[model.joint(f"head_{side}_{j}").id] for j in ("pan", "tilt")]
            if k > 0:  # correct by the error of the camera's actual optical axis
                cam = data.cam(f"head_{side}_camera")
                now = head_gaze(np.zeros(3), rot, -cam.xmat.reshape(3, 3)[:, 2])
                want = head_gaze(cam.xpos, rot, target)
                pan = data.qpos[adr[0]] + want[0] - now[0]
                tilt = data.qpos[adr[1]] + want[1] - now[1]
            model.key_qpos[key, adr] = pan, tilt
    # Position servos hold the keyframe pose: ctrl = the joint each actuator drives.
    for a in range(model.nu):
        j = model.actuator_trnid[a, 0]
        model.key_ctrl[key, a] = model.key_qpos[key, model.jnt_qposadr[j]]


def object_status(world: World, data: mujoco.MjData, object_id: int, pads: tuple[int, int]) -> str:
    """Where an object is, from the simulation state (ground truth, for ``info`` only).

    ``pads`` are the geom ids of the two gripper pads: an object touched by both is in hand.
    """
    body = world.object_bodies[object_id]
    com = data.xipos[body]
    touching: set[int] = set()
    for c in data.contact[: data.ncon]:
        for mine, other in ((c.geom1, c.geom2), (c.geom2, c.geom1)):
            if world.object_geoms.get(int(mine)) == object_id:
                touching.add(int(other))
    if pads[0] in touching and pads[1] in touching:
        return "in_hand"
    for category, box in world.places.bins.items():
        # inside the walls, from the floor up to a pile of objects above the rim
        inside = np.all(np.abs(com[:2] - box.center[:2]) <= box.half[:2] + 0.01)
        if (
            inside
            and box.center[2] - box.half[2] - 0.01 <= com[2] <= box.center[2] + box.half[2] + 0.3
        ):
            return f"in_bin:{category}"
    table = world.places.table_top
    on_table = bool(
        np.all(np.abs(com[:2] - table.center[:2]) <= table.half[:2])
        and table.center[2] < com[2] < table.center[2] + 0.35
    )
    if on_table:
        area = world.places.inspection_area
        if np.all(np.abs(com[:2] - area.center[:2]) <= area.half[:2]):
            return "in_inspection_area"
        return "on_table"
    return "dropped"
