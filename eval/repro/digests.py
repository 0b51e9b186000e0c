"""Stage digests: SHA-256 of each pipeline stage's output for fixed inputs (``ipbench check``).

Every stage runs a small, fixed piece of the benchmark and returns

* ``parts``: a SHA-256 hex digest of each output array (dtype, shape and bytes), so a
  difference in the last bit of any number shows;
* ``summary``: a few numbers of the same output (means, counts, in the units the names say),
  so that two platforms whose bits differ can still be compared statistically, within the
  stage's :attr:`Stage.tolerances`.

The stages, in pipeline order (``depends_on``: a stage whose input comes from another one
differs whenever that one does):

=====================  ======================================================================
``model``              MJCF of the cluttered scene (seed 0, v1) and the compiled MuJoCo models
                       of v1 and v2 (meshes, inertias, procedural textures)
``layout``             object layouts of every scene and catalogue for seeds 0-19
``physics_settle``     the cluttered v1 scene after ``reset(seed=0)`` (0.3 s settling, arms
                       placed) and after 250 more ``mj_step`` (0.5 s)
``physics_skill``      the state after one scripted pick-and-place from that reset
``render_fixed``       overview camera, RGB and depth, of the v1 and v2 models at their
                       ``home`` keyframe (kinematics only: no physics, no IK): the renderer
``render_reset``       wrist RGB, ideal depth and segmentation after ``reset(seed=0)``
``noise_synthetic``    v1 (``DEFAULT_CONFIG``) and v2 (``STRUCTURED_LIGHT``) depth noise on
                       five synthetic 640x480 images (those of
                       ``tests/test_structured_light.py``, whose stored digests the parts equal)
``noise_rendered``     the same two sensors on the rendered wrist depth of ``render_reset``
``perception``         table-top segmentation and FPFH descriptors of a fixed synthetic cloud
``codebook``           k-means codebook (k = 32) of those descriptors, the segments' BoW
``gpc``                our multi-class Laplace GP classifier trained on 300 synthetic BoW
                       vectors, and its Monte-Carlo class probabilities of 200 test vectors
``threshold``          the confidence-threshold rule on those probabilities: its grid point
                       must come out identical on every platform
``episode_v1/_v2``     a short oracle sorting episode (cluttered, seed 0, 6 steps) of
                       ``ipbench/Sorting-v1`` / ``-v2``: rewards, statuses, skills, actions
=====================  ======================================================================

The v2 parts (``mjb_v2``, ``render_fixed``'s v2 images, ``episode_v2``) follow Sorting-v2,
released and frozen; the episode stages also follow the policies' code
(``ipbench.policies.POLICY_VERSION``): regenerate the reference when that changes on purpose.

:func:`run_stages` runs them on one thread (BLAS and OpenMP limited to 1 with threadpoolctl),
the way the benchmark's evaluation runs; ``MUJOCO_GL`` must select a working OpenGL backend
(``egl`` on a headless machine) before MuJoCo is imported.
"""

from __future__ import annotations

import hashlib
import os
import platform
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import numpy as np

__all__ = [
    "CHEAP_STAGES",
    "STAGES",
    "Stage",
    "StageResult",
    "digest_arrays",
    "platform_info",
    "run_stage",
    "run_stages",
    "synthetic_cloud",
    "synthetic_depth_images",
]

SEED = 0
"""The episode seed of every stage that resets an environment."""
SCENE = "cluttered"
"""The scene of every stage that resets an environment (the harder one: contacts, occlusion)."""
LAYOUT_SEEDS = range(20)
"""Seeds whose layouts the ``layout`` stage samples, for every scene and catalogue."""
PHYSICS_STEPS = 250
"""``mj_step`` calls of the ``physics_settle`` stage after the reset (0.5 s at 2 ms)."""
EPISODE_STEPS = 6
"""Step limit of the ``episode_*`` stages (about 5 s each on one core)."""
IMAGE_SIZE = (480, 640)
"""(height, width) px of every rendered and synthetic image."""
_F = 570.0  # px; focal length of the synthetic depth images (the Xtion's at 640x480)
_NOISE_SEED = 12345  # seed of the depth-noise streams (that of the digests in tests/data)


