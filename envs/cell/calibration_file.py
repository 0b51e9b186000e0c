"""The calibration file: what ``ipbench calibrate --out FILE`` measured, saved and read back.

One JSON object, human-readable (a matrix is a list of rows, a row a line; numbers in Python's
shortest round-trip form, so a saved file loads bit-identical):

.. code-block:: text

    format           "ipbench-calibration"
    format_version   1 (:data:`FORMAT_VERSION`)
    created          ISO 8601 time of the calibration (UTC)
    ipbench_version  the ipbench that produced it
    seed             the routine's seed (int >= 0) or null
    cameras          {name: {K (3x3, px), dist (4/5/8/12/14 OpenCV coefficients),
                             image_size [width, height] (px), rms_px}}
    hand_eye         {camera: {method, setup, X (4x4, m), residual_rotation_deg,
                               residual_translation_mm, n_poses}}
    stereo           {left, right, left_to_right (4x4, m), rms_px} or null
    head_gaze        optional: (4,) PTU encoder readings (left pan, left tilt, right pan,
                     right tilt), rad, at which the head's eye-to-hand X and the stereo
                     transform were measured; absent in files that predate it (they load,
                     with ``head_gaze = None``) and written only when known
    cell             optional: {"robot_seed": R or null}, the simulated cell the file was
                     measured in (``ipbench calibrate --robot-seed R``; null: the nominal
                     cell); absent when unknown (older files)

Camera names are the observation's (``head_left``, ``head_right``, ``wrist``). Transforms are
named as :mod:`~ipbench.perception.calibration.poses` (``a_to_b`` maps frame ``a``'s
coordinates to frame ``b``'s): the stereo ``left_to_right`` is the right-from-left transform;
a hand-eye ``X`` is :mod:`~ipbench.perception.calibration.hand_eye`'s (camera-to-gripper for
``eye_in_hand``, camera-to-base for ``eye_to_hand``; a head camera's camera-to-base holds at
``head_gaze`` only) and its residuals are the RMS over pose pairs. ``head_gaze`` is an optional
key of format version 1 (only ``extrinsics="calibrated"`` needs it), so a file without it
loads unchanged. Rotations must be proper to
:data:`ORTHONORMAL_TOLERANCE`.

:meth:`CalibrationFile.load` refuses a missing file, non-JSON, another format or version,
missing or unknown keys, wrong shapes, non-finite values, improper rotations, entries naming
cameras the file does not calibrate, and cameras other than the expected ones; each message
says what was wrong and how to regenerate the file. :meth:`CalibrationFile.save` never
replaces an existing file unless ``overwrite=True``.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from types import MappingProxyType

import numpy as np

__all__ = [
    "CalibrationFileError",
    "DIST_LENGTHS",
    "METHODS",
    "MIN_POSES",
    "SETUPS",
    "FORMAT",
    "FORMAT_VERSION",
    "CalibrationFile",
    "CameraCalibration",
    "HandEyeEntry",
    "StereoEntry",
]

# The file's vocabulary: the names ipbench.perception.calibration.hand_eye gives its methods and
# set-ups (the envs read this file and may not import perception; a test holds them equal)
METHODS = ("tsai", "park", "horaud", "andreff", "daniilidis", "shah", "li")
SETUPS = ("eye_in_hand", "eye_to_hand")
MIN_POSES = 3
ORTHONORMAL_TOLERANCE = 1e-5


class CalibrationFileError(ValueError):
    """A calibration file or entry that cannot be used; the message says why and how to
    regenerate it."""


FORMAT = "ipbench-calibration"
FORMAT_VERSION = 1
DIST_LENGTHS = (4, 5, 8, 12, 14)  # the distortion models OpenCV accepts
_KEYS = {
    "the file": ("format", "format_version", "created", "ipbench_version", "seed", "cameras",
                 "hand_eye", "stereo"),
    "camera": ("K", "dist", "image_size", "rms_px"),
    "hand_eye": ("method", "setup", "X", "residual_rotation_deg", "residual_translation_mm",
                 "n_poses"),
    "stereo": ("left", "right", "left_to_right", "rms_px"),
}  # fmt: skip
_OPTIONAL = {"the file": ("head_gaze", "cell")}  # keys a file may lack (older files)


def _text(value, where: str, valid: tuple[str, ...] = ()) -> str:
    if not isinstance(value, str) or not value.strip() or (valid and value not in valid):
        options = ", ".join(valid) if valid else "a non-empty string"
        raise CalibrationFileError(f"{where} is {value!r}; valid: {options}")
    return value


def _number(value, where: str) -> float:
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if not (ok and math.isfinite(value) and value >= 0):
        raise CalibrationFileError(f"{where} is {value!r}; valid: a finite number >= 0")
    return float(value)


def _int(value, where: str, least: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
        raise CalibrationFileError(f"{where} is {value!r}; valid: an integer >= {least}")
    return int(value)


def _array(value, where: str, shape: tuple[int, ...]) -> np.ndarray:
    try:
        numeric = np.asarray(value).dtype.kind in "iuf"
        array = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):  # ragged, None, ...
        numeric = False
    if not numeric:
        raise CalibrationFileError(f"{where} is not an array of numbers; valid: shape {shape}")
    if array.shape != shape:
        raise CalibrationFileError(f"{where} has shape {array.shape}; valid: shape {shape}")
    if not np.all(np.isfinite(array)):
        raise CalibrationFileError(f"{where} has non-finite values (NaN or inf); valid: finite")
    array.flags.writeable = False
    return array


def _intrinsics(value, where: str) -> np.ndarray:
    K = _array(value, where, (3, 3))
    if not (K[0, 0] > 0 and K[1, 1] > 0 and K[1, 0] == 0 and np.array_equal(K[2], [0, 0, 1])):
        raise CalibrationFileError(
            f"{where} = {K.tolist()} is not a camera matrix; valid: [[fx, s, cx], [0, fy, cy],"
            " [0, 0, 1]] with fx, fy > 0 px"
        )
    return K


def _distortion(value, where: str) -> np.ndarray:
    """(n,) coefficients; OpenCV's (1, n) and (n, 1) arrays are flattened."""
    if isinstance(value, np.ndarray) and value.ndim == 2 and 1 in value.shape:
        value = value.ravel()
    length = len(value) if isinstance(value, (list, tuple, np.ndarray)) else None
    if length not in DIST_LENGTHS:
        raise CalibrationFileError(
            f"{where} has {length} entries; valid: a flat list of"
            f" {', '.join(map(str, DIST_LENGTHS))} OpenCV coefficients (k1, k2, p1, p2[, k3, ...])"
        )
    return _array(value, where, (length,))


