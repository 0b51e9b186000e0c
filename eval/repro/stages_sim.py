"""The stages of :mod:`ipbench.eval.repro.digests` that build, step or render the simulated
cell: the model, layouts, physics, rendering, the depth sensors' noise and a short episode."""

from __future__ import annotations

import hashlib
from collections.abc import Iterator
from contextlib import contextmanager
from functools import cache

import numpy as np

from ipbench.eval.repro.stage import (
    _F,
    _NOISE_SEED,
    EPISODE_STEPS,
    IMAGE_SIZE,
    LAYOUT_SEEDS,
    PHYSICS_STEPS,
    SCENE,
    SEED,
    digest_arrays,
)

__all__ = [
    "stage_episode",
    "stage_layout",
    "stage_model",
    "stage_noise_rendered",
    "stage_noise_synthetic",
    "stage_physics_settle",
    "stage_physics_skill",
    "stage_render_fixed",
    "stage_render_reset",
    "synthetic_depth_images",
]


# shared inputs
def _places():
    from ipbench.envs.sorting import workcell_places

    return workcell_places()


def _layout(scene: str, seed: int, catalog: str):
    from ipbench.envs.layout import sample_layout

    p = _places()
    return sample_layout(
        scene, seed, p.spawn_area.center, p.spawn_area.half, p.table_height, catalog=catalog
    )


def _world(catalog: str):
    """The :data:`SCENE` layout of layout seed :data:`SEED` with ``catalog``'s objects,
    compiled into the work cell as ``reset`` compiles it: the ``World`` and its spec."""
    from ipbench.assets.compose import build_workcell_spec
    from ipbench.envs.world import build_world

    spec = build_workcell_spec()
    return build_world(_layout(SCENE, SEED, catalog), spec), spec


@contextmanager
def _env(env_id: str, **kwargs) -> Iterator:
    """``gym.make(env_id)`` of :data:`SCENE` with the wrist camera only, closed afterwards."""
    import gymnasium as gym

    import ipbench.envs  # noqa: F401  (registers the ids)

    env = gym.make(env_id, scene=SCENE, cameras=("wrist",), **kwargs)
    try:
        yield env
    finally:
        env.close()


def _object_xyz(env) -> np.ndarray:
    """(n, 3) world positions of the objects' bodies (m)."""
    base = env.unwrapped
    return base.data.xpos[base.world.object_bodies].copy()


def _status_counts(info: dict) -> dict[str, float]:
    statuses = [o["status"] for o in info["objects"].values()]
    correct = sum(o["status"] == f"in_bin:{o['category']}" for o in info["objects"].values())
    return {
        "on_table": float(statuses.count("on_table")),
        "in_bin": float(sum(s.startswith("in_bin:") for s in statuses)),
        "correct": float(correct),
        "dropped": float(statuses.count("dropped")),
    }


def _image_summary(prefix: str, rgb: np.ndarray | None, depth: np.ndarray) -> dict[str, float]:
    """Mean colour (0-255), mean valid depth (m) and valid fraction of a rendered image."""
    valid = depth > 0
    out = {
        f"{prefix}depth_mean_m": float(depth[valid].mean()) if valid.any() else 0.0,
        f"{prefix}valid_fraction": float(valid.mean()),
    }
    if rgb is not None:
        out[f"{prefix}rgb_mean"] = float(rgb.mean())
    return out


# -- stages -----------------------------------------------------------------------------------
def stage_model() -> tuple[dict[str, str], dict[str, float]]:
    import mujoco

    parts, summary = {}, {}
    for catalog in ("v1", "v2"):
        world, spec = _world(catalog)
        m = world.model
        if catalog == "v1":  # v2's printed textures are buffer textures, which MJCF cannot hold
            parts["xml_v1"] = digest_arrays(spec.to_xml())
        mjb = np.zeros(mujoco.mj_sizeModel(m), np.uint8)
        mujoco.mj_saveModel(m, None, mjb)
        parts[f"mjb_{catalog}"] = digest_arrays(mjb)
        summary |= {
            f"{catalog}_mass_kg": float(m.body_mass.sum()),
            f"{catalog}_inertia_sum": float(m.body_inertia.sum()),
            f"{catalog}_extent_m": float(m.stat.extent),
            f"{catalog}_ngeom": float(m.ngeom),
            f"{catalog}_mesh_vertices": float(m.nmeshvert),
            f"{catalog}_texture_mean": float(m.tex_data.mean()) if m.ntexdata else 0.0,
        }
    return parts, summary