# -- digests ----------------------------------------------------------------------------------
def digest_arrays(*values) -> str:
    """SHA-256 hex digest of ``values``: arrays (dtype, shape and bytes), numbers or strings.

    Two calls agree iff every value has the same type, shape and bits.
    """
    h = hashlib.sha256()
    for value in values:
        if isinstance(value, str | bytes):
            raw = value.encode() if isinstance(value, str) else value
            h.update(f"s{len(raw)}:".encode())
            h.update(raw)
            continue
        arr = np.ascontiguousarray(value)
        if arr.dtype.hasobject:
            raise TypeError(f"cannot digest an object array ({arr.dtype}); pass numbers or str")
        h.update(f"a{arr.dtype.str}{arr.shape}:".encode())
        h.update(arr.tobytes())
    return h.hexdigest()


@dataclass(frozen=True)
class StageResult:
    """What a stage produced: part digests, summary numbers and its wall time (s)."""

    parts: dict[str, str]
    summary: dict[str, float]
    seconds: float = 0.0

    @property
    def digest(self) -> str:
        """SHA-256 of every part's name and digest: equal iff every part is."""
        return digest_arrays(*(f"{k}={v}" for k, v in sorted(self.parts.items())))

    def to_json(self) -> dict:
        """JSON-ready ``{"digest", "parts", "summary", "seconds"}``."""
        return {
            "digest": self.digest,
            "parts": dict(sorted(self.parts.items())),
            "summary": dict(self.summary),
            "seconds": round(self.seconds, 3),
        }


@dataclass(frozen=True)
class Stage:
    """One stage: what it runs and how its summaries may differ on another platform.

    ``tolerances``: summary name -> ``(abs, rel)``; two values ``a`` (here) and ``b`` (the
    reference) are close when ``|a - b| <= abs + rel * |b|``. A summary not listed (a count)
    must be equal. ``cheap``: no rendering and no physics (seconds; the cross-process test
    runs these).
    """

    name: str
    run: Callable[[], tuple[dict[str, str], dict[str, float]]]
    description: str
    tolerances: dict[str, tuple[float, float]] = field(default_factory=dict)
    depends_on: tuple[str, ...] = ()
    cheap: bool = False


# -- shared inputs ----------------------------------------------------------------------------
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
def _stage_model() -> tuple[dict[str, str], dict[str, float]]:
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


def _stage_layout() -> tuple[dict[str, str], dict[str, float]]:
    from ipbench.envs.layout import STANDARD_SCENES

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


def _stage_physics_settle() -> tuple[dict[str, str], dict[str, float]]:
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


def _stage_physics_skill() -> tuple[dict[str, str], dict[str, float]]:
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


def _stage_render_fixed() -> tuple[dict[str, str], dict[str, float]]:
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


def _stage_render_reset() -> tuple[dict[str, str], dict[str, float]]:
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
    from ipbench.envs.depth_noise import DEFAULT_CONFIG, STRUCTURED_LIGHT

    return {"v1": DEFAULT_CONFIG, "v2": STRUCTURED_LIGHT}


def _noise_frames(config, depth, spec, fx) -> tuple[np.ndarray, np.ndarray]:
    """Two consecutive noisy frames of ``depth`` from one seeded stream (and the unit's error
    drawn first, as an episode draws it)."""
    from ipbench.envs.depth_noise import DepthNoiseModel

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


def _stage_noise_synthetic() -> tuple[dict[str, str], dict[str, float]]:
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


def _stage_noise_rendered() -> tuple[dict[str, str], dict[str, float]]:
    _, depth, _, specular, _, fx = _wrist_reset()
    parts, summary = {}, {}
    for sensor, config in _sensors().items():
        a, b = _noise_frames(config, depth, specular, fx)
        parts[sensor] = digest_arrays(a, b)
        summary |= _noise_summary(f"{sensor}_", [depth, depth], [a, b])
    return parts, summary