def _as_transform(value, where: str) -> np.ndarray:
    """``value`` as a (4, 4) rigid transform: finite, last row [0, 0, 0, 1], proper rotation."""
    T = _array(value, where, (4, 4))
    if not np.allclose(T[3], (0.0, 0.0, 0.0, 1.0), atol=ORTHONORMAL_TOLERANCE):
        raise CalibrationFileError(
            f"{where} has last row {T[3].tolist()}; valid: [0, 0, 0, 1] (a rigid transform)"
        )
    R = T[:3, :3]
    error = float(np.abs(R.T @ R - np.eye(3)).max())
    if error > ORTHONORMAL_TOLERANCE or abs(np.linalg.det(R) - 1.0) > ORTHONORMAL_TOLERANCE:
        raise CalibrationFileError(
            f"{where} has a rotation part that is not a proper rotation (|R^T R - I| = "
            f"{error:.2g}, det R = {np.linalg.det(R):.6g}); valid: an orthonormal R with det +1"
        )
    return T


def _rigid(value, where: str) -> np.ndarray:
    _array(value, where, (4, 4))  # the file's messages: not numbers, shape, non-finite
    T = _as_transform(value, where).copy()
    T.flags.writeable = False
    return T


def _keys(value, where: str, kind: str) -> dict:
    keys, optional = _KEYS[kind], _OPTIONAL.get(kind, ())
    if not isinstance(value, dict):
        raise CalibrationFileError(f"{where} is a {type(value).__name__}; valid: an object {keys}")
    missing = [k for k in keys if k not in value]
    unknown = sorted(set(value) - set(keys) - set(optional))
    if missing or unknown:
        problems = []
        if missing:
            problems.append(f"lacks keys {missing}")
        if unknown:
            problems.append(f"has unknown keys {unknown}")
        extra = f" (optional: {optional})" if optional else ""
        raise CalibrationFileError(f"{where} {' and '.join(problems)}; valid keys: {keys}{extra}")
    return value


