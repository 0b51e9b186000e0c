"""A released id never changes: each released id's observations for fixed seeds and one step
are those recorded when it was released (``tests/data/<family>_<v>_digests.json``: Sorting v1
before the v2 work; v2, Exploration v0 and Exploration v1 each at its release).

Rendering (Mesa llvmpipe) and contact physics are bit-exact within a platform family (the
same :func:`fingerprint`: CPU model, the kernels numpy and OpenBLAS dispatch to, library
versions, OpenGL renderer), not across families: OpenBLAS's SkylakeX, Haswell and Sandybridge
kernels give renders that differ in a few edge pixels and contact physics that diverges after
a pick. So every observation is checked on every platform:

* **exactly** (SHA-256 digests of every key) where a recording of this platform's family
  exists: the release record, or a platform-family file
  ``tests/data/<family>_<v>_digests.<tag>.json`` (same digests and fingerprint format, plus
  compact summaries; ``<tag>`` is a hash of the fingerprint);
* **within tolerance** elsewhere: compact summaries of each observation (:func:`summarize`:
  8x8 block means of each image, the vectors in full) are compared with a platform-family
  file's, through :func:`ipbench.eval.repro.check.check_report`, with the tolerances of
  :data:`TOLERANCES` (measured spreads there). What is compared depends on the stage's
  :func:`regime`: a settled view is compared in full, a pile's reset by its robot and cameras
  and whole-image means, a Sorting step (after a pick and place, whose contacts diverge
  across families) by its structure only.

Intrinsics are pure arithmetic and compared exactly everywhere, and so is every key's dtype
and shape.

Record a new release's file (once, at its release) with
``python tests/test_released_ids.py ipbench/Sorting-vN``. Record a new platform family's file
with ``python tests/test_released_ids.py --platform-family ipbench/Sorting-vN`` on it, but only
after showing that its code is the released behaviour: e.g. the release commit's code, checked
out with ``git worktree``, gives the same digests on that platform as the current code, or the
current code reproduces the release record when the recording platform's kernels are forced
(``OPENBLAS_CORETYPE``).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import replace
from pathlib import Path

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import ipbench.envs  # noqa: F401
from ipbench.envs.sorting import WRIST_CAMERA
from ipbench.eval.repro.check import check_report, format_report
from ipbench.eval.repro.digests import digest_arrays, platform_info
from ipbench.policies.scripted import GroundTruthSorter

__all__ = [
    "RELEASED",
    "TOLERANCES",
    "fingerprint",
    "observations",
    "record",
    "record_platform_family",
    "regime",
    "summarize",
    "tolerance_report",
]

DATA = Path(__file__).parent / "data"
STANDARD = [("uncluttered", 0), ("uncluttered", 7), ("cluttered", 0), ("cluttered", 7)]
RELEASED: dict[str, list[tuple[str, int]]] = {
    "ipbench/Sorting-v1": STANDARD,
    "ipbench/Sorting-v2": [*STANDARD, ("pile", 0), ("pile", 7)],
    "ipbench/Exploration-v0": [("simple", 0), ("complex", 7)],
    "ipbench/Exploration-v1": [("simple", 0), ("complex", 7)],
}
"""The released ids and the (scene, seed) cases recorded for each."""
STAGES = ("reset", "step")
"""The observations recorded for each case: after ``reset(seed)`` and after one step."""
GRID = 8
"""Each image is summarised by the means of GRID x GRID blocks (per colour channel)."""

# Tolerances (abs) of a summary by its kind. Measured spread between platform families, the
# same code on one machine with OpenBLAS's SkylakeX, Haswell (the Sorting-v2 recording's) and
# Sandybridge kernels: settled views' block means differ by <= 0.12 colour levels, 4e-4 m of
# depth and 4.2e-4 of valid fraction (a few edge pixels), robot joints by <= 3e-13 and camera
# poses by <= 2e-15; a pile's whole-image means by <= 0.04 levels, 3e-4 m and 5e-4, its robot
# by <= 2e-7. Changes they catch (Sorting-v2 resets): a wrist camera moved 1 mm changes block
# means by >= 0.6 levels and 0.0096 m and its pose by 7e-4; an object moved 1 mm changes some
# block by 0.48-0.82 levels; an object's colour 10 % darker by 1.6-10 levels.
TOLERANCES: dict[str, float] = {
    "rgb": 0.3,  # colour levels (0-255), block or image mean
    "depth": 1e-3,  # m, mean depth (0 where invalid) of a block or image
    "valid": 2e-3,  # fraction of a block's or image's pixels with a depth
    "vector": 1e-4,  # joints (rad, m) and camera poses (rotation entries, m)
}
"""Absolute tolerance of each kind of summary; a shape or dtype must be equal."""


def _data_file(env_id: str) -> Path:
    family = "exploration" if "Exploration" in env_id else "sorting"
    return DATA / f"{family}_{env_id.rsplit('-', 1)[1]}_digests.json"


def _recordings(env_id: str) -> list[tuple[Path, dict]]:
    """The release record, then every platform-family file of ``env_id``."""
    release = _data_file(env_id)
    files = [release, *sorted(DATA.glob(f"{release.stem}.*.json"))]
    return [(p, json.loads(p.read_text())) for p in files]


def _first_action(env_id: str, obs: dict, info: dict):
    """The recorded step: ground-truth sorting, or for exploration a saccade of +3 deg pan on
    both eyes and no report."""
    if "Exploration" not in env_id:
        return GroundTruthSorter(True).act(obs, info)
    return {
        "gaze": obs["head_qpos"] + np.radians([3.0, 0.0, 3.0, 0.0]),
        "report": {"kind": 0, "label": 0, "position": np.zeros(3)},
    }


def fingerprint() -> dict[str, object]:
    """What bit-exact reproduction depends on: the CPU model, the kernels numpy and BLAS
    dispatch to (an AVX2 and an AVX-512 machine of one CPU model differ), the numeric
    libraries and the OpenGL renderer (:func:`ipbench.eval.repro.digests.platform_info`)."""
    info = platform_info()
    keys = ("cpu", "mujoco", "numpy", "opencv", "numpy_simd", "blas", "gl")
    return {k: info[k] for k in keys}


def _same_platform(recorded: dict, here: dict) -> bool:
    """``here`` is the recording platform, on the fields the recording kept (v1's file has
    the CPU model and library versions only)."""
    return all(here.get(k) == v for k, v in recorded.items())


def _digest(obs: dict) -> dict[str, str]:
    return {
        k: hashlib.sha256(np.ascontiguousarray(v).tobytes()).hexdigest()[:16]
        for k, v in sorted(obs.items())
    }


def observations(env_id: str, scene: str, seed: int) -> dict[str, dict[str, np.ndarray]]:
    """The observation after ``reset(seed)`` and after one step (:func:`_first_action`)."""
    env = gym.make(env_id, scene=scene)
    try:
        obs, info = env.reset(seed=seed)
        out = {"reset": {k: np.asarray(v) for k, v in obs.items()}}
        obs, *_ = env.step(_first_action(env_id, obs, info))
        out["step"] = {k: np.asarray(v) for k, v in obs.items()}
    finally:
        env.close()
    return out


def regime(env_id: str, scene: str, stage: str) -> str:
    """What the tolerance comparison covers: ``"settled"`` (no contact outcome in the view:
    exploration, a Sorting reset of a standard scene) every summary; ``"pile"`` (a pile
    settles differently on every family) the robot, the cameras and whole-image means;
    ``"outcome"`` (a Sorting step: a pick and place, which measured families end with arm
    joints up to 2 rad apart) the keys' shapes and dtypes only."""
    if "Exploration" in env_id:
        return "settled"
    if stage == "step":
        return "outcome"
    return "pile" if scene == "pile" else "settled"