def synthetic_cloud(seed: int = 0):
    """A fixed table-top :class:`~ipbench.perception.cloud.Cloud` (world frame, m): a table
    plane at z = 0.70 m (4 mm grid) and five objects (an upright carton, a bottle, a lying
    box, a bowl-like cylinder and a small box touching it), with 1.5 mm Gaussian noise (the
    Xtion's at 1 m) from ``seed``; viewed from (0.9, -0.1, 1.6)."""
    from ipbench.perception.cloud import Cloud

    table_z, step = 0.70, 0.004

    def grid(a: float, b: float) -> np.ndarray:
        u, v = np.meshgrid(np.arange(-a, a + 1e-9, step), np.arange(-b, b + 1e-9, step))
        return np.column_stack([u.ravel(), v.ravel()])

    def box(size, x, y, yaw) -> np.ndarray:
        half, faces = np.asarray(size) / 2, []
        for axis in range(3):
            i, j = (k for k in range(3) if k != axis)
            uv = grid(half[i], half[j])
            for sign in (1.0, -1.0) if axis < 2 else (1.0,):  # no bottom face
                face = np.zeros((len(uv), 3))
                face[:, [i, j]], face[:, axis] = uv, sign * half[axis]
                faces.append(face)
        return _place(np.concatenate(faces) + [0, 0, half[2]], x, y, yaw)

    def cylinder(radius, height, x, y) -> np.ndarray:
        a, z = np.meshgrid(np.arange(0, 2 * np.pi, step / radius), np.arange(0, height, step))
        side = np.column_stack([radius * np.cos(a.ravel()), radius * np.sin(a.ravel()), z.ravel()])
        top = grid(radius, radius)
        top = top[np.hypot(top[:, 0], top[:, 1]) <= radius]
        top = np.column_stack([top, np.full(len(top), height)])
        return _place(np.concatenate([side, top]), x, y, 0.0)

    def _place(local: np.ndarray, x: float, y: float, yaw: float) -> np.ndarray:
        c, s = np.cos(yaw), np.sin(yaw)
        return local @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T + [x, y, table_z]

    table = grid(0.33, 0.42) + [0.95, -0.10]
    table = np.column_stack([table, np.full(len(table), table_z)])
    points = np.concatenate(
        [
            table,
            box((0.09, 0.06, 0.20), 0.80, -0.30, 0.4),
            cylinder(0.035, 0.22, 1.00, 0.00),
            box((0.16, 0.10, 0.06), 0.85, 0.15, -0.3),
            cylinder(0.07, 0.06, 1.12, -0.25),
            box((0.05, 0.05, 0.12), 1.12, -0.145, 0.0),
        ]
    )
    points += np.random.default_rng([seed, 2024]).normal(0.0, 0.0015, points.shape)
    n = len(points)
    return Cloud(points, np.arange(n, dtype=np.int64), (1, n), np.array([0.9, -0.1, 1.6]))


@cache
def _synthetic_perception():
    """Segments of :func:`synthetic_cloud` and the FPFH descriptors of each."""
    from ipbench.perception.features import fpfh
    from ipbench.perception.segmentation import segment_scene

    cloud = synthetic_cloud()
    seg = segment_scene(cloud)
    return seg, tuple(fpfh(s.points, viewpoint=cloud.origin) for s in seg.segments)


def _stage_perception() -> tuple[dict[str, str], dict[str, float]]:
    seg, descriptors = _synthetic_perception()
    segs = seg.segments
    parts = {
        "plane": digest_arrays(np.asarray(seg.normal, float), float(seg.offset)),
        "segments": digest_arrays(
            *(np.sort(s.pixels) for s in segs),
            *(np.stack([s.box_center, s.box_extent]) for s in segs),
            *(s.box_rotation for s in segs),
        ),
        "fpfh": digest_arrays(*descriptors),
    }
    all_d = np.concatenate(descriptors)
    summary = {
        "segments": float(len(segs)),
        "segment_points": float(sum(len(s.points) for s in segs)),
        "extent_mean_m": float(np.mean([s.box_extent for s in segs])),
        "height_mean_m": float(np.mean([s.height for s in segs])),
        "fpfh_rows": float(len(all_d)),
        "fpfh_peak_mean": float(all_d.max(axis=1).mean()),  # (each row sums to 600)
        "fpfh_std": float(all_d.std()),
    }
    return parts, summary


def _stage_codebook() -> tuple[dict[str, str], dict[str, float]]:
    from ipbench.perception.features import Codebook

    _, descriptors = _synthetic_perception()
    all_d = np.concatenate(descriptors)
    codebook = Codebook.fit(all_d, k=32, seed=0)
    bows = np.stack([codebook.encode(d) for d in descriptors])
    words = codebook.assign(all_d)
    err = ((all_d - codebook.centers[words]) ** 2).sum(axis=1)
    parts = {"centers": digest_arrays(codebook.centers), "bow": digest_arrays(bows)}
    summary = {
        "quantisation_error": float(err.mean()),
        "words_used": float(len(np.unique(words))),
        "bow_words_mean": float((bows > 0).sum(axis=1).mean()),
    }
    return parts, summary