@dataclass(frozen=True, eq=False)
class CameraCalibration:
    """One camera's intrinsics.

    Attributes
    ----------
    name : str
        The camera (``head_left``, ``head_right``, ``wrist``).
    K : (3, 3) float array
        ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]``, px.
    dist : (n,) float array
        OpenCV distortion coefficients, n in :data:`DIST_LENGTHS`.
    image_size : (int, int)
        ``(width, height)`` of the calibrated images, px.
    rms_px : float
        Reprojection RMS of the calibration, px.
    """

    name: str
    K: np.ndarray
    dist: np.ndarray
    image_size: tuple[int, int]
    rms_px: float

    def __post_init__(self) -> None:
        put, where = object.__setattr__, f"cameras.{self.name}"
        _text(self.name, "camera name")
        put(self, "K", _intrinsics(self.K, f"{where}.K"))
        put(self, "dist", _distortion(self.dist, f"{where}.dist"))
        size = self.image_size
        if not (isinstance(size, (list, tuple)) and len(size) == 2):
            raise CalibrationFileError(f"{where}.image_size is {size!r}; valid: [width, height] px")
        put(self, "image_size", (_int(size[0], f"{where}.image_size[0] (width)", 1),
                                 _int(size[1], f"{where}.image_size[1] (height)", 1)))  # fmt: skip
        put(self, "rms_px", _number(self.rms_px, f"{where}.rms_px"))


@dataclass(frozen=True, eq=False)
class HandEyeEntry:
    """One camera's hand-eye calibration (as :class:`~.hand_eye.HandEyeResult` gives it).

    Attributes
    ----------
    method : str
        One of :data:`METHODS`.
    setup : str
        ``"eye_in_hand"`` or ``"eye_to_hand"``.
    X : (4, 4) float array
        Camera-to-gripper (eye in hand) or camera-to-base (eye to hand), m.
    residual_rotation_deg, residual_translation_mm : float
        RMS residuals of the fit, deg and mm.
    n_poses : int
        Robot poses used, at least :data:`MIN_POSES` (3).
    """

    method: str
    setup: str
    X: np.ndarray
    residual_rotation_deg: float
    residual_translation_mm: float
    n_poses: int

    def __post_init__(self) -> None:
        put = object.__setattr__
        _text(self.method, "method", METHODS)
        _text(self.setup, "setup", SETUPS)
        put(self, "X", _rigid(self.X, "X"))
        for name in ("residual_rotation_deg", "residual_translation_mm"):
            put(self, name, _number(getattr(self, name), name))
        put(self, "n_poses", _int(self.n_poses, "n_poses", MIN_POSES))