def _blocks(image: np.ndarray, grid: int) -> np.ndarray:
    """(grid, grid[, channels]) means of ``image``'s blocks (float64)."""
    h, w = image.shape[:2]
    rows, cols = (np.linspace(0, n, grid + 1).astype(int) for n in (h, w))
    sums = np.add.reduceat(np.add.reduceat(image.astype(np.float64), rows[:-1], 0), cols[:-1], 1)
    counts = np.outer(np.diff(rows), np.diff(cols))
    return sums / (counts[..., None] if image.ndim == 3 else counts)


def summarize(obs: dict[str, np.ndarray], kind: str) -> dict[str, float]:
    """Compact numbers of one observation under regime ``kind`` (:func:`regime`): each key's
    shape and dtype; images' block means (``GRID`` x ``GRID``, or the whole image for a pile),
    depth's valid fraction too; the vectors (joints, poses) in full. Intrinsics (``*_K``) are
    compared by digest."""
    out: dict[str, float] = {}
    for key, v in sorted(obs.items()):
        out |= {f"{key}.shape{i}": float(n) for i, n in enumerate(v.shape)}
        out[f"{key}.dtype"] = float(v.dtype.num)
        if kind == "outcome" or key.endswith("_K"):
            continue
        if v.ndim >= 2 and v.shape[0] > 4:  # an image
            grid = GRID if kind == "settled" else 1
            parts = {"rgb": v} if v.dtype == np.uint8 else {"depth": v, "valid": v > 0}
            for name, image in parts.items():
                blocks = _blocks(image, grid)
                out |= {
                    f"{key}.{name}{list(i)}": float(blocks[i]) for i in np.ndindex(blocks.shape)
                }
        else:
            out |= {f"{key}.vector[{i}]": float(x) for i, x in enumerate(v.ravel())}
    return out


