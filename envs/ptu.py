"""The FLIR / Directed Perception PTU-D46 command model: limits, step grid, speed, encoder.

Pure numpy (a compiled model is read once for its limits and speeds). Every number has one
home:

* joint limits: ``assets/head/ptu_d46.xml`` (pan +-158.9 deg, tilt -31.1 deg up / +46.6 deg down;
  PTU-D46 User's Manual v2.14.0 §4.3.4), read from the compiled model's ``jnt_range``;
* maximum speeds: the same XML's joint ``user`` attribute (rad/s; pan 300 deg/s, tilt 60 deg/s,
  Directed Perception D47 User Manual: "pan speeds over 300°/second, tilt over 60°/s"), read from
  ``jnt_user``;
* step resolution: :data:`STEP_ARCSEC` = 185.1428 arc-sec = 0.0514 deg per position
  (PTU-D46 User's Manual v2.14.0 §4.3.3).

A command is a target (rad) per axis: it is clipped into the limits' step grid and quantised
to whole positions (:meth:`PtuSpec.command`); the unit then moves its setpoint towards it at
most ``speed * dt`` per control step (:func:`setpoint_step`, :func:`trajectory`) and ends
exactly on the quantised target. The encoder reads the joint position quantised to the grid
(:meth:`PtuSpec.encoder`).

Angles are ordered ``(pan, tilt)`` per unit; the head's two units give 4-vectors
``(left_pan, left_tilt, right_pan, right_tilt)`` (:func:`head_spec_arrays`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import mujoco
import numpy as np

from ipbench.assets import ASSETS_DIR

__all__ = [
    "AXES",
    "PtuError",
    "PtuSpec",
    "STEP_ARCSEC",
    "STEP_RAD",
    "head_spec_arrays",
    "play",
    "ptu_spec",
    "setpoint_step",
    "trajectory",
]

AXES: tuple[str, ...] = ("pan", "tilt")
"""The axes of one unit, in the order of every (2,) array of this module."""
STEP_ARCSEC = 185.1428
"""One PTU-D46 position (arc-sec): 0.0514 deg (PTU-D46 User's Manual v2.14.0 §4.3.3)."""
STEP_RAD = math.radians(STEP_ARCSEC / 3600.0)
"""One position in rad (about 8.976e-4)."""


class PtuError(ValueError):
    """Bad input to the PTU model (wrong shape, non-finite, outside the limits)."""


@dataclass(frozen=True)
class PtuSpec:
    """One PTU-D46's limits, speeds and step.

    Attributes
    ----------
    lower, upper : (2,) joint limits (pan, tilt), rad (positive tilt pitches down).
    speed : (2,) maximum speed (pan, tilt), rad/s.
    step : one position, rad (:data:`STEP_RAD`).
    """

    lower: tuple[float, float]
    upper: tuple[float, float]
    speed: tuple[float, float]
    step: float = STEP_RAD

    @classmethod
    def from_model(cls, model: mujoco.MjModel, prefix: str = "") -> PtuSpec:
        """Read the limits and speeds of the unit whose joints are ``prefix + "pan"`` and
        ``prefix + "tilt"`` (e.g. ``"head_left_"`` in the work cell)."""
        ids = [model.joint(prefix + a).id for a in AXES]
        return cls(
            lower=tuple(float(model.jnt_range[j, 0]) for j in ids),
            upper=tuple(float(model.jnt_range[j, 1]) for j in ids),
            speed=tuple(float(model.jnt_user[j, 0]) for j in ids),
        )

    @property
    def grid_lower(self) -> np.ndarray:
        """(2,) lowest position on the step grid inside the limits, rad."""
        return np.ceil(np.asarray(self.lower) / self.step - 1e-9) * self.step

    @property
    def grid_upper(self) -> np.ndarray:
        """(2,) highest position on the step grid inside the limits, rad."""
        return np.floor(np.asarray(self.upper) / self.step + 1e-9) * self.step

    def quantise(self, angle) -> np.ndarray:
        """``angle`` (rad, any shape) rounded to the nearest whole position (idempotent; at
        most half a step away)."""
        return np.round(np.asarray(angle, float) / self.step) * self.step

    def check(self, target) -> np.ndarray:
        """(2,) float target (pan, tilt) rad, checked: finite and within the limits, else a
        :class:`PtuError` naming the axis and the valid range."""
        t = np.asarray(target, float)
        if t.shape != (2,) or not np.isfinite(t).all():
            raise PtuError(f"a PTU target is 2 finite angles (pan, tilt) in rad, got {target!r}")
        for k, axis in enumerate(AXES):
            if not self.lower[k] <= t[k] <= self.upper[k]:
                raise PtuError(
                    f"{axis} target {t[k]:.4f} rad is outside the limits "
                    f"[{self.lower[k]:.4f}, {self.upper[k]:.4f}] rad "
                    f"([{math.degrees(self.lower[k]):.1f}, {math.degrees(self.upper[k]):.1f}] deg)"
                )
        return t

    def command(self, target) -> np.ndarray:
        """(2,) the position the unit goes to for ``target``: checked, quantised and kept on
        the grid inside the limits."""
        t = self.quantise(self.check(target))
        return np.clip(t, self.grid_lower, self.grid_upper)

    def encoder(self, qpos) -> np.ndarray:
        """(2,) encoder reading of joint positions ``qpos`` (rad): the nearest position on
        the grid inside the limits."""
        return np.clip(self.quantise(qpos), self.grid_lower, self.grid_upper)


@cache
def ptu_spec() -> PtuSpec:
    """The PTU-D46 of ``assets/head/ptu_d46.xml`` (both head units are this model)."""
    model = mujoco.MjModel.from_xml_path(str(ASSETS_DIR / "head" / "ptu_d46.xml"))
    return PtuSpec.from_model(model)


def head_spec_arrays(specs: tuple[PtuSpec, PtuSpec]) -> dict[str, np.ndarray]:
    """(4,) arrays ``lower``, ``upper``, ``speed`` of the head's two units, in the order
    (left_pan, left_tilt, right_pan, right_tilt)."""
    return {
        key: np.concatenate([np.asarray(getattr(s, key), float) for s in specs])
        for key in ("lower", "upper", "speed")
    }


def setpoint_step(setpoint, target, max_delta) -> np.ndarray:
    """The next setpoint: ``setpoint`` moved towards ``target`` by at most ``max_delta``
    (each element, rad); exactly ``target`` once within reach."""
    s, t = np.asarray(setpoint, float), np.asarray(target, float)
    d = np.asarray(max_delta, float)
    if np.any(d <= 0):
        raise PtuError(f"max_delta must be positive (speed * dt), got {max_delta!r}")
    return np.where(np.abs(t - s) <= d, t, s + np.sign(t - s) * d)


def play(output, motor, half_width) -> np.ndarray:
    """A gear train's output after its motor moved to ``motor``, through backlash: the play
    (hysteresis) operator. Each element of ``output`` stays where it is while the motor turns
    inside the dead band ``[output - half_width, output + half_width]`` and is dragged along
    at its edge otherwise, so a reversal costs ``2 * half_width`` of motor travel before the
    output moves. All (k,) rad; ``half_width >= 0`` (half the backlash)."""
    y, x, h = (np.asarray(v, float) for v in (output, motor, half_width))
    if np.any(h < 0):
        raise PtuError(f"half_width is half a dead band, >= 0 rad, got {half_width!r}")
    return np.clip(y, x - h, x + h)


def trajectory(start, target, speed, dt: float) -> np.ndarray:
    """(n, k) setpoints from ``start`` to ``target`` (both (k,) rad), one per control step of
    ``dt`` s at most ``speed`` (k,) rad/s; the last row is exactly ``target`` (n >= 1)."""
    s, t = np.asarray(start, float), np.asarray(target, float)
    d = np.asarray(speed, float) * dt
    n = int(np.max(np.ceil(np.abs(t - s) / d - 1e-12))) if s.size else 0
    rows = [s]
    for _ in range(max(n, 1)):
        rows.append(setpoint_step(rows[-1], t, d))
    return np.array(rows[1:])