@dataclass(frozen=True, eq=False)
class StereoEntry:
    """The head's stereo transform.

    Attributes
    ----------
    left, right : str
        The two cameras' names.
    left_to_right : (4, 4) float array
        Left-camera coordinates to right-camera coordinates (``T_right_left``), m.
    rms_px : float
        Reprojection RMS of the stereo calibration, px.
    """

    left: str
    right: str
    left_to_right: np.ndarray
    rms_px: float

    def __post_init__(self) -> None:
        _text(self.left, "stereo.left")
        _text(self.right, "stereo.right")
        if self.left == self.right:
            raise CalibrationFileError(
                f"stereo.left and stereo.right are both {self.left!r}; valid: two cameras"
            )
        object.__setattr__(
            self, "left_to_right", _rigid(self.left_to_right, "stereo.left_to_right")
        )
        object.__setattr__(self, "rms_px", _number(self.rms_px, "stereo.rms_px"))


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def _ipbench_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("ipbench")
    except PackageNotFoundError:
        return "unknown"


def _dumps(value, indent: int = 0) -> str:
    """JSON with one matrix row per line."""
    pad = "  " * indent
    if isinstance(value, dict) and value:
        items = [f"{pad}  {json.dumps(k)}: {_dumps(v, indent + 1)}" for k, v in value.items()]
        return "{\n" + ",\n".join(items) + f"\n{pad}}}"
    if isinstance(value, list) and value and all(isinstance(v, list) for v in value):
        rows = [f"{pad}  {json.dumps(row, allow_nan=False)}" for row in value]
        return "[\n" + ",\n".join(rows) + f"\n{pad}]"
    return json.dumps(value, allow_nan=False)