@cache
def _gpc_fit():
    """The synthetic split of the ``gpc`` stage, the GP fitted on it and its test
    probabilities (one fit for the ``gpc`` and ``threshold`` stages)."""
    from ipbench.perception.gpc import GPCConfig, MulticlassLaplaceGPC
    from ipbench.perception.synthetic import make_split

    X, y, X_test, y_test = make_split(300, 200, seed=0)
    gp = MulticlassLaplaceGPC(GPCConfig()).fit(X, y, 5)
    return X, y, X_test, y_test, gp, gp.predict_proba(X_test)


def _stage_gpc() -> tuple[dict[str, str], dict[str, float]]:
    X, y, X_test, y_test, gp, proba = _gpc_fit()
    state = gp.get_state()
    parts = {
        "data": digest_arrays(X, y, X_test, y_test),
        "hyperparameters": digest_arrays(state["log_theta"]),
        "posterior": digest_arrays(state["a"]),
        "proba": digest_arrays(proba),
    }
    summary = {
        "log_sigma": float(state["log_theta"][0]),
        "log_ell": float(state["log_theta"][1]),
        "log_marginal_likelihood": float(gp.log_marginal_likelihood_value_),
        "accuracy": float((proba.argmax(axis=1) == y_test).mean()),
        "confidence_mean": float(proba.max(axis=1).mean()),
    }
    return parts, summary


def _stage_threshold() -> tuple[dict[str, str], dict[str, float]]:
    from ipbench.policies.threshold import choose_threshold

    *_, y_test, _, proba = _gpc_fit()
    choice = choose_threshold(proba.max(axis=1), proba.argmax(axis=1) == y_test, 0.9)
    parts = {
        "fit": digest_arrays(np.array(choice.fit)),
        "threshold": digest_arrays(choice.threshold),
    }
    summary = {"threshold": choice.threshold, "fit_a": choice.fit[0], "fit_b": choice.fit[1]}
    return parts, summary


class _Uniform:
    """A classifier of no opinion (the oracle labels from ground truth; a model is only needed
    to run the same perception code)."""

    def __init__(self, n_classes: int) -> None:
        self.n_classes = n_classes

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        return np.full((len(X), self.n_classes), 1.0 / self.n_classes)


def _episode(env_id: str) -> tuple[dict[str, str], dict[str, float]]:
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


# -- the registry -----------------------------------------------------------------------------
# Tolerances (abs, rel): "close" is what round-off differences alone do to a summary, measured
# on the reference machine by perturbing each stage's input at round-off level (1e-12 m on the
# objects' reset poses, 1e-15 relative on the GP's inputs, 1e-12 m on the cloud) and by running
# BLAS on 2 threads instead of 1; the measurements are in eval/check.py's docstring. Summaries
# not listed (counts) must be equal.
_IMG = {"rgb_mean": (0.25, 0.0), "depth_mean_m": (5e-4, 0.0), "valid_fraction": (1e-3, 0.0)}
_NOISE = {"kept_fraction": (1e-3, 0.0), "error_mean_m": (1e-5, 0.0), "error_std_m": (0.0, 0.01)}
# One short episode is chaotic: its outcome spans the whole step budget on platforms whose bits
# differ (measured: 0 to 4 objects sorted), so only its length must agree; its outcomes are
# reported, and compared statistically by an evaluation over many seeds.
_EPISODE = {
    k: (float(EPISODE_STEPS) + (0.5 if k == "reward_total" else 0.0), 0.0)
    for k in ("reward_total", "correct", "in_bin", "on_table", "dropped", "grasp_failures")
}