def _tolerances(summary: dict[str, float]) -> dict[str, tuple[float, float]]:
    """(abs, rel) of each summary by its kind (:data:`TOLERANCES`; shape and dtype: 0)."""
    return {
        name: (TOLERANCES[kind], 0.0)
        for name in summary
        if (kind := name.rsplit(".", 1)[1].split("[")[0]) in TOLERANCES
    }


def _stage(digests: dict[str, str], summary: dict[str, float]) -> dict:
    """One stage in :mod:`ipbench.eval.repro.check`'s result layout."""
    parts = dict(sorted(digests.items()))
    return {
        "digest": digest_arrays(*(f"{k}={v}" for k, v in parts.items())),
        "parts": parts,
        "summary": summary,
    }


def tolerance_report(env_id: str, scene: str, seed: int, got: dict, reference: dict) -> dict:
    """:func:`~ipbench.eval.repro.check.check_report` of the observations ``got``
    (:func:`observations`) against a platform-family file's ``reference`` (its digests and
    summaries); stages are named ``scene/seed/stage``."""
    case, results, stages, tolerances = f"{scene}/{seed}", {}, {}, {}
    for stage in STAGES:
        name = f"{case}/{stage}"
        summary = summarize(got[stage], regime(env_id, scene, stage))
        results[name] = _stage(_digest(got[stage]), summary)
        want = reference["summaries"][case][stage]
        stages[name] = _stage(reference["digests"][case][stage], want)
        tolerances[name] = _tolerances(want)
    ref = {"stages": stages, "platform": reference["fingerprint"]}
    return check_report(results, ref, fingerprint(), tolerances)


def record(env_id: str) -> Path:
    """Write ``env_id``'s release record (at its release: once)."""
    digests = {
        f"{sc}/{sd}": {st: _digest(o) for st, o in observations(env_id, sc, sd).items()}
        for sc, sd in RELEASED[env_id]
    }
    path = _data_file(env_id)
    path.write_text(json.dumps({"fingerprint": fingerprint(), "digests": digests}, indent=1))
    return path


def record_platform_family(env_id: str) -> Path:
    """Write ``env_id``'s file of this platform family: fingerprint, digests and summaries
    (once per family, after showing its code is the released behaviour: module docstring)."""
    here = fingerprint()
    tag = digest_arrays(json.dumps(here, sort_keys=True))[:8]
    digests, summaries = {}, {}
    for sc, sd in RELEASED[env_id]:
        obs = observations(env_id, sc, sd)
        digests[f"{sc}/{sd}"] = {st: _digest(o) for st, o in obs.items()}
        summaries[f"{sc}/{sd}"] = {
            st: summarize(o, regime(env_id, sc, st)) for st, o in obs.items()
        }
    path = _data_file(env_id).with_suffix(f".{tag}.json")
    payload = {"fingerprint": here, "digests": digests, "summaries": summaries}
    path.write_text(json.dumps(payload, indent=1) + "\n")
    return path