def stage_layout() -> tuple[dict[str, str], dict[str, float]]:
    from ipbench.envs.sorting_scenes import STANDARD_SCENES

    parts, rows, lying = {}, [], 0
    for catalog in ("v1", "v2"):
        for scene in STANDARD_SCENES:
            poses, names = [], []
            for seed in LAYOUT_SEEDS:
                for o in _layout(scene, seed, catalog).objects:
                    poses.append([*o.position, o.yaw, *o.quat])
                    names.append(f"{o.instance.name}/{o.resting.name}")
                    lying += o.resting.name != "upright"
            parts[f"{catalog}/{scene}"] = digest_arrays(np.array(poses), "\n".join(names))
            rows += poses
    a = np.array(rows)
    return parts, {
        "objects": float(len(a)),
        "x_mean_m": float(a[:, 0].mean()),
        "y_mean_m": float(a[:, 1].mean()),
        "z_mean_m": float(a[:, 2].mean()),
        "yaw_mean_rad": float(a[:, 3].mean()),
        "lying_fraction": lying / len(a),
    }


def stage_physics_settle() -> tuple[dict[str, str], dict[str, float]]:
    import mujoco

    with _env("ipbench/Sorting-v1") as env:
        env.reset(seed=SEED)
        m, d = env.unwrapped.model, env.unwrapped.data
        parts = {"reset_state": digest_arrays(d.qpos, d.qvel)}
        start = _object_xyz(env)
        for _ in range(PHYSICS_STEPS):
            mujoco.mj_step(m, d)
        parts["stepped_state"] = digest_arrays(d.qpos, d.qvel)
        end = _object_xyz(env)
        speed = np.linalg.norm(d.qvel[env.unwrapped._object_dofs].reshape(-1, 3), axis=1)
        summary = {
            "object_z_mean_m": float(end[:, 2].mean()),
            "drift_mean_m": float(np.linalg.norm(end - start, axis=1).mean()),
            "speed_max_m_s": float(speed.max()),
            "contacts": float(d.ncon),
        }
    return parts, summary


def stage_physics_skill() -> tuple[dict[str, str], dict[str, float]]:
    from ipbench.policies.scripted import GroundTruthSorter

    with _env("ipbench/Sorting-v1") as env:
        obs, info = env.reset(seed=SEED)
        start = _object_xyz(env)
        action = GroundTruthSorter(True).act(obs, info)
        _, reward, _, _, info = env.step(action)
        d = env.unwrapped.data
        moved = np.linalg.norm(_object_xyz(env) - start, axis=1)
        still = np.array([o["status"] == "on_table" for o in info["objects"].values()])
        parts = {
            "action": digest_arrays(*(np.asarray(action[k], float) for k in sorted(action))),
            "state": digest_arrays(d.qpos, d.qvel),
        }
        summary = {
            "reward": float(reward),
            "skills_ok": float(sum(s["success"] for s in info["skills"])),
            "others_moved_mean_m": float(moved[still].mean()) if still.any() else 0.0,
            "sim_time_s": float(info["sim_time"]),
            **_status_counts(info),
        }
    return parts, summary