STAGES: dict[str, Stage] = {
    s.name: s
    for s in (
        Stage(
            "model",
            _stage_model,
            "MJCF and compiled MuJoCo models (v1, v2) of the cluttered scene, seed 0",
            {
                f"{c}_{k}": tol
                for c in ("v1", "v2")
                for k, tol in {
                    "mass_kg": (0.0, 1e-9),
                    "inertia_sum": (0.0, 1e-6),
                    "extent_m": (0.0, 1e-9),
                    "texture_mean": (0.05, 0.0),
                }.items()
            },
            cheap=True,
        ),
        Stage(
            "layout",
            _stage_layout,
            f"object layouts, every scene and catalogue, seeds 0-{LAYOUT_SEEDS[-1]}",
            {k: (1e-6, 0.0) for k in ("x_mean_m", "y_mean_m", "z_mean_m", "yaw_mean_rad")},
            cheap=True,
        ),
        Stage(
            "physics_settle",
            _stage_physics_settle,
            f"reset(seed=0) of the cluttered v1 scene, then {PHYSICS_STEPS} mj_step",
            {
                "object_z_mean_m": (1e-5, 0.0),
                "drift_mean_m": (1e-5, 0.0),
                "speed_max_m_s": (1e-3, 0.0),
                "contacts": (4.0, 0.0),
            },
            depends_on=("model",),
        ),
        Stage(
            "physics_skill",
            _stage_physics_skill,
            "one scripted pick-and-place after that reset",
            {"others_moved_mean_m": (1e-4, 0.0), "sim_time_s": (0.1, 0.0)},
            depends_on=("physics_settle",),
        ),
        Stage(
            "render_fixed",
            _stage_render_fixed,
            "overview RGB-D of the v1 and v2 models at the home keyframe (no physics)",
            {f"{c}_{k}": tol for c in ("v1", "v2") for k, tol in _IMG.items()},
            depends_on=("model",),
        ),
        Stage(
            "render_reset",
            _stage_render_reset,
            "wrist RGB, depth and segmentation after reset(seed=0)",
            {**_IMG, "object_fraction": (1e-3, 0.0)},
            depends_on=("physics_settle",),
        ),
        Stage(
            "noise_synthetic",
            _stage_noise_synthetic,
            "v1 and v2 depth noise on five synthetic images",
            {f"{s}_{k}": tol for s in ("v1", "v2") for k, tol in _NOISE.items()},
            cheap=True,
        ),
        Stage(
            "noise_rendered",
            _stage_noise_rendered,
            "v1 and v2 depth noise on the rendered wrist depth",
            {f"{s}_{k}": tol for s in ("v1", "v2") for k, tol in _NOISE.items()},
            depends_on=("render_reset",),
        ),
        Stage(
            "perception",
            _stage_perception,
            "segmentation and FPFH of a fixed synthetic cloud",
            {
                "segment_points": (0.0, 1e-3),
                "extent_mean_m": (1e-4, 0.0),
                "height_mean_m": (1e-4, 0.0),
                "fpfh_rows": (0.0, 1e-3),
                "fpfh_peak_mean": (0.0, 1e-3),
                "fpfh_std": (0.0, 1e-3),
            },
            cheap=True,
        ),
        Stage(
            "codebook",
            _stage_codebook,
            "k-means codebook (k=32) and BoW of those descriptors",
            {
                "quantisation_error": (0.0, 0.01),
                "words_used": (1.0, 0.0),
                "bow_words_mean": (0.0, 0.05),
            },
            depends_on=("perception",),
            cheap=True,
        ),
        Stage(
            "gpc",
            _stage_gpc,
            "GP classifier on 300 synthetic BoW vectors, 200 test predictions",
            {
                "log_sigma": (1e-3, 0.0),
                "log_ell": (1e-3, 0.0),
                "log_marginal_likelihood": (0.0, 1e-5),
                "accuracy": (0.015, 0.0),
                "confidence_mean": (0.002, 0.0),
            },
            cheap=True,
        ),
        Stage(
            "threshold",
            _stage_threshold,
            "the threshold rule on those predictions (target precision 0.9): the grid point "
            "must be identical everywhere",
            # the fit follows the GP's predictions (within the gpc stage's tolerances):
            # OpenBLAS' SkylakeX, Haswell and Sandybridge kernels gave fit_a 2.71-2.80,
            # fit_b 3.18-3.46; the grid point 0.4 on every one
            {"threshold": (0.0, 0.0), "fit_a": (0.2, 0.0), "fit_b": (0.5, 0.0)},
            depends_on=("gpc",),
            cheap=True,
        ),
        *(
            Stage(
                f"episode_{v}",
                (lambda v=v: _episode(f"ipbench/Sorting-{v}")),
                f"oracle episode, ipbench/Sorting-{v} cluttered, seed 0, {EPISODE_STEPS} steps",
                _EPISODE,
                depends_on=("physics_skill", "noise_rendered", "perception"),
            )
            for v in ("v1", "v2")
        ),
    )
}
"""Every stage, in pipeline order."""

CHEAP_STAGES: tuple[str, ...] = tuple(n for n, s in STAGES.items() if s.cheap)
"""Stages without rendering or physics (a few seconds in all)."""


def run_stage(name: str) -> StageResult:
    """Run stage ``name`` of :data:`STAGES` single-threaded and time it (wall seconds)."""
    from threadpoolctl import threadpool_limits

    if name not in STAGES:
        raise KeyError(f"unknown stage {name!r}; valid: {', '.join(STAGES)}")
    t0 = time.perf_counter()
    with threadpool_limits(1):
        parts, summary = STAGES[name].run()
    return StageResult(parts, {k: float(v) for k, v in summary.items()}, time.perf_counter() - t0)