@pytest.mark.parametrize(
    ("env_id", "scene", "seed"),
    [(env_id, sc, sd) for env_id, cases in RELEASED.items() for sc, sd in cases],
)
def test_released_observations_are_unchanged(env_id, scene, seed):
    recordings, case = _recordings(env_id), f"{scene}/{seed}"
    got = observations(env_id, scene, seed)
    digests = {stage: _digest(obs) for stage, obs in got.items()}
    want = recordings[0][1]["digests"][case]
    for stage in STAGES:  # intrinsics: pure arithmetic, equal on every platform
        for key in ("wrist_K", "head_left_K", "head_right_K"):
            if key in want[stage]:
                assert digests[stage][key] == want[stage][key], (stage, key)
    here = fingerprint()
    own = [(p, r) for p, r in recordings if _same_platform(r["fingerprint"], here)]
    if own:  # this platform family's recording: bit for bit
        path, recorded = own[0]
        assert digests == recorded["digests"][case], f"digests differ from {path.name}"
        return
    references = [(p, r) for p, r in recordings if "summaries" in r]
    assert references, f"no platform-family file of {env_id} in {DATA} to compare with"
    path, reference = references[0]
    report = tolerance_report(env_id, scene, seed, got, reference)
    assert report["verdict"] != "differs", f"{path.name}:\n{format_report(report)}"


@pytest.fixture(scope="module")
def v2_reference() -> dict:
    refs = [r for _, r in _recordings("ipbench/Sorting-v2") if "summaries" in r]
    assert refs, "no platform-family file of ipbench/Sorting-v2 with summaries"
    return refs[0]


def _change_world(monkeypatch, layout=None, world=None) -> None:
    """Sorting's ``build_world`` with its layout passed through ``layout`` and the built world
    changed in place by ``world``."""
    import ipbench.envs.sorting as sorting

    real = sorting.build_world

    def build(lay, *args, **kwargs):
        built = real(layout(lay) if layout else lay, *args, **kwargs)
        if world:
            world(built)
        return built

    monkeypatch.setattr(sorting, "build_world", build)


def _move_object(layout):
    """The first object 1 mm further along x."""
    first = layout.objects[0]
    moved = replace(first, position=np.asarray(first.position) + [0.001, 0.0, 0.0])
    return replace(layout, objects=(moved, *layout.objects[1:]))


def _move_wrist_camera(world) -> None:
    """The wrist camera 1 mm along its image's x axis."""
    m = world.model
    cam = m.camera(WRIST_CAMERA).id
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, m.cam_quat[cam])
    m.cam_pos[cam] += 0.001 * rotation.reshape(3, 3)[:, 0]


def _darken_an_object(world) -> None:
    """The first object's materials 10 % darker."""
    m = world.model
    body = world.object_bodies[0]
    geoms = [g for g in range(m.ngeom) if m.body_rootid[m.geom_bodyid[g]] == body]
    for mat in {int(m.geom_matid[g]) for g in geoms if m.geom_matid[g] >= 0}:
        m.mat_rgba[mat, :3] *= 0.9


_CASE = ("ipbench/Sorting-v2", "uncluttered", 0)
"""The case the changes are made to (a settled view of the benchmark's id)."""


def test_the_tolerance_comparison_accepts_the_unchanged_observation(v2_reference):
    report = tolerance_report(*_CASE, observations(*_CASE), v2_reference)
    assert report["verdict"] != "differs", format_report(report)


@pytest.mark.parametrize(
    ("change", "keys"),
    [
        ({"layout": _move_object}, ("head_left.rgb", "wrist_rgb.rgb")),
        (
            {"world": _move_wrist_camera},
            ("wrist_pose.vector", "wrist_rgb.rgb", "wrist_depth.depth"),
        ),
        ({"world": _darken_an_object}, ("head_left.rgb", "wrist_rgb.rgb")),
    ],
    ids=["object moved 1 mm", "wrist camera moved 1 mm", "object 10 % darker"],
)
def test_the_tolerance_comparison_catches_a_changed_observation(
    monkeypatch, v2_reference, change, keys
):
    """A reset changed by 1 mm or a colour is out of tolerance in the views' summaries (not
    only in its digests)."""
    _change_world(monkeypatch, **change)
    report = tolerance_report(*_CASE, observations(*_CASE), v2_reference)
    stage = report["stages"][f"{_CASE[1]}/{_CASE[2]}/reset"]
    assert stage["status"] == "differs", format_report(report)
    flagged = {name.split("[")[0] for name in stage["out_of_tolerance"]}
    assert set(keys) <= flagged, f"out of tolerance: {sorted(flagged)}"


if __name__ == "__main__":
    import sys

    if sys.argv[1] == "--platform-family":
        print(record_platform_family(sys.argv[2]))
    else:
        print(record(sys.argv[1]))