def stage_render_fixed() -> tuple[dict[str, str], dict[str, float]]:
    import mujoco

    from ipbench.envs.sensors import SensorRenderer

    h, w = IMAGE_SIZE
    parts, summary = {}, {}
    for catalog in ("v1", "v2"):
        m = _world(catalog)[0].model
        d = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
        mujoco.mj_forward(m, d)
        with SensorRenderer(m) as renderer:
            rgb, depth = renderer.render_rgbd(d, "overview", w, h)
        parts[f"{catalog}_rgb"] = digest_arrays(rgb)
        parts[f"{catalog}_depth"] = digest_arrays(depth)
        summary |= _image_summary(f"{catalog}_", rgb, depth)
    return parts, summary


@cache
def _wrist_reset() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """Wrist RGB, ideal depth (m), geom id per pixel, specular mask, object mask and fx (px)
    after ``reset(seed=0)`` of the cluttered v1 scene (read-only arrays)."""
    from ipbench.envs.sensors import intrinsics, specular_geoms
    from ipbench.envs.sorting import WRIST_CAMERA

    h, w = IMAGE_SIZE
    with _env("ipbench/Sorting-v1") as env:
        env.reset(seed=SEED)
        base = env.unwrapped
        rgb, depth = base.renderer.render_rgbd(base.data, WRIST_CAMERA, w, h)
        seg = base.renderer.render_segmentation(base.data, WRIST_CAMERA, w, h)
        specular = np.append(specular_geoms(base.model), False)[seg]
        objects = np.isin(seg, np.array(sorted(base.world.object_geoms), dtype=seg.dtype))
        fx = intrinsics(base.model, WRIST_CAMERA, w, h).fx
    for a in (rgb, depth, seg, specular, objects):
        a.setflags(write=False)
    return rgb, depth, seg, specular, objects, float(fx)


def stage_render_reset() -> tuple[dict[str, str], dict[str, float]]:
    rgb, depth, seg, _, objects, _ = _wrist_reset()
    parts = {
        "rgb": digest_arrays(rgb),
        "depth": digest_arrays(depth),
        "segmentation": digest_arrays(seg),
    }
    return parts, _image_summary("", rgb, depth) | {"object_fraction": float(objects.mean())}


def synthetic_depth_images() -> dict[str, tuple[np.ndarray, np.ndarray | None]]:
    """Five synthetic 480x640 z-depth images (m) and specular masks: planes at 1.2 m, a plane
    tilted by 40 deg, a scene of boxes with holes and out-of-range depth, with and without
    specular patches (the sensor tests' stored digests were recorded on them)."""
    import math

    h, w = IMAGE_SIZE
    u = ((np.arange(w) - (w - 1) / 2) / _F)[None, :]
    b = math.radians(40)
    tilted = (1.3 * math.cos(b) / (math.sin(b) * u + math.cos(b))).astype(np.float32)
    tilted = np.broadcast_to(tilted, (h, w)).copy()
    scene = tilted.copy()
    scene[100:200, 100:300] = 0.9
    scene[300:380, 400:460] = 0.6
    scene[:, :20] = 0
    scene[400:, 500:] = 4.0
    spec = np.zeros((h, w), bool)
    spec[300:400, 300:500] = True
    spec[120:180, 150:250] = True
    plane = np.full((h, w), 1.2, np.float32)
    return {
        "plane_1.2m": (plane, None),
        "tilted_40deg": (tilted, None),
        "scene": (scene, None),
        "scene_specular": (scene, spec),
        "plane_specular": (plane, spec),
    }


def _sensors() -> dict:
    from ipbench.envs.sensors.depth_noise import DEFAULT_CONFIG, STRUCTURED_LIGHT

    return {"v1": DEFAULT_CONFIG, "v2": STRUCTURED_LIGHT}


def _noise_frames(config, depth, spec, fx) -> tuple[np.ndarray, np.ndarray]:
    """Two consecutive noisy frames of ``depth`` from one seeded stream (and the unit's error
    drawn first, as an episode draws it)."""
    from ipbench.envs.sensors.depth_noise import DepthNoiseModel

    model = DepthNoiseModel(config)
    rng = np.random.default_rng(_NOISE_SEED)
    unit = model.draw_unit(rng)
    a = model.apply(depth, fx, fx, rng, spec, unit=unit)
    b = model.apply(depth, fx, fx, rng, spec, unit=unit)
    return a, b


