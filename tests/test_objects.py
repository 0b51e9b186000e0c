"""Tests of the procedural object catalogue and builder (ipbench.assets.objects)."""

from __future__ import annotations

import ast
import importlib
import itertools
import os
import pkgutil
import subprocess
import sys
import warnings

import mujoco
import numpy as np
import pytest

import ipbench.assets.objects as objects
from ipbench.assets.objects import (
    CATEGORIES,
    INSTANCES_PER_CATEGORY,
    KNOWN_INSTANCES,
    SPECULAR_THRESHOLD,
    ObjectCatalogError,
    ObjectInstance,
    add_object,
    get_instance,
    instances,
    resting_poses,
)
from ipbench.assets.objects import catalog as catalog_module

ALL = instances()
MM = 1e-3
EPS = 1e-9


def _world() -> mujoco.MjSpec:
    """A floor plane with the benchmark's physics options."""
    spec = mujoco.MjSpec()
    spec.option.timestep = 0.002
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = 10
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[1, 1, 0.1])
    return spec


def _compile(spec: mujoco.MjSpec) -> mujoco.MjModel:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # MuJoCo compiler warnings become UserWarning
        return spec.compile()


def _body_geoms(model: mujoco.MjModel, body: str) -> list[int]:
    bid = model.body(body).id
    return [g for g in range(model.ngeom) if model.geom_bodyid[g] == bid]


def _angle_deg(q1: np.ndarray, q2: np.ndarray) -> float:
    dot = abs(float(np.dot(q1 / np.linalg.norm(q1), q2 / np.linalg.norm(q2))))
    return float(np.degrees(2 * np.arccos(min(1.0, dot))))


# --- catalogue -------------------------------------------------------------------------------


def test_catalogue_shape_and_order():
    assert CATEGORIES == ("juice_bottle", "milk_carton", "bowl", "mug", "juice_box")
    assert INSTANCES_PER_CATEGORY == 12 and KNOWN_INSTANCES == 8
    assert len(ALL) == 60
    assert [i.category for i in ALL[::12]] == list(CATEGORIES)
    for inst in ALL:
        assert isinstance(inst, ObjectInstance)
        assert inst.name == f"{inst.category}_{inst.index:02d}"
    assert len({i.name for i in ALL}) == 60


def test_known_unknown_rule():
    known, unknown = instances(known=True), instances(known=False)
    assert len(known) == 5 * 8 and len(unknown) == 5 * 4
    assert all(i.known and i.index < 8 for i in known)
    assert all(not i.known and i.index >= 8 for i in unknown)
    assert set(known) | set(unknown) == set(ALL)


def test_deterministic_and_frozen():
    first = [get_instance(c, i) for c in CATEGORIES for i in range(12)]
    catalog_module._make.cache_clear()
    second = [get_instance(c, i) for c in CATEGORIES for i in range(12)]
    assert first == second and all(a is not b for a, b in zip(first, second, strict=True))
    with pytest.raises(AttributeError):
        first[0].mass = 1.0  # frozen


def test_seed_independent_of_python_hash():
    code = "from ipbench.assets.objects import get_instance; print(repr(get_instance('mug', 5)))"
    env = dict(os.environ, PYTHONHASHSEED="12345")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == repr(get_instance("mug", 5))


def test_distinct_instances_differ():
    for cat in CATEGORIES:
        insts = [get_instance(cat, i) for i in range(12)]
        assert len({i.shape for i in insts}) == 12
        assert len({i.size for i in insts}) == 12
        assert len({i.mass for i in insts}) == 12
        assert len({i.rgba for i in insts}) > 1


def test_bad_lookups_list_valid_options():
    with pytest.raises(ObjectCatalogError, match="juice_bottle.*milk_carton.*juice_box"):
        get_instance("teapot", 0)
    with pytest.raises(ObjectCatalogError, match="0..11"):
        get_instance("mug", 12)
    with pytest.raises(ValueError):
        get_instance("mug", -1)
    assert issubclass(ObjectCatalogError, ValueError)


def _within(value: float, lo: float, hi: float) -> bool:
    return lo - EPS <= value <= hi + EPS


