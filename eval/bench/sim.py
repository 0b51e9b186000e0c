"""``ipbench bench sim``: speed of the simulated work cell, printed (and optionally as JSON).

Figures, for the sorting scene: physics steps/s as the environment runs them (with its frame
hook) against raw ``mj_step`` of the same model; wrist RGB-D frames/s at 640x480 —
``rgbd_fps`` renders RGB and metric depth in one pass, ``rgbd_noisy_fps`` adds the env's own
depth sensor model (what the environment observes; for ``ipbench/Sorting-v2`` the full
structured-light model with the episode's unit error); head stereo pairs/s at the
default 1024x680; wall time of a pick-and-place skill; ``reset`` time;
``mj_step_per_s_manipulation``, raw ``mj_step`` of the *cluttered* scene while the gripper
holds an object between its pads during a pick (see :func:`manipulation_step_rate`: the
physics the episodes spend most of their steps on, and what ``Sorting-v2``'s
:data:`~ipbench.envs.world.FAST_PHYSICS` speeds up). Speed targets live here, never in timed
tests.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import gymnasium as gym
import mujoco
import numpy as np

import ipbench.envs  # noqa: F401
from ipbench.envs.sensors import intrinsics
from ipbench.envs.sorting import WRIST_CAMERA, WRIST_SIZE
from ipbench.policies.scripted import GroundTruthSorter

__all__ = ["bench_sim", "manipulation_step_rate", "TARGETS"]

TARGETS = {
    "rgbd_fps": 200.0,
    "rgbd_noisy_fps": 60.0,
    "stereo_fps": 50.0,
    "reset_s": 0.5,
    "skill_s": 1.0,
    "scene_s": 0.5,
    "cycle_s": 0.5,
}
"""Targets on the 2-core reference machine (``>=`` for rates, ``<=`` for times)."""


def _rate(fn, n: int) -> float:
    fn()  # warm-up
    t0 = time.perf_counter()
    for _ in range(n):
        fn()
    return n / (time.perf_counter() - t0)


class _InContact(Exception):
    """Raised from the physics step once the pads have held an object long enough."""


def manipulation_step_rate(
    env_id: str = "ipbench/Sorting-v1",
    seeds: tuple[int, ...] = (0, 1, 2),
    steps: int = 500,
    repeats: int = 3,
    touch_steps: int = 50,
) -> float:
    """Raw ``mj_step`` calls per second during a pick in the cluttered scene (median over
    ``seeds``).

    For each seed: ``reset`` the cluttered scene of ``env_id`` (wrist camera only: nothing
    is rendered while stepping), let the scripted ground-truth sorter pick; the first time
    both gripper pads have touched a free object for ``touch_steps`` physics steps (the jaws
    closing on it, the neighbours it leans on in contact too) the state is copied. From that
    copy ``mj_step`` runs ``steps`` times with the controls as they were (jaws squeezing,
    arm holding still), ``repeats`` times; the fastest run gives the seed's rate. Only
    ``mujoco.mj_step`` is timed — no Python hooks, rendering or skill logic — so the figure
    is what the model's physics options cost where clutter makes them costly (contacts of
    the pile, the pads and the table), comparable across env ids. A seed whose first picks
    never touch anything is skipped; with none left the result is 0.
    """
    rates = [_pick_contact_rate(env_id, seed, steps, repeats, touch_steps) for seed in seeds]
    rates = [r for r in rates if r is not None]
    return float(np.median(rates)) if rates else 0.0


def _pick_contact_rate(
    env_id: str, seed: int, steps: int, repeats: int, touch_steps: int
) -> float | None:
    """One seed of :func:`manipulation_step_rate` (None: no pick held anything)."""
    from ipbench.policies.scripted import GroundTruthSorter

    env = gym.make(env_id, scene="cluttered", cameras=("wrist",))
    try:
        obs, info = env.reset(seed=seed)
        base = env.unwrapped
        model, data, skills = base.model, base.data, base.skills
        step, held = base.robot._step, [0]

        def step_and_watch():
            step()
            if skills._pads_touch_object():
                held[0] += 1
                if held[0] >= touch_steps:
                    raise _InContact

        base.robot._step = step_and_watch
        policy = GroundTruthSorter(base.config.jaw_opening)
        try:
            for _ in range(5):
                obs, _, terminated, truncated, info = env.step(policy.act(obs, info))
                if terminated or truncated:
                    break
            return None
        except _InContact:
            pass
        snapshot = mujoco.MjData(model)
        mujoco.mj_copyData(snapshot, model, data)
        best = np.inf
        for _ in range(repeats):
            mujoco.mj_copyData(data, model, snapshot)
            t0 = time.perf_counter()
            for _ in range(steps):
                mujoco.mj_step(model, data)
            best = min(best, time.perf_counter() - t0)
        return steps / best
    finally:
        env.close()


def bench_sim(
    scene: str = "uncluttered",
    seed: int = 0,
    repeats: int = 3,
    env_id: str = "ipbench/Sorting-v1",
) -> dict[str, float]:
    """The figures of the module docstring for ``env_id``'s ``scene``."""
    env = gym.make(env_id, scene=scene)
    base = env.unwrapped
    reset_times = []
    for k in range(repeats):
        t0 = time.perf_counter()
        obs, info = env.reset(seed=seed + k)
        reset_times.append(time.perf_counter() - t0)
    model, data, renderer = base.model, base.data, base.renderer
    snapshot = mujoco.MjData(model)
    mujoco.mj_copyData(snapshot, model, data)
    physics = _rate(base._physics_step, 2000)
    mujoco.mj_copyData(data, model, snapshot)
    raw = _rate(lambda: mujoco.mj_step(model, data), 2000)
    mujoco.mj_copyData(data, model, snapshot)
    h, w = WRIST_SIZE
    k = intrinsics(model, WRIST_CAMERA, w, h)
    rng = np.random.default_rng(0)

    def rgbd():
        _, depth = renderer.render_rgbd(data, WRIST_CAMERA, w, h)
        base.depth_noise.apply(depth, k.fx, k.fy, rng, unit=unit)

    unit = base.depth_noise.draw_unit(rng)
    noisy_fps = _rate(rgbd, 100)
    rgbd_fps = _rate(lambda: renderer.render_rgbd(data, WRIST_CAMERA, w, h), 100)
    hh, hw = base.config.head_size

    def stereo():
        for side in ("left", "right"):
            renderer.render_rgb(data, f"head_{side}_camera", hw, hh)

    stereo_fps = _rate(stereo, 30)
    policy, skill_times = GroundTruthSorter(), []
    for _ in range(3):
        t0 = time.perf_counter()
        obs, _, terminated, truncated, info = env.step(policy.act(obs, info))
        skill_times.append(time.perf_counter() - t0 - _observation_time(base))
        if terminated or truncated:
            break
    env.close()
    manipulation = manipulation_step_rate(env_id)
    return {
        "physics_steps_per_s": round(physics, 1),
        "raw_mj_step_per_s": round(raw, 1),
        "mj_step_per_s_manipulation": round(manipulation, 1),
        "rgbd_fps": round(rgbd_fps, 1),
        "rgbd_noisy_fps": round(noisy_fps, 1),
        "stereo_fps": round(stereo_fps, 1),
        "skill_s": round(float(np.median(skill_times)), 3),
        "reset_s": round(float(np.median(reset_times)), 3),
    }


def _observation_time(env) -> float:
    """Wall time of one observation (subtracted so ``skill_s`` is the skill alone)."""
    t0 = time.perf_counter()
    env._observation()
    return time.perf_counter() - t0


def report(figures: dict[str, float], json_path: Path | None = None) -> str:
    lines = []
    for key, value in figures.items():
        target = TARGETS.get(key)
        note = ""
        if target is not None:
            at_most = key.endswith("_s")
            ok = value <= target if at_most else value >= target
            sign = "<=" if at_most else ">="
            note = f"  (target {sign} {target}: {'ok' if ok else 'MISSED'})"
        lines.append(f"{key:>22}: {value}{note}")
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(figures, indent=2))
    return "\n".join(lines)