@dataclass(frozen=True, eq=False)
class CalibrationFile:
    """Everything one calibration run measured (the module docstring gives the file layout).

    Attributes
    ----------
    cameras : tuple of CameraCalibration
        The calibrated cameras, unique names, in the file's order.
    hand_eye : mapping str -> HandEyeEntry
        Hand-eye calibrations by camera name (cameras of ``cameras``); may be empty.
    stereo : StereoEntry or None
        The head's stereo transform between two of ``cameras``.
    seed : int or None
        The calibration routine's seed.
    created : str
        ISO 8601 time of the calibration (default: now, UTC).
    ipbench_version : str
        The ipbench that produced it (default: the installed one).
    format_version : int
        :data:`FORMAT_VERSION`; no other is accepted.
    head_gaze : (4,) float array or None
        PTU encoder readings (left pan, left tilt, right pan, right tilt), rad, at which the
        head cameras' eye-to-hand ``X`` (and the stereo transform) were measured; ``None`` when
        unknown (files that predate the key). Needed by ``extrinsics="calibrated"`` to carry a
        head camera's pose to another gaze (:mod:`ipbench.envs.cell.extrinsics`).
    cell : mapping or None
        ``{"robot_seed": R}`` (int >= 0, or None for the nominal cell): the simulated cell the
        file was measured in; ``None`` when unknown (files that predate the key). The envs
        refuse a file measured in another cell than theirs.
    """

    cameras: tuple[CameraCalibration, ...]
    hand_eye: Mapping[str, HandEyeEntry] = field(default_factory=dict)
    stereo: StereoEntry | None = None
    seed: int | None = None
    created: str = field(default_factory=_now)
    ipbench_version: str = field(default_factory=_ipbench_version)
    format_version: int = FORMAT_VERSION
    head_gaze: np.ndarray | None = None
    cell: Mapping[str, int | None] | None = None

    def __post_init__(self) -> None:
        cameras = tuple(self.cameras)
        names = [c.name for c in cameras if isinstance(c, CameraCalibration)]
        if not cameras or len(names) != len(cameras) or len(set(names)) != len(names):
            raise CalibrationFileError(
                f"cameras are {names or list(cameras)}; valid: one or more CameraCalibration"
                " with unique names"
            )
        if not isinstance(self.hand_eye, Mapping):
            raise CalibrationFileError("hand_eye is not a mapping; valid: {camera: HandEyeEntry}")
        stereo = () if self.stereo is None else (self.stereo.left, self.stereo.right)
        for where, name in [("hand_eye", n) for n in self.hand_eye] + [
            ("stereo", n) for n in stereo
        ]:
            if name not in names:
                raise CalibrationFileError(
                    f"{where} names camera {name!r}, which the file does not calibrate;"
                    f" valid: {names}"
                )
        if not all(isinstance(e, HandEyeEntry) for e in self.hand_eye.values()):
            raise CalibrationFileError("hand_eye has values that are not HandEyeEntry")
        if self.stereo is not None and not isinstance(self.stereo, StereoEntry):
            raise CalibrationFileError("stereo is not a StereoEntry; valid: a StereoEntry or None")
        if self.seed is not None:
            _int(self.seed, "seed", 0)
        try:
            datetime.fromisoformat(_text(self.created, "created"))
        except ValueError:
            raise CalibrationFileError(
                f"created is {self.created!r}; valid: an ISO 8601 time, e.g. {_now()!r}"
            ) from None
        _text(self.ipbench_version, "ipbench_version")
        version = self.format_version
        if version != FORMAT_VERSION or isinstance(version, bool):
            raise CalibrationFileError(
                f"format version {version!r}; this ipbench reads version {FORMAT_VERSION} only"
            )
        if self.head_gaze is not None:
            object.__setattr__(self, "head_gaze", _array(self.head_gaze, "head_gaze (rad)", (4,)))
        if self.cell is not None:
            seed = self.cell.get("robot_seed", -1) if isinstance(self.cell, Mapping) else -1
            ok = seed is None or (
                isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0
            )
            if not ok or set(self.cell) != {"robot_seed"}:
                raise CalibrationFileError(
                    f'cell is {self.cell!r}; valid: {{"robot_seed": R}} with R an int >= 0, or '
                    "null for the nominal cell"
                )
            object.__setattr__(self, "cell", MappingProxyType({"robot_seed": seed}))
        object.__setattr__(self, "cameras", cameras)
        object.__setattr__(self, "hand_eye", MappingProxyType(dict(self.hand_eye)))

    @property
    def camera_names(self) -> tuple[str, ...]:
        """The calibrated cameras' names, in order."""
        return tuple(c.name for c in self.cameras)

    def camera(self, name: str) -> CameraCalibration:
        """The calibration of camera ``name``."""
        for c in self.cameras:
            if c.name == name:
                return c
        raise CalibrationFileError(
            f"no camera {name!r} in the file; valid: {list(self.camera_names)}"
        )

    def to_dict(self) -> dict:
        """The file's JSON object (plain lists, numbers and strings)."""
        s = self.stereo
        gaze = {} if self.head_gaze is None else {"head_gaze": self.head_gaze.tolist()}
        gaze |= {} if self.cell is None else {"cell": dict(self.cell)}
        return {
            "format": FORMAT, "format_version": self.format_version, "created": self.created,
            "ipbench_version": self.ipbench_version, "seed": self.seed,
            "cameras": {c.name: {"K": c.K.tolist(), "dist": c.dist.tolist(),
                                 "image_size": list(c.image_size), "rms_px": c.rms_px}
                        for c in self.cameras},
            "hand_eye": {name: {"method": h.method, "setup": h.setup, "X": h.X.tolist(),
                                "residual_rotation_deg": h.residual_rotation_deg,
                                "residual_translation_mm": h.residual_translation_mm,
                                "n_poses": h.n_poses}
                         for name, h in self.hand_eye.items()},
            "stereo": None if s is None else {"left": s.left, "right": s.right,
                                              "left_to_right": s.left_to_right.tolist(),
                                              "rms_px": s.rms_px},
        } | gaze  # fmt: skip

    @classmethod
    def from_dict(cls, data) -> CalibrationFile:
        """The calibration of a file's JSON object; :class:`CalibrationFileError` names the bad
        key."""
        found = data.get("format") if isinstance(data, dict) else type(data).__name__
        if found != FORMAT:
            raise CalibrationFileError(
                f'not an ipbench calibration file ("format" is {found!r}); valid: "{FORMAT}"'
            )
        version = data.get("format_version")
        if version != FORMAT_VERSION or isinstance(version, bool):
            raise CalibrationFileError(
                f"format version {version!r}; this ipbench reads version {FORMAT_VERSION} only"
            )
        _keys(data, "the file", "the file")
        for key in ("cameras", "hand_eye"):
            if not isinstance(data[key], dict) or (key == "cameras" and not data[key]):
                raise CalibrationFileError(
                    f"{key} is {data[key]!r}; valid: an object {{camera name: {{...}}}}"
                    + (" with one or more cameras" if key == "cameras" else "")
                )
        cameras = []
        for name, entry in data["cameras"].items():
            _keys(entry, f"cameras.{name}", "camera")
            cameras.append(CameraCalibration(name, **entry))
        hand_eye = {}
        for name, entry in data["hand_eye"].items():
            _keys(entry, f"hand_eye.{name}", "hand_eye")
            try:
                hand_eye[name] = HandEyeEntry(**entry)
            except CalibrationFileError as error:
                raise CalibrationFileError(f"hand_eye.{name}.{error}") from None
        stereo = data["stereo"]
        if stereo is not None:
            stereo = StereoEntry(**_keys(stereo, "stereo", "stereo"))
        return cls(tuple(cameras), hand_eye, stereo, data["seed"], data["created"],
                   data["ipbench_version"], version, data.get("head_gaze"),
                   data.get("cell"))  # fmt: skip

    def save(self, path: str | os.PathLike, overwrite: bool = False) -> Path:
        """Write the file as JSON (module docstring) and return its path.

        An existing file is kept (:class:`CalibrationFileError`) unless ``overwrite``; the text
        goes to a temporary file beside it and is moved into place, so a failed write loses
        nothing.
        """
        path = Path(path)
        if path.is_dir():
            raise CalibrationFileError(
                f"{path} is a folder; valid: a file path, e.g. {path}/calib.json"
            )
        if path.exists() and not overwrite:
            raise CalibrationFileError(
                f"{path} exists and was not overwritten (nothing lost); pass overwrite=True to"
                " replace it, or choose another path"
            )
        if not path.parent.is_dir():
            raise CalibrationFileError(f"folder {path.parent} does not exist; create it first")
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        try:
            tmp.write_text(_dumps(self.to_dict()) + "\n")
            os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)
        return path

    @classmethod
    def load(
        cls, path: str | os.PathLike, expect_cameras: Iterable[str] | None = None
    ) -> CalibrationFile:
        """Read a file written by :meth:`save`, refusing anything else (module docstring).

        ``expect_cameras``, if given, names the cameras the caller needs: the file must
        calibrate exactly these (one made for other cameras is refused, listing both).
        """
        path = Path(path)
        regenerate = f"regenerate it with `ipbench calibrate --out {path}`"
        if not path.is_file():
            what = "is a folder" if path.is_dir() else "does not exist"
            raise CalibrationFileError(
                f"calibration file {path} {what}; make one with `ipbench calibrate --out {path}`"
            )
        try:
            data = json.loads(path.read_text())
        except (UnicodeDecodeError, json.JSONDecodeError) as error:
            raise CalibrationFileError(f"{path} is not JSON ({error}); {regenerate}") from None
        try:
            calibration = cls.from_dict(data)
        except CalibrationFileError as error:
            raise CalibrationFileError(f"{path}: {error}; {regenerate}") from None
        if expect_cameras is not None:
            expected = sorted({expect_cameras} if isinstance(expect_cameras, str)
                              else set(expect_cameras))  # fmt: skip
            have = list(calibration.camera_names)
            if set(expected) != set(have):
                raise CalibrationFileError(
                    f"{path} calibrates cameras {have}, expected {expected} (missing:"
                    f" {sorted(set(expected) - set(have))}, not expected:"
                    f" {sorted(set(have) - set(expected))}); regenerate it for the expected"
                    f" cameras with `ipbench calibrate --cameras ... --out {path}`"
                )
        return calibration
