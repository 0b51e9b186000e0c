"""The settings of a sorting episode, and what each version of ``ipbench/Sorting`` fixes.

:class:`SortingConfig` holds every setting of :class:`~ipbench.envs.sorting.SortingEnv` (the
keyword arguments of ``gym.make``); :data:`V0`, :data:`V2` and :data:`V3` are the overrides that
make ``Sorting-v0``, ``-v2`` and ``-v3`` out of the v1 defaults (registered in
:mod:`ipbench.envs`). A released id's settings never change: a change is a new version.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ipbench.assets.compose import BIN_INTERIOR
from ipbench.assets.objects.object_model import ObjectModel
from ipbench.envs.cell.extrinsics import check_extrinsics
from ipbench.envs.robot import MotionConfig
from ipbench.envs.sensors.depth_noise import STRUCTURED_LIGHT, DepthNoiseConfig
from ipbench.envs.skill_config import V3_SKILLS, SkillConfig
from ipbench.envs.world import FAST_PHYSICS, PhysicsConfig

__all__ = ["CAMERAS", "V0", "V2", "V3", "SortingConfig", "check_cameras"]

CAMERAS: tuple[str, ...] = ("wrist", "head")
"""The cameras an observation can hold (:attr:`SortingConfig.cameras`), in this order:
``"wrist"``: the camera arm's RGB-D camera (``wrist_rgb``, ``wrist_depth``, ``wrist_K``,
``wrist_pose``; and ``info["wrist_mask"]``); ``"head"``: the head's stereo pair (``head_left``,
``head_right``, ``head_left_K``, ``head_left_pose``, ``head_right_K``, ``head_right_pose``)."""


def check_cameras(cameras) -> tuple[str, ...]:
    """``cameras`` checked and in :data:`CAMERAS` order; a clear error listing the valid ones."""
    valid = f"valid: a non-empty tuple of {', '.join(map(repr, CAMERAS))}, e.g. ('wrist',)"
    if isinstance(cameras, str) or not isinstance(cameras, (tuple, list)):
        raise ValueError(f"cameras must be a tuple of camera names, got {cameras!r}; {valid}")
    unknown = [c for c in cameras if c not in CAMERAS]
    if unknown or not cameras or len(set(cameras)) != len(cameras):
        what = f"unknown camera(s) {unknown}" if unknown else "no camera or one named twice"
        raise ValueError(f"cameras={tuple(cameras)!r}: {what}; {valid}")
    return tuple(c for c in CAMERAS if c in cameras)


@dataclass(frozen=True)
class SortingConfig:
    """Settings of a sorting episode (defaults are the benchmark's).

    Attributes
    ----------
    scene : ``"uncluttered"`` or ``"cluttered"`` (thesis Table 5.1); with the v2 catalogue
        also ``"pile"`` (:data:`~ipbench.envs.sorting_scenes.SCENES`).
    head_size : (height, width) of each head image, px (D5100-like 3:2).
    render_size : (height, width) of ``render()`` frames from the overview camera, px.
    max_steps : step limit (truncation); ``None`` = 4 per object + 10.
    step_cost : reward cost of each skill.
    settle_time : physics time at reset for the objects to settle (s).
    depth_noise : the wrist camera's noise model; ``DepthNoiseConfig(enabled=False)`` for
        ideal depth.
    motion, skills : robot motion and skill settings.
    jaw_opening : the action has an ``opening`` (the gripper pre-shapes to it before a
        pick); without it every pick opens the jaws fully (``Sorting-v0``).
    undo_blowups : a step during which the contact solver blew up (an object faster than
        :data:`~ipbench.envs.sorting.MAX_OBJECT_SPEED`, a non-finite state or a MuJoCo warning) is
        rolled back and its skill reported as failed, instead of truncating the episode
        (``Sorting-v0``).
    finger_armature : reflected inertia of each gripper finger's drive (kg); ``None`` keeps
        the model's (``assets/motoman/gripper.xml``).
    bin_depth : inside depth of the bins (m).
    bin_floor_backing : how much thicker each bin's 1 cm floor is, downwards, inside the bin
        table (m; ``Sorting-v3``: 0.04, so that a bowl's foot or a mug's handle dropped into a
        bin cannot pass the floor's mid-plane and stick in it, as it can with 0, every released
        id: :func:`~ipbench.assets.compose.build_workcell_spec`).
    catalog : the object catalogue (``"v1"``: one shape family per category, flat colours;
        ``"v2"``: several real-product families per category with printed textures; see
        :mod:`ipbench.assets.objects`).
    cameras : the cameras rendered into the observation, a non-empty tuple of
        :data:`CAMERAS` (a list is taken as a tuple; stored in :data:`CAMERAS` order; a plain
        string is an error). A camera not named is not rendered and its keys are absent from
        the observation and its space; the other keys and the environment's random stream
        are those of the default. Without ``"wrist"`` the wrist's depth noise is not drawn
        either (and ``info`` has no ``wrist_mask``), so an unseeded ``reset()`` after an
        episode then lays out other objects than the default would; seeded resets agree.
    pick_command : the action's ``command`` has a fourth value,
        :data:`~ipbench.envs.sorting.PICK` (``Sorting-v2``).
    physics : physics options on top of the work cell's MJCF
        (:class:`~ipbench.envs.world.PhysicsConfig`; the default changes nothing, as v0/v1
        run; ``Sorting-v2``: :data:`~ipbench.envs.world.FAST_PHYSICS`, objects at rest
        sleep).
    extrinsics : what the robot knows of its cameras (:mod:`ipbench.envs.cell.extrinsics`):
        ``"true"`` (default; every released id: the simulator's values, the world as before),
        ``"nominal"`` or ``"calibrated"``: the world is the true cell of ``robot_seed``
        (:func:`~ipbench.envs.cell.model_errors.sample_model_errors`; images distorted by its
        lenses, RGB bilinear, depth and ``wrist_mask`` nearest), ``*_K``/``*_pose`` are the
        robot's beliefs, and the observation gains ``wrist_dist``/``head_*_dist`` (5,), the
        distortion the robot believes (zeros for ``nominal``).
    robot_seed : seed of the true cell's model errors (``nominal``/``calibrated`` only).
    objects : how the objects are modelled
        (:class:`~ipbench.assets.objects.object_model.ObjectModel`: collision geometry of
        hollow objects, print orientation); the default is every released id's.
    keep_area_after_failed_pick : when a pick of the object in the inspection area fails and
        it is still there, the env keeps track of it, and the next command that needs an
        object in hand tries the area again (``Sorting-v3``); otherwise (released ids) the env
        forgets it and that command picks at the action's ``position``.
    calibration : path of a calibration file (``ipbench calibrate --robot-seed R``) for
        ``extrinsics="calibrated"``; None otherwise.
    """

    scene: str = "uncluttered"
    head_size: tuple[int, int] = (680, 1024)
    render_size: tuple[int, int] = (480, 640)
    max_steps: int | None = None
    step_cost: float = 0.01
    settle_time: float = 0.3
    depth_noise: DepthNoiseConfig = field(default_factory=DepthNoiseConfig)
    motion: MotionConfig = field(default_factory=MotionConfig)
    skills: SkillConfig = field(default_factory=SkillConfig)
    jaw_opening: bool = True
    undo_blowups: bool = True
    finger_armature: float | None = None
    bin_depth: float = BIN_INTERIOR[2]
    bin_floor_backing: float = 0.0
    catalog: str = "v1"
    cameras: tuple[str, ...] = CAMERAS
    physics: PhysicsConfig = field(default_factory=PhysicsConfig)
    pick_command: bool = False
    extrinsics: str = "true"
    robot_seed: int = 0
    calibration: str | None = None
    objects: ObjectModel = field(default_factory=ObjectModel)
    keep_area_after_failed_pick: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "cameras", check_cameras(self.cameras))
        check_extrinsics(self.extrinsics, self.calibration, self.robot_seed)


V0: dict = {
    "jaw_opening": False,
    "undo_blowups": False,
    "finger_armature": 0.05,
    "bin_depth": 0.24,
    "skills": SkillConfig(close_time=0.45, finger_speed=None, guard_force=None),
}
"""The settings ``Sorting-v0`` fixes: no jaw pre-shaping, blind descents, fingers stepped
shut, light fingers, 24 cm deep bins, and a blow-up truncates the episode."""

V2: dict = {
    "catalog": "v2",
    "depth_noise": STRUCTURED_LIGHT,
    "physics": FAST_PHYSICS,
    "pick_command": True,
}
"""The settings ``Sorting-v2`` adds to v1: the v2 object catalogue (real
product families, printed textures, train / similar / novel splits), structured-light
depth as the sensor makes it (projector shadow, disparity block matching, per-unit error),
faster physics (:data:`~ipbench.envs.world.FAST_PHYSICS`: objects at rest sleep), and the
:data:`~ipbench.envs.sorting.PICK` command."""

V3: dict = {
    **V2,
    "objects": ObjectModel(hollow_collision="convex", upright_prints=True),
    "keep_area_after_failed_pick": True,
    "bin_floor_backing": 0.04,
    "skills": V3_SKILLS,
}
"""The settings ``Sorting-v3`` (under development) changes from v2: picks that descend and lift
on straight lines and correct themselves from what the arm senses
(:data:`~ipbench.envs.skills.V3_SKILLS`), bowls and mugs collide as
a few convex pieces each instead of rings of boxes, printed textures read upright, bin floors
are thick enough that nothing dropped into a bin sticks in them, and the env
keeps track of the object in the inspection area after a failed re-pick."""