def test_sizes_and_masses_within_real_world_ranges():
    for inst in ALL:
        sx, sy, sz = inst.size
        s = inst.shape
        if inst.category == "juice_bottle":
            assert sx == sy and _within(sx, 0.065, 0.090) and _within(sz, 0.200, 0.290)
            assert s.cap_radius < s.radius and s.body_top < s.neck_bottom < s.cap_bottom < sz
            assert _within(inst.mass, 0.5, 1.05)
        elif inst.category == "milk_carton":
            assert sx == sy and _within(sx, 0.070, 0.095) and _within(sz, 0.220, 0.265)
            assert _within(s.shoulder, 0.15, 0.24) and s.gable > 0 and s.fin > 0
            assert _within(inst.mass, 1.0, 1.5)
        elif inst.category == "bowl":
            assert sx == sy and _within(sx, 0.140, 0.170) and _within(sz, 0.050, 0.080)
            assert _within(s.wall, 0.004, 0.006) and s.foot_radius < s.rim_radius
            assert _within(inst.mass, 0.25, 0.40)
        elif inst.category == "mug":
            assert _within(sy, 0.075, 0.090) and _within(sz, 0.090, 0.110)
            assert _within(sx - sy, 0.030, 0.035)  # the handle
            assert _within(s.wall, 0.004, 0.006)
            assert _within(inst.mass, 0.30, 0.35)
        else:
            w, d, h = s.width, s.depth, s.height
            assert _within(w, 0.053, 0.063) and _within(d, 0.038, 0.040)
            assert _within(h, 0.088, 0.110) and sx == w and sy > d
            assert _within(w * d * h, 200e-6, 235e-6)
            assert _within(inst.mass, 0.19, 0.25)
        assert all(0 <= c <= 1 for c in inst.rgba + inst.accent_rgba)


def test_specular_rule():
    assert all(i.specular for i in ALL if i.category == "bowl")
    mugs = [i.specular for i in ALL if i.category == "mug"]
    assert sum(mugs) >= 8 and not all(mugs)  # most mugs glazed
    assert not any(i.specular for i in ALL if i.category not in ("bowl", "mug"))


def test_resting_poses_listed():
    for inst in ALL:
        poses = resting_poses(inst)
        names = [p.name for p in poses]
        assert names[0] == "upright" and len(set(names)) == len(names)
        assert ("side" in names) == (inst.category != "bowl")
        for p in poses:
            assert abs(np.linalg.norm(p.quat) - 1) < 1e-9 and p.height >= 0
        assert abs(poses[0].height) < 1e-9 and poses[0].quat == (1.0, 0.0, 0.0, 0.0)


# --- public API ------------------------------------------------------------------------------


