"""The hand-eye study of ``ipbench eval calibration`` (thesis ch. 4), synthetic.

Because a simulation knows the true hand-eye transform ``X``, every calibration can be scored
against it: the rotation (deg) and translation (mm) error of ``X`` per camera and method
(:data:`~ipbench.perception.calibration.hand_eye.HAND_EYE_METHODS`), against the number of
poses and against how far the gripper turns between poses (the rotation diversity; small
turns break Tsai, which the study shows).

The study works on poses, not images: the observed ``target_to_camera`` poses carry the noise
of OpenCV's own hand-eye regression test (``modules/calib3d/test/test_calibration_hand_eye.cpp``):
target 0.002 rad / 5 mm, gripper 0.001 rad / 1 mm, per axis, scaled by the config's
``noise_scales``. A rotation is perturbed by ``Exp(n) R``, ``n ~ N(0, σ² I)``, a
translation by ``N(0, σ² I)`` (OpenCV adds ``N(0, σ²)`` to each Rodrigues component, which
turns the rotation by as much or, off its axis, by ``sin(θ/2) / (θ/2)`` times less). Whether
the board is inside the image, and whether the arm reaches a pose, is not modelled.

Rigs (:class:`HandEyeRig`), in the cell's world frame (CloPeMa's r750 frame at turntable
angle 0 on the floor, ``assets/scenes/workcell.xml``; the turntable stays at 0):

- ``wrist``: eye in hand, the Xtion on the right arm (:data:`WRIST_RIG`). ``X`` is
  camera-to-flange, the flange frame taken with joint T at 0 (the Xtion is on link B:
  ``assets/motoman/xtion.xml``), ``|t| = 0.122 m``. The board lies on the work table; the camera
  presents itself 0.8 m above it, looking down (the near end of the ASUS Xtion datasheet's 0.8-3.5 m
  range).
- ``head_left``: eye to hand, the left Nikon of the PTU head at pan = tilt = 0
  (:data:`HEAD_LEFT_RIG`). ``X`` is camera-to-world, the camera 2.362 m above the floor,
  pitched 35.6° down (``assets/motoman/motoman.xml``, ``assets/head/ptu_d46.xml``). The
  gripper (the left arm's flange frame) holds the board by its left margin, 1.0 m in front
  of the camera, facing it.

Each trial draws ``n`` gripper poses about the rig's nominal presenting pose: orientation
``R_nom Exp(θ a)`` with ``a`` uniform on the unit sphere and ``θ`` uniform in ``[0, spread]``;
position uniform in a box of :attr:`HandEyeRig.position_half_extents_m` about the nominal one.
The main study uses :attr:`HandEyeStudyConfig.rotation_spread_deg`, 45° (the upper end of
OpenCV's test's gripper rotations, 5°-45°), fixed before any result was seen. The draws are
shared (paired) across methods, pose counts (the first ``n`` poses), noise scales (the same
unit noise, scaled) and spreads (the same unit angles, scaled), so differences come from the
factor varied. A :class:`~ipbench.perception.calibration.errors.CalibrationError` (the motion
check refusing the poses) is a failure: counted and reported, never dropped silently.
"""

from __future__ import annotations

import contextlib
import math
import time
import zlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy.spatial.transform import Rotation
from threadpoolctl import threadpool_limits

from ipbench.perception.calibration.errors import CalibrationError
from ipbench.perception.calibration.hand_eye import (
    HAND_EYE_METHODS,
    MIN_POSES,
    SETUPS,
    calibrate_hand_eye,
)
from ipbench.perception.calibration.poses import (
    as_transform,
    rotation_angle_deg,
    translation_error_mm,
)
from ipbench.perception.calibration.target import Checkerboard

__all__ = [
    "GRIPPER_NOISE",
    "HEAD_LEFT_RIG",
    "TARGETS",
    "TARGET_NOISE",
    "WRIST_RIG",
    "CalibrationStudyError",
    "HandEyeRig",
    "HandEyeStudyConfig",
    "metrics_view",
    "run_hand_eye_study",
]

