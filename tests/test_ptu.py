"""The PTU-D46 command model (envs/ptu.py) against its sources and its contract."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ipbench.envs.ptu import STEP_RAD, PtuError, play, ptu_spec, setpoint_step, trajectory


def test_numbers_match_the_facts_sheet():
    spec = ptu_spec()
    # 185.1428 arc-sec = 0.0514 deg per position (PTU-D46 User's Manual v2.14.0 §4.3.3)
    assert math.degrees(STEP_RAD) == pytest.approx(0.0514, abs=5e-5)
    assert spec.step == STEP_RAD
    # limits pan +-158.9 deg, tilt -31.1 / +46.6 deg (ptu_d46.xml; PTU-D46 User's Manual §4.3.4)
    np.testing.assert_allclose(np.degrees(spec.lower), [-158.9, -31.1], atol=1e-9)
    np.testing.assert_allclose(np.degrees(spec.upper), [158.9, 46.6], atol=1e-9)
    # speeds pan 300 deg/s, tilt 60 deg/s (the XML's user attributes)
    np.testing.assert_allclose(np.degrees(spec.speed), [300.0, 60.0], rtol=2e-4)


def test_quantise_is_idempotent_and_within_half_a_step():
    spec = ptu_spec()
    angles = np.random.default_rng(0).uniform(-3, 3, 1000)
    q = spec.quantise(angles)
    np.testing.assert_array_equal(spec.quantise(q), q)
    assert np.abs(q - angles).max() <= STEP_RAD / 2 + 1e-15
    np.testing.assert_allclose(q / STEP_RAD, np.round(q / STEP_RAD), atol=1e-9)


def test_commands_respect_the_limits_and_the_grid():
    spec = ptu_spec()
    rng = np.random.default_rng(1)
    for _ in range(200):
        target = rng.uniform(spec.lower, spec.upper)
        cmd = spec.command(target)
        assert np.all(cmd >= spec.lower) and np.all(cmd <= spec.upper)
        np.testing.assert_allclose(cmd / STEP_RAD, np.round(cmd / STEP_RAD), atol=1e-9)
        assert np.abs(cmd - target).max() <= STEP_RAD  # half a step, or one at a limit
    # the limits themselves: the nearest grid point inside
    cmd = spec.command(spec.upper)
    assert np.all(cmd <= spec.upper) and np.all(spec.upper - cmd < STEP_RAD)
    for bad in ([spec.upper[0] + 0.01, 0.0], [0.0, spec.lower[1] - 0.01]):
        with pytest.raises(PtuError, match="outside the limits"):
            spec.command(bad)
    with pytest.raises(PtuError, match="2 finite angles"):
        spec.command([0.0, np.nan])


def test_encoder_reads_the_grid_inside_the_limits():
    spec = ptu_spec()
    q = np.array([0.123456, -0.2])
    np.testing.assert_array_equal(spec.encoder(q), spec.quantise(q))
    beyond = spec.encoder(np.array(spec.upper) + 0.01)  # a joint past its soft limit
    assert np.all(beyond <= spec.upper)


@pytest.mark.parametrize("dt", [0.002, 0.01])
def test_trajectory_is_rate_limited_and_ends_on_the_quantised_target(dt):
    spec = ptu_spec()
    rng = np.random.default_rng(2)
    speed = np.array(spec.speed)
    for _ in range(50):
        start = spec.command(rng.uniform(spec.lower, spec.upper))
        target = spec.command(rng.uniform(spec.lower, spec.upper))
        path = trajectory(start, target, speed, dt)
        steps = np.abs(np.diff(np.vstack([start, path]), axis=0))
        assert np.all(steps <= speed * dt + 1e-12)
        np.testing.assert_array_equal(path[-1], target)
        # as fast as allowed: the slowest axis needs ceil(distance / (speed dt)) steps
        assert len(path) == max(1, int(np.max(np.ceil(np.abs(target - start) / (speed * dt)))))


def test_setpoint_step_rejects_a_non_positive_speed():
    with pytest.raises(PtuError, match="positive"):
        setpoint_step([0.0], [1.0], [0.0])


def test_play_is_a_dead_band_that_drags_the_output_at_its_edges():
    h = np.array([0.5, 0.0])
    y = np.zeros(2)
    y = play(y, np.array([0.3, 0.3]), h)  # inside the band: the geared axis stays put
    np.testing.assert_allclose(y, [0.0, 0.3])
    y = play(y, np.array([2.0, 2.0]), h)  # dragged: trails the motor by h
    np.testing.assert_allclose(y, [1.5, 2.0])
    y = play(y, np.array([1.2, 1.2]), h)  # a reversal smaller than 2h: no output motion
    np.testing.assert_allclose(y, [1.5, 1.2])
    y = play(y, np.array([0.0, 0.0]), h)  # past the band: leads the motor by h
    np.testing.assert_allclose(y, [0.5, 0.0])
    with pytest.raises(PtuError, match=">= 0 rad"):
        play(y, y, np.array([-0.1, 0.0]))