def run_stages(
    names: Iterable[str] | None = None, progress: Callable[[str], None] | None = None
) -> dict[str, StageResult]:
    """Run ``names`` (default: every stage) in pipeline order; ``progress`` gets one line per
    finished stage."""
    wanted = list(STAGES) if names is None else list(names)
    bad = [n for n in wanted if n not in STAGES]
    if bad:
        raise KeyError(f"unknown stage(s) {', '.join(bad)}; valid: {', '.join(STAGES)}")
    results = {}
    for name in (n for n in STAGES if n in wanted):
        results[name] = run_stage(name)
        if progress is not None:
            progress(f"{name}: {results[name].digest[:16]} ({results[name].seconds:.1f} s)")
    return results


# -- platform ---------------------------------------------------------------------------------
_CPU_FLAGS = ("sse4_2", "avx", "fma", "avx2", "avx512f", "avx512vl", "avx512_fp16", "amx_tile")
"""The instruction-set flags that decide which kernels numpy, OpenBLAS, OpenCV, numba and
Mesa dispatch to."""


def _cpuinfo() -> tuple[str, list[str]]:
    """The first CPU's model name and which of :data:`_CPU_FLAGS` it has (Linux)."""
    fields: dict[str, str] = {}
    path = Path("/proc/cpuinfo")
    for line in path.read_text().splitlines() if path.exists() else []:
        key, _, value = line.partition(":")
        fields.setdefault(key.strip(), value.strip())
    flags = fields.get("flags", "").split()
    return fields.get("model name", platform.processor() or "unknown"), [
        f for f in _CPU_FLAGS if f in flags
    ]


def _version(module: str) -> str:
    try:
        return str(__import__(module).__version__)
    except Exception:  # noqa: BLE001 - a missing or broken library is reported, not fatal
        return "missing"


def _gl_renderer() -> str:
    """The OpenGL renderer and version (e.g. Mesa llvmpipe) of the MuJoCo backend."""
    try:
        import mujoco
        from OpenGL import GL

        ctx = mujoco.GLContext(16, 16)
        try:
            ctx.make_current()
            return " / ".join(GL.glGetString(k).decode() for k in (GL.GL_RENDERER, GL.GL_VERSION))
        finally:
            ctx.free()
    except Exception as err:  # noqa: BLE001
        return f"unknown ({type(err).__name__})"


def platform_info() -> dict[str, object]:
    """What bit-exact results depend on: CPU model and instruction-set flags, the kernels the
    libraries dispatch to (BLAS, numpy SIMD, numba's LLVM target), library versions, libc,
    the OpenGL renderer and ``MUJOCO_GL``."""
    from importlib.metadata import PackageNotFoundError, version

    cpu, flags = _cpuinfo()
    info: dict[str, object] = {
        "cpu": cpu,
        "cpu_flags": flags,
        "cores": os.cpu_count(),
        "machine": platform.machine(),
        "system": f"{platform.system()} {platform.release()}",
        "libc": " ".join(platform.libc_ver()),
        "python": platform.python_version(),
    }
    try:
        info["ipbench"] = version("ipbench")
    except PackageNotFoundError:
        info["ipbench"] = "unknown"
    for name, module in (
        ("numpy", "numpy"),
        ("scipy", "scipy"),
        ("mujoco", "mujoco"),
        ("opencv", "cv2"),
        ("numba", "numba"),
        ("open3d", "open3d"),
        ("scikit-learn", "sklearn"),
        ("gymnasium", "gymnasium"),
    ):
        info[name] = _version(module)
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__

        info["numpy_simd"] = [f for f in __cpu_dispatch__ if __cpu_features__.get(f)]
    except ImportError:
        info["numpy_simd"] = "unknown"
    try:
        from threadpoolctl import threadpool_info

        info["blas"] = sorted(
            f"{p.get('internal_api')} {p.get('version')} {p.get('architecture')} "
            f"({Path(p['filepath']).parent.name})"
            for p in threadpool_info()
            if p.get("user_api") == "blas"
        )
    except Exception:  # noqa: BLE001
        info["blas"] = "unknown"
    try:
        import llvmlite.binding as llvm

        info["numba_cpu"] = llvm.get_host_cpu_name()
    except Exception:  # noqa: BLE001
        info["numba_cpu"] = "unknown"
    info["mujoco_gl"] = os.environ.get("MUJOCO_GL", "")
    info["gl"] = _gl_renderer()
    return info