def _defined_public(module) -> set[str]:
    tree = ast.parse(open(module.__file__).read())
    names: set[str] = set()
    for node in tree.body:
        if isinstance(node, ast.FunctionDef | ast.ClassDef):
            names.add(node.name)
        elif isinstance(node, ast.Assign | ast.AnnAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names |= {t.id for t in targets if isinstance(t, ast.Name)}
        elif isinstance(node, ast.ImportFrom) and module.__name__.endswith("objects"):
            names |= {a.asname or a.name for a in node.names}
    return {n for n in names if not n.startswith("_")}


def test_all_matches_public_names():
    modules = [objects] + [
        importlib.import_module(f"{objects.__name__}.{m.name}")
        for m in pkgutil.iter_modules(objects.__path__)
    ]
    assert len(modules) >= 5
    for mod in modules:
        assert set(mod.__all__) == _defined_public(mod), mod.__name__
        assert len(mod.__all__) == len(set(mod.__all__))
        for name in mod.__all__:
            assert hasattr(mod, name), f"{mod.__name__}.{name}"


# --- MuJoCo models ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def all_in_one() -> mujoco.MjModel:
    spec = _world()
    for k, inst in enumerate(ALL):
        add_object(spec, inst, f"o{k}", pos=(0.25 * (k % 10), 0.3 * (k // 10), 0.0))
    return _compile(spec)


def test_geoms_groups_masses_and_materials(all_in_one):
    m = all_in_one
    for k, inst in enumerate(ALL):
        body = m.body(f"o{k}")
        assert abs(body.mass[0] - inst.mass) < 1e-9
        assert np.all(body.inertia > 0)
        lo = np.array(inst.center) - np.array(inst.size) / 2
        assert np.all(body.ipos >= lo) and np.all(body.ipos <= lo + np.array(inst.size))
        faces, n_vis, n_col = 0, 0, 0
        for g in _body_geoms(m, f"o{k}"):
            if m.geom_group[g] == 2:
                n_vis += 1
                assert m.geom_contype[g] == 0 and m.geom_conaffinity[g] == 0
                assert m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH
                faces += m.mesh_facenum[m.geom_dataid[g]]
                spec_val = m.mat_specular[m.geom_matid[g]]
                if inst.specular:
                    assert spec_val >= SPECULAR_THRESHOLD and m.mat_shininess[m.geom_matid[g]] > 0.5
                else:
                    assert spec_val < 0.3
            else:
                n_col += 1
                assert m.geom_group[g] == 3 and m.geom_rgba[g, 3] == 0
                assert m.geom_contype[g] == 1 and m.geom_conaffinity[g] == 1
                assert m.geom_condim[g] == 3
                np.testing.assert_allclose(m.geom_friction[g], [0.8, 0.01, 0.001])
                if inst.category in ("bowl", "mug"):  # concave: primitives only
                    assert m.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH
        assert n_vis >= 1 and n_col >= 1
        assert 0 < faces <= 800, (inst.name, faces)
        if inst.category in ("bowl", "mug"):
            boxes = [
                g for g in _body_geoms(m, f"o{k}") if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX
            ]
            assert 10 <= len(boxes) <= 16


def test_visual_bounding_box_matches_size(all_in_one):
    m, d = all_in_one, mujoco.MjData(all_in_one)
    mujoco.mj_kinematics(m, d)
    for k, inst in enumerate(ALL):
        pts = []
        for g in _body_geoms(m, f"o{k}"):
            if m.geom_group[g] != 2:
                continue
            mid = m.geom_dataid[g]
            v = m.mesh_vert[m.mesh_vertadr[mid] : m.mesh_vertadr[mid] + m.mesh_vertnum[mid]]
            pts.append(
                v @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g] - d.xpos[m.body(f"o{k}").id]
            )
        pts = np.vstack(pts)
        np.testing.assert_allclose(pts.max(0) - pts.min(0), inst.size, atol=1e-6)
        np.testing.assert_allclose((pts.max(0) + pts.min(0)) / 2, inst.center, atol=1e-6)


def test_fourteen_objects_in_one_spec():
    spec = _world()
    picks = [get_instance(c, i) for c, i in itertools.product(CATEGORIES, (0, 9, 5))][:14]
    for k, inst in enumerate(picks):
        add_object(spec, inst, f"item{k}", pos=(0.3 * k, 0.0, 0.0))
    with pytest.raises(ObjectCatalogError, match="already used"):
        add_object(spec, picks[0], "item0")
    m = _compile(spec)
    assert m.nbody == 15 and m.njnt == 14
    for k in range(14):
        assert m.joint(f"item{k}_freejoint").type == mujoco.mjtJoint.mjJNT_FREE
    for objtype, n in (
        (mujoco.mjtObj.mjOBJ_GEOM, m.ngeom),
        (mujoco.mjtObj.mjOBJ_MESH, m.nmesh),
        (mujoco.mjtObj.mjOBJ_MATERIAL, m.nmat),
    ):
        names = [mujoco.mj_id2name(m, objtype, i) for i in range(n)]
        names = [x for x in names if x != "floor"]
        assert len(set(names)) == len(names)
        assert all(x.split("_")[0] in {f"item{k}" for k in range(14)} for x in names)


@pytest.mark.parametrize("category", CATEGORIES)
def test_settles_stably_in_every_resting_pose(category):
    for index in range(INSTANCES_PER_CATEGORY):
        inst = get_instance(category, index)
        for pose in resting_poses(inst):
            spec = _world()
            add_object(spec, inst, "obj", pos=(0.0, 0.0, pose.height + 0.01), quat=pose.quat)
            m = _compile(spec)
            d = mujoco.MjData(m)
            mujoco.mj_step(m, d, nstep=750)  # 1.5 s
            where = f"{inst.name} {pose.name}"
            assert np.all(np.isfinite(d.qpos)), where
            assert d.warning.number.sum() == 0, where
            assert _angle_deg(d.qpos[3:7], np.array(pose.quat)) < 10.0, where
            assert np.hypot(*d.qpos[:2]) < 0.02, where
            assert abs(d.qpos[2] - pose.height) < 0.005, where  # the height is right
            assert np.linalg.norm(d.qvel[:3]) < 0.01, where  # at rest


@pytest.mark.parametrize("category", ["bowl", "mug"])
def test_sphere_rests_inside(category):
    for index in (0, 5, 11):
        inst = get_instance(category, index)
        spec = _world()
        add_object(spec, inst, "cup")
        ball = spec.worldbody.add_body(name="ball", pos=[0.0, 0.0, inst.size[2] + 0.03])
        ball.add_freejoint()
        ball.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.01], mass=0.01)
        m = _compile(spec)
        d = mujoco.MjData(m)
        mujoco.mj_step(m, d, nstep=750)
        x, y, z = d.body("ball").xpos
        bottom = inst.shape.bottom
        assert bottom + 0.005 < z < inst.size[2], (inst.name, z)
        assert np.hypot(x, y) < 0.02, inst.name
        assert abs(z - (bottom + 0.01)) < 0.003, inst.name  # lies on the inner bottom


def test_bowls_stack():
    for index in (0, 8):
        inst = get_instance("bowl", index)
        spec = _world()
        add_object(spec, inst, "lower")
        add_object(spec, inst, "upper", pos=(0.003, 0.0, 0.04))
        m = _compile(spec)
        d = mujoco.MjData(m)
        mujoco.mj_step(m, d, nstep=750)
        z = d.body("upper").xpos[2]
        assert inst.shape.bottom < z < 0.5 * inst.size[2], (inst.name, z)
        assert np.hypot(*d.body("upper").xpos[:2]) < 0.01
        assert _angle_deg(d.body("upper").xquat, np.array([1.0, 0, 0, 0])) < 5.0