def _noise_summary(prefix: str, ideal: list[np.ndarray], noisy: list[np.ndarray]) -> dict:
    """Kept fraction of the ideal depth's valid pixels; mean and std of noisy - ideal (m)."""
    kept, err = [], []
    for z, n in zip(ideal, noisy, strict=True):
        valid = z > 0
        kept.append((n > 0)[valid])
        both = valid & (n > 0)
        err.append(n[both].astype(np.float64) - z[both])
    e = np.concatenate(err)
    return {
        f"{prefix}kept_fraction": float(np.concatenate(kept).mean()),
        f"{prefix}error_mean_m": float(e.mean()),
        f"{prefix}error_std_m": float(e.std()),
    }


def stage_noise_synthetic() -> tuple[dict[str, str], dict[str, float]]:
    parts, summary = {}, {}
    for sensor, config in _sensors().items():
        ideal, noisy = [], []
        for name, (depth, spec) in synthetic_depth_images().items():
            a, b = _noise_frames(config, depth, spec, _F)
            parts[f"{sensor}/{name}"] = hashlib.sha256(a.tobytes() + b.tobytes()).hexdigest()
            ideal += [depth, depth]
            noisy += [a, b]
        summary |= _noise_summary(f"{sensor}_", ideal, noisy)
    return parts, summary


def stage_noise_rendered() -> tuple[dict[str, str], dict[str, float]]:
    _, depth, _, specular, _, fx = _wrist_reset()
    parts, summary = {}, {}
    for sensor, config in _sensors().items():
        a, b = _noise_frames(config, depth, specular, fx)
        parts[sensor] = digest_arrays(a, b)
        summary |= _noise_summary(f"{sensor}_", [depth, depth], [a, b])
    return parts, summary


class _Uniform:
    """A classifier of no opinion (the oracle labels from ground truth; a model is only needed
    to run the same perception code)."""

    def __init__(self, n_classes: int) -> None:
        self.n_classes = n_classes

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        return np.full((len(X), self.n_classes), 1.0 / self.n_classes)


def stage_episode(env_id: str) -> tuple[dict[str, str], dict[str, float]]:
    from ipbench.assets.objects import CATEGORIES
    from ipbench.perception.features import FPFH_DIM, Codebook
    from ipbench.perception.model import PerceptionModel
    from ipbench.policies import NothingToSort, PolicyModels, make_policy

    codebook = Codebook(np.random.default_rng(0).random((2, FPFH_DIM)))
    model = PerceptionModel(CATEGORIES, codebook, _Uniform(len(CATEGORIES)), "check")
    area = tuple(float(v) for v in _places().inspection_area.center)
    policy = make_policy("oracle", PolicyModels(gp=model, inspection_area=area, thresholds={}))
    policy.reset(SEED)
    steps, rewards, records, failures = 0, [], [], 0
    with _env(env_id, max_steps=EPISODE_STEPS) as env:
        obs, info = env.reset(seed=SEED)
        done = False
        while not done:
            try:
                action = policy.act(obs, info)
            except NothingToSort:
                break
            obs, reward, terminated, truncated, info = env.step(action)
            done, steps = terminated or truncated, steps + 1
            rewards.append(reward)
            failures += sum(s["name"] == "pick" and not s["success"] for s in info["skills"])
            records.append(
                digest_arrays(
                    *(np.asarray(action[k], float) for k in sorted(action)),
                    float(reward),
                    "|".join(o["status"] for o in info["objects"].values()),
                    "|".join(f"{s['name']}:{s['success']}" for s in info["skills"]),
                )
            )
        d = env.unwrapped.data
        parts = {"steps": digest_arrays(*records), "final_state": digest_arrays(d.qpos, d.qvel)}
    summary = {
        "steps": float(steps),
        "reward_total": float(np.sum(rewards)),
        "grasp_failures": float(failures),
        **_status_counts(info),
    }
    return parts, summary