TARGET_NOISE = (0.002, 0.005)
"""Target-to-camera noise per axis (rad, m): OpenCV's hand-eye regression test."""
GRIPPER_NOISE = (0.001, 0.001)
"""Gripper-to-base noise per axis (rad, m): OpenCV's hand-eye regression test."""
TARGETS = {"min_poses": 10, "noise_scale": 0.1, "rotation_deg": 0.02, "translation_mm": 1.5}
"""The hand-eye target: with >= 10 poses at 0.1x OpenCV's noise, <= 0.02° and 1.5 mm."""
METRICS_POSES, METRICS_NOISE_SCALE = 10, 1.0  # the cell metrics.json reports
_FLAGS = {m: getattr(cv2, f"CALIB_HAND_EYE_{m.upper()}") for m in HAND_EYE_METHODS}


class CalibrationStudyError(ValueError):
    """Bad study settings or study dict; the message says what is valid."""


def _transform(R, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def _inverse(T: np.ndarray) -> np.ndarray:
    """Inverse of (..., 4, 4) rigid transforms."""
    out = np.zeros_like(T)
    out[..., :3, :3] = np.swapaxes(T[..., :3, :3], -1, -2)
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", out[..., :3, :3], T[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


@dataclass(frozen=True, eq=False)
class HandEyeRig:
    """One camera's calibration set-up and its true geometry.

    Attributes
    ----------
    name : str
        The camera (as in the observation: ``wrist``, ``head_left``).
    setup : str
        ``eye_in_hand`` or ``eye_to_hand`` (``hand_eye.SETUPS``).
    X : (4, 4) float array
        The truth: camera-to-gripper (eye in hand) or camera-to-base (eye to hand), m; the
        camera frame is OpenCV's (x right, y down, z along the optical axis).
    fixed : (4, 4) float array
        ``Z``: target-to-base (eye in hand) or target-to-gripper (eye to hand), m.
    nominal_target_to_camera : (4, 4) float array
        The target as the camera sees it at the nominal presenting pose, m.
    position_half_extents_m : (3,) floats
        Half sizes of the box of gripper positions about the nominal one (base axes), m.
    """

    name: str
    setup: str
    X: np.ndarray
    fixed: np.ndarray
    nominal_target_to_camera: np.ndarray
    position_half_extents_m: tuple[float, float, float]

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise CalibrationStudyError(f"rig name {self.name!r}; valid: a non-empty string")
        if self.setup not in SETUPS:
            raise CalibrationStudyError(
                f"rig {self.name!r}: setup {self.setup!r}; valid: {', '.join(SETUPS)}"
            )
        for attr in ("X", "fixed", "nominal_target_to_camera"):
            try:
                T = as_transform(getattr(self, attr), f"rig {self.name!r} {attr}").copy()
            except CalibrationError as error:
                raise CalibrationStudyError(str(error)) from error
            T.flags.writeable = False
            object.__setattr__(self, attr, T)
        half = tuple(float(h) for h in np.ravel(self.position_half_extents_m))
        if len(half) != 3 or not all(math.isfinite(h) and h >= 0 for h in half):
            raise CalibrationStudyError(
                f"rig {self.name!r}: position_half_extents_m {self.position_half_extents_m!r}; "
                "valid: three finite lengths >= 0, m"
            )
        object.__setattr__(self, "position_half_extents_m", half)

    @property
    def nominal_gripper_to_base(self) -> np.ndarray:
        """(4, 4) gripper pose, m, at which the camera sees :attr:`nominal_target_to_camera`."""
        T_tc = self.nominal_target_to_camera
        if self.setup == "eye_in_hand":  # gripper X T_tc = Z
            return self.fixed @ _inverse(T_tc) @ _inverse(self.X)
        return self.X @ T_tc @ _inverse(self.fixed)  # gripper^-1 X T_tc = Z

    def target_to_camera(self, gripper_to_base: np.ndarray) -> np.ndarray:
        """(n, 4, 4) exact target poses in the camera for (n, 4, 4) gripper poses, m."""
        X_inv = _inverse(self.X)
        if self.setup == "eye_in_hand":
            return X_inv @ _inverse(gripper_to_base) @ self.fixed
        return X_inv @ gripper_to_base @ self.fixed

    def as_dict(self) -> dict:
        """JSON-ready copy (matrices as lists of rows)."""
        return {
            "name": self.name,
            "setup": self.setup,
            "X": self.X.tolist(),
            "fixed": self.fixed.tolist(),
            "nominal_target_to_camera": self.nominal_target_to_camera.tolist(),
            "position_half_extents_m": list(self.position_half_extents_m),
        }


def _board_centre() -> np.ndarray:
    """Centre of the inner-corner grid in the target frame, m (9 x 6 corners, 24 mm)."""
    board = Checkerboard()
    return np.array([(board.cols - 1) / 2, (board.rows - 1) / 2, 0.0]) * board.square_m


def _wrist_rig() -> HandEyeRig:
    # xtion.xml / ma1400.xml: the camera 0.12 m ahead of the tool axis, 0.024 m behind the
    # flange face, looking along the tool axis; image x along the flange's y
    X = _transform([[0, -1, 0], [1, 0, 0], [0, 0, 1]], [0.12, 0.0, -0.024])
    # board face up on the work table, corner grid centred on its top (0.95, -0.1, 0.70)
    # (workcell.xml; CloPeMa table height 0.70 m, clopema_UG.urdf.xacro); z into the table
    R_Z = np.diag([1.0, -1.0, -1.0])
    Z = _transform(R_Z, np.array([0.95, -0.1, 0.70]) - R_Z @ _board_centre())
    # camera 0.8 m above the board, looking down (Xtion range 0.8-3.5 m, ASUS datasheet)
    nominal = _transform(np.eye(3), np.array([0.0, 0.0, 0.8]) - _board_centre())
    # [EST] the camera stays 0.7-0.9 m from the board, the board near the image centre
    return HandEyeRig("wrist", "eye_in_hand", X, Z, nominal, (0.15, 0.15, 0.10))


def _head_left_rig() -> HandEyeRig:
    # motoman.xml: head_left_mount at (-0.523, 0.144, 1.77) on r750 (0.521 m above the floor),
    # pitched 35.6° down; ptu_d46.xml at pan = tilt = 0: the camera 0.134 m ahead of and
    # 0.0468 + 0.0449 + 0.0916 = 0.1833 m above the PTU base, looking along the base's +x
    mount = _transform(
        Rotation.from_euler("y", 35.6, degrees=True).as_matrix(), [-0.523, 0.144, 0.521 + 1.77]
    )
    optical = _transform([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], [0.134, 0.0, 0.1833])
    X = mount @ optical
    # gripper.xml: the jaws close along the flange's x (the board normal), the TCP is 0.225 m
    # out. [EST] The left arm holds the board from the robot's left by the margin of its left
    # edge (as the camera sees it), the pads from 0.205 m, the tool axis along the board's
    # rows: the first inner corner a margin and a square further out, the grid centred on it
    square = Checkerboard().square_m
    Z = _transform(
        [[0, 0, 1], [0, -1, 0], [1, 0, 0]], [0.0, _board_centre()[1], 0.205 + 2 * square]
    )
    # board facing the camera 1.0 m away, in front of the head in the gripper arm's reach
    # (MA1400 reach 1.434 m, Yaskawa datasheet and the CloPeMa DH table)
    nominal = _transform(np.eye(3), np.array([0.0, 0.0, 1.0]) - _board_centre())
    return HandEyeRig("head_left", "eye_to_hand", X, Z, nominal, (0.15, 0.15, 0.15))


WRIST_RIG = _wrist_rig()
"""Eye in hand: the right arm's Xtion (see the module docstring)."""
HEAD_LEFT_RIG = _head_left_rig()
"""Eye to hand: the head's left camera, the board in the left arm's gripper."""


def _key(value: float) -> str:
    """The study's dict key of a pose count, noise scale or spread: ``f"{value:g}"``."""
    return f"{value:g}"


@dataclass(frozen=True)
class HandEyeStudyConfig:
    """What the hand-eye study runs (defaults: the evaluation's, about 10 s on one core).

    Attributes
    ----------
    pose_counts : poses per calibration (each >= 3).
    noise_scales : multiples of OpenCV's test noise (:data:`TARGET_NOISE`,
        :data:`GRIPPER_NOISE`), each >= 0.
    trials : independent pose sets per cell.
    methods : hand-eye methods of the main study.
    rotation_spread_deg : largest gripper rotation about the nominal orientation in the main
        study, deg, in (0, 180].
    diversity_spreads_deg : the spreads of the diversity sweep, deg, each in (0, 180].
    diversity_methods, diversity_poses, diversity_noise_scale : its methods, pose count and
        noise scale.
    seed : seeds every draw.
    rigs : the cameras, unique names.
    """

    pose_counts: tuple[int, ...] = (3, 5, 10, 20)
    noise_scales: tuple[float, ...] = (1.0, 0.1)
    trials: int = 50
    methods: tuple[str, ...] = HAND_EYE_METHODS
    rotation_spread_deg: float = 45.0
    diversity_spreads_deg: tuple[float, ...] = (2.0, 5.0, 10.0, 20.0, 45.0)
    diversity_methods: tuple[str, ...] = ("tsai", "park")
    diversity_poses: int = 10
    diversity_noise_scale: float = 1.0
    seed: int = 0
    rigs: tuple[HandEyeRig, ...] = field(default_factory=lambda: (WRIST_RIG, HEAD_LEFT_RIG))

    def __post_init__(self) -> None:
        def integer(value, name: str, least: int) -> None:
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise CalibrationStudyError(f"{name} {value!r}; valid: an integer >= {least}")
            if value < least:
                raise CalibrationStudyError(f"{name} {value}; valid: an integer >= {least}")

        def number(value, name: str, low: float, high: float, open_low: bool) -> None:
            ok = isinstance(value, (int, float, np.number)) and not isinstance(value, bool)
            ok = ok and math.isfinite(value) and (value > low if open_low else value >= low)
            if not (ok and value <= high):
                bounds = f"{'(' if open_low else '['}{low:g}, {high:g}]"
                raise CalibrationStudyError(f"{name} {value!r}; valid: a number in {bounds}")

        def sequence(values, name: str) -> None:
            if not isinstance(values, (tuple, list)) or not values:
                raise CalibrationStudyError(f"{name} {values!r}; valid: a non-empty tuple")
            numeric = (int, float, np.number)
            keys = [_key(v) if isinstance(v, numeric) else repr(v) for v in values]
            if len(set(keys)) != len(keys):
                raise CalibrationStudyError(f"{name} {tuple(values)!r} repeat a value")

        for name, valid in (("methods", HAND_EYE_METHODS), ("diversity_methods", HAND_EYE_METHODS)):
            sequence(getattr(self, name), name)
            for method in getattr(self, name):
                if method not in valid:
                    raise CalibrationStudyError(
                        f"{name}: unknown method {method!r}; valid: {', '.join(valid)}"
                    )
        sequence(self.pose_counts, "pose_counts")
        for n in self.pose_counts:
            integer(n, "pose count", MIN_POSES)
        integer(self.diversity_poses, "diversity_poses", MIN_POSES)
        integer(self.trials, "trials", 1)
        integer(self.seed, "seed", 0)
        sequence(self.noise_scales, "noise_scales")
        for scale in (*self.noise_scales, self.diversity_noise_scale):
            number(scale, "noise scale", 0.0, 1e3, open_low=False)
        sequence(self.diversity_spreads_deg, "diversity_spreads_deg")
        for spread in (self.rotation_spread_deg, *self.diversity_spreads_deg):
            number(spread, "rotation spread (deg)", 0.0, 180.0, open_low=True)
        rigs = self.rigs
        if not (isinstance(rigs, (tuple, list)) and rigs and
                all(isinstance(rig, HandEyeRig) for rig in rigs)):  # fmt: skip
            raise CalibrationStudyError(
                "rigs must be a non-empty tuple of HandEyeRig (e.g. (WRIST_RIG, HEAD_LEFT_RIG))"
            )
        names = [rig.name for rig in self.rigs]
        if len(set(names)) != len(names):
            raise CalibrationStudyError(f"rig names {names} repeat; give each camera once")

    def as_dict(self) -> dict:
        """JSON-ready copy."""
        return {
            "pose_counts": [int(n) for n in self.pose_counts],
            "noise_scales": [float(s) for s in self.noise_scales],
            "trials": int(self.trials),
            "methods": list(self.methods),
            "rotation_spread_deg": float(self.rotation_spread_deg),
            "diversity_spreads_deg": [float(s) for s in self.diversity_spreads_deg],
            "diversity_methods": list(self.diversity_methods),
            "diversity_poses": int(self.diversity_poses),
            "diversity_noise_scale": float(self.diversity_noise_scale),
            "seed": int(self.seed),
            "rigs": [rig.as_dict() for rig in self.rigs],
        }


@dataclass(frozen=True)
class _Draw:
    """One trial's unit draws for ``n`` poses: positions in [-1, 1]^3, rotation axes and
    fractions of the spread, standard-normal noise (gripper/target, rotation/translation)."""

    box: np.ndarray
    axes: np.ndarray
    fractions: np.ndarray
    noise: np.ndarray  # (4, n, 3)

    @classmethod
    def sample(cls, rng: np.random.Generator, n: int) -> _Draw:
        axes = rng.normal(size=(n, 3))
        axes /= np.linalg.norm(axes, axis=1, keepdims=True)
        return cls(
            rng.uniform(-1, 1, (n, 3)), axes, rng.uniform(0, 1, n), rng.normal(size=(4, n, 3))
        )


def _observe(rig: HandEyeRig, draw: _Draw, spread_deg: float, scale: float):
    """Noisy (gripper_to_base, target_to_camera), each (n, 4, 4), of one trial."""
    nominal = rig.nominal_gripper_to_base
    turn = Rotation.from_rotvec(draw.axes * np.radians(spread_deg) * draw.fractions[:, None])
    gripper = np.tile(np.eye(4), (len(draw.box), 1, 1))
    gripper[:, :3, :3] = nominal[:3, :3] @ turn.as_matrix()
    gripper[:, :3, 3] = nominal[:3, 3] + draw.box * rig.position_half_extents_m
    camera = rig.target_to_camera(gripper)

    def noisy(T, rotation, translation, sigmas):
        out = T.copy()
        out[:, :3, :3] = (
            Rotation.from_rotvec(scale * sigmas[0] * rotation).as_matrix() @ T[:, :3, :3]
        )
        out[:, :3, 3] += scale * sigmas[1] * translation
        return out

    return (
        noisy(gripper, draw.noise[0], draw.noise[1], GRIPPER_NOISE),
        noisy(camera, draw.noise[2], draw.noise[3], TARGET_NOISE),
    )


def _calibrate(rig: HandEyeRig, gripper, camera, method: str) -> tuple[float, float] | str:
    """(rotation error deg, translation error mm) of X against the truth, or the refusal."""
    try:
        X = calibrate_hand_eye(list(gripper), list(camera), method=method, setup=rig.setup).X
    except CalibrationError as error:
        return str(error)
    return float(rotation_angle_deg(X, rig.X)), float(translation_error_mm(X, rig.X))


def _unchecked(rig: HandEyeRig, gripper, camera, method: str) -> tuple[float, float]:
    """The error of what ``cv2.calibrateHandEye`` returns without the motion check (Tsai
    answers degenerate motions with the identity); NaN when it returns non-finite values."""
    robot = gripper if rig.setup == "eye_in_hand" else _inverse(gripper)
    R, t = cv2.calibrateHandEye(
        list(robot[:, :3, :3]), list(robot[:, :3, 3]), list(camera[:, :3, :3]),
        list(camera[:, :3, 3]), method=_FLAGS[method],
    )  # fmt: skip
    X = _transform(R, np.ravel(t))
    if not np.all(np.isfinite(X)):
        return math.nan, math.nan
    return float(rotation_angle_deg(X, rig.X)), float(translation_error_mm(X, rig.X))


def _stats(values: Sequence[float]) -> dict:
    if not len(values):
        return {"median": None, "p90": None}
    return {"median": float(np.median(values)), "p90": float(np.percentile(values, 90))}


def _cell(outcomes: list) -> dict:
    """Summary of one cell's trials: medians and 90th percentiles of the successful ones."""
    done = [o for o in outcomes if not isinstance(o, str)]
    failed = [o for o in outcomes if isinstance(o, str)]
    return {
        "trials": len(outcomes),
        "failures": len(failed),
        "failure_rate": len(failed) / len(outcomes),
        "failure_example": failed[0] if failed else None,
        "rotation_deg": _stats([r for r, _ in done]),
        "translation_mm": _stats([t for _, t in done]),
    }


def _study_rig(rig: HandEyeRig, config: HandEyeStudyConfig) -> dict:
    rng = np.random.default_rng([config.seed, zlib.crc32(rig.name.encode())])
    n_max = max(*config.pose_counts, config.diversity_poses)
    main = {(n, s, m): [] for n in config.pose_counts for s in config.noise_scales
            for m in config.methods}  # fmt: skip
    sweep = {
        (a, m): ([], []) for a in config.diversity_spreads_deg for m in config.diversity_methods
    }
    for _ in range(config.trials):
        draw = _Draw.sample(rng, n_max)
        for scale in config.noise_scales:
            gripper, camera = _observe(rig, draw, config.rotation_spread_deg, scale)
            for n in config.pose_counts:
                for method in config.methods:
                    main[n, scale, method].append(_calibrate(rig, gripper[:n], camera[:n], method))
        n = config.diversity_poses
        for spread in config.diversity_spreads_deg:
            gripper, camera = _observe(rig, draw, spread, config.diversity_noise_scale)
            for method in config.diversity_methods:
                checked, unchecked = sweep[spread, method]
                checked.append(_calibrate(rig, gripper[:n], camera[:n], method))
                unchecked.append(_unchecked(rig, gripper[:n], camera[:n], method))
    poses = {_key(n): {_key(s): {m: _cell(main[n, s, m]) for m in config.methods}
                       for s in config.noise_scales} for n in config.pose_counts}  # fmt: skip
    diversity = {}
    for spread in config.diversity_spreads_deg:
        diversity[_key(spread)] = {}
        for method in config.diversity_methods:
            checked, unchecked = sweep[spread, method]
            finite = [o for o in unchecked if math.isfinite(o[0])]
            cell = _cell(checked)
            cell["opencv_unchecked"] = {
                "rotation_deg": _stats([r for r, _ in finite]),
                "translation_mm": _stats([t for _, t in finite]),
                "non_finite": len(unchecked) - len(finite),
            }
            diversity[_key(spread)][method] = cell
    return {"setup": rig.setup, "X": rig.X.tolist(), "poses": poses, "diversity": diversity}


@contextlib.contextmanager
def _one_thread_quiet_opencv() -> Iterator[None]:
    """One BLAS/OpenMP and one OpenCV thread; OpenCV's log silenced (its Tsai logs an error
    for every refused pose set of the unchecked runs), both restored afterwards."""
    logging = getattr(getattr(cv2, "utils", None), "logging", None)
    level = logging.getLogLevel() if logging else None
    threads = cv2.getNumThreads()
    with threadpool_limits(1):
        try:
            cv2.setNumThreads(1)
            if logging:
                logging.setLogLevel(logging.LOG_LEVEL_SILENT)
            yield
        finally:
            cv2.setNumThreads(threads)
            if logging:
                logging.setLogLevel(level)


def run_hand_eye_study(config: HandEyeStudyConfig | None = None) -> dict:
    """Run the study; a JSON-ready dict.

    Layout: ``config`` (:meth:`HandEyeStudyConfig.as_dict`), ``noise`` (OpenCV's test noise
    at scale 1), ``seconds`` (wall time), and ``cameras[name]`` with ``setup``, ``X`` (the
    truth), ``poses[n][scale][method]`` and ``diversity[spread][method]``; keys are
    ``f"{value:g}"`` (``"10"``, ``"0.1"``, ``"45"``). A cell holds ``trials``, ``failures``,
    ``failure_rate``, ``failure_example`` (the first refusal's message, or None) and
    ``rotation_deg`` / ``translation_mm`` as ``{"median", "p90"}`` over the successful trials
    (None when none succeeded). A diversity cell adds ``opencv_unchecked``: the same errors of
    ``cv2.calibrateHandEye`` called without the motion check on every trial.
    """
    config = HandEyeStudyConfig() if config is None else config
    if not isinstance(config, HandEyeStudyConfig):
        raise CalibrationStudyError(
            f"config is a {type(config).__name__}; valid: a HandEyeStudyConfig"
        )
    start = time.perf_counter()
    with _one_thread_quiet_opencv():
        cameras = {rig.name: _study_rig(rig, config) for rig in config.rigs}
    noise = {
        part: {"rotation_rad": sigmas[0], "translation_m": sigmas[1]}
        for part, sigmas in (("target", TARGET_NOISE), ("gripper", GRIPPER_NOISE))
    }
    return {
        "config": config.as_dict(),
        "noise": noise,
        "cameras": cameras,
        "seconds": time.perf_counter() - start,
    }


def _cells(study: dict, n: int, scale: float) -> dict:
    """``{camera: {method: cell}}`` at ``n`` poses and noise ``scale``."""
    try:
        cameras = study["cameras"]
        return {name: cam["poses"][_key(n)][_key(scale)] for name, cam in cameras.items()}
    except (KeyError, TypeError) as error:
        raise CalibrationStudyError(
            f"the study has no cell at {n} poses and noise scale {scale:g} ({error!r}); run "
            f"run_hand_eye_study with {n} in pose_counts and {scale:g} in noise_scales"
        ) from error


def metrics_view(study: dict) -> dict:
    """The ``metrics.json`` entries from :func:`run_hand_eye_study`'s result.

    ``hand_eye[camera][method]`` = ``{"rotation_deg", "translation_mm"}``: medians at 10
    poses and noise scale 1 (None when every trial failed). ``targets["hand_eye"]``: the
    target (:data:`TARGETS`) and, per camera and method, ``met`` (True when, at
    every pose count >= 10 at noise scale 0.1, no trial failed and both medians are within
    the target; None when the study has no such cell) with the cells it judged (``by_poses``).
    """
    if not isinstance(study, dict) or not {"config", "cameras"} <= set(study):
        raise CalibrationStudyError(
            "study is not a run_hand_eye_study result (a dict with 'config' and 'cameras'); "
            "pass what run_hand_eye_study returned"
        )
    hand_eye = {
        camera: {
            method: {"rotation_deg": c["rotation_deg"]["median"],
                     "translation_mm": c["translation_mm"]["median"]}
            for method, c in methods.items()
        }
        for camera, methods in _cells(study, METRICS_POSES, METRICS_NOISE_SCALE).items()
    }  # fmt: skip
    counts = [n for n in study["config"]["pose_counts"] if n >= TARGETS["min_poses"]]
    scale = TARGETS["noise_scale"]
    judged: dict = {camera: {method: {} for method in hand_eye[camera]} for camera in hand_eye}
    if any(_key(s) == _key(scale) for s in study["config"]["noise_scales"]):
        for n in counts:
            for camera, methods in _cells(study, n, scale).items():
                for method, c in methods.items():
                    rot, trans = c["rotation_deg"]["median"], c["translation_mm"]["median"]
                    met = c["failures"] == 0 and rot <= TARGETS["rotation_deg"]
                    met = met and trans <= TARGETS["translation_mm"]
                    judged[camera][method][_key(n)] = {
                        "rotation_deg": rot, "translation_mm": trans,
                        "failures": c["failures"], "met": bool(met),
                    }  # fmt: skip
    cameras = {
        camera: {
            method: {
                "met": all(c["met"] for c in cells.values()) if cells else None,
                "by_poses": cells,
            }
            for method, cells in methods.items()
        }
        for camera, methods in judged.items()
    }
    return {"hand_eye": hand_eye, "targets": {"hand_eye": {**TARGETS, "cameras": cameras}}}
