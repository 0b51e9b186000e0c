"""A released id never changes: each released id's observations for fixed seeds and one step
are those recorded when it was released (``tests/data/<family>_<v>_digests.json``: Sorting v1
before the v2 work, v2 at its release in issue 12, Exploration v0 at its release in issue 13).

Record a new release's file (on one machine, then never again) with
``python tests/test_released_ids.py ipbench/Sorting-vN``.

Rendering (Mesa llvmpipe) and contact physics are bit-exact on one machine and library set,
not across machines, so the digests are compared where they were recorded (same CPU model and
library versions, :func:`fingerprint`) and the test is skipped elsewhere, saying why; the
intrinsics are pure arithmetic and are compared everywhere.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import ipbench.envs  # noqa: F401
from ipbench.eval.digests import platform_info
from ipbench.policies.scripted import GroundTruthSorter

DATA = Path(__file__).parent / "data"
STANDARD = [("uncluttered", 0), ("uncluttered", 7), ("cluttered", 0), ("cluttered", 7)]
RELEASED: dict[str, list[tuple[str, int]]] = {
    "ipbench/Sorting-v1": STANDARD,
    "ipbench/Sorting-v2": [*STANDARD, ("pile", 0), ("pile", 7)],
    "ipbench/Exploration-v0": [("simple", 0), ("complex", 7)],
}
"""The released ids and the (scene, seed) cases recorded for each."""


def _data_file(env_id: str) -> Path:
    family = "exploration" if "Exploration" in env_id else "sorting"
    return DATA / f"{family}_{env_id.rsplit('-', 1)[1]}_digests.json"


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
    dispatch to (an AVX2 and an AVX-512 machine of one CPU model differ) and the numeric
    libraries (:func:`ipbench.eval.digests.platform_info`)."""
    info = platform_info()
    keys = ("cpu", "mujoco", "numpy", "opencv", "numpy_simd", "blas")
    return {k: info[k] for k in keys}


def _same_platform(recorded: dict) -> bool:
    """This platform is the recording one, on the fields the recording kept (v1's file has
    the CPU model and library versions only)."""
    here = fingerprint()
    return all(here.get(k) == v for k, v in recorded.items())


def _digest(obs: dict) -> dict[str, str]:
    return {
        k: hashlib.sha256(np.ascontiguousarray(v).tobytes()).hexdigest()[:16]
        for k, v in sorted(obs.items())
    }


def observation_digests(env_id: str, scene: str, seed: int) -> dict[str, dict[str, str]]:
    """Digests of the observation after ``reset(seed)`` and after one step
    (:func:`_first_action`)."""
    env = gym.make(env_id, scene=scene)
    try:
        obs, info = env.reset(seed=seed)
        out = {"reset": _digest(obs)}
        obs, *_ = env.step(_first_action(env_id, obs, info))
        out["step"] = _digest(obs)
    finally:
        env.close()
    return out


def record(env_id: str) -> Path:
    """Write ``env_id``'s digests file (at its release: once)."""
    digests = {f"{sc}/{sd}": observation_digests(env_id, sc, sd) for sc, sd in RELEASED[env_id]}
    path = _data_file(env_id)
    path.write_text(json.dumps({"fingerprint": fingerprint(), "digests": digests}, indent=1))
    return path


@pytest.mark.parametrize(
    ("env_id", "scene", "seed"),
    [(env_id, sc, sd) for env_id, cases in RELEASED.items() for sc, sd in cases],
)
def test_released_observations_are_unchanged(env_id, scene, seed):
    recorded = json.loads(_data_file(env_id).read_text())
    want = recorded["digests"][f"{scene}/{seed}"]
    got = observation_digests(env_id, scene, seed)
    for stage in ("reset", "step"):  # intrinsics: pure arithmetic, equal on every machine
        for key in ("wrist_K", "head_left_K", "head_right_K"):
            if key in want[stage]:
                assert got[stage][key] == want[stage][key], (stage, key)
    if got != want and not _same_platform(recorded["fingerprint"]):
        # bit-exactness depends on the instruction set (OpenBLAS, llvmpipe), not the vendor:
        # equal digests on another CPU still pass; only differing ones on another one skip
        pytest.skip(
            f"digests were recorded on {recorded['fingerprint']}, this is {fingerprint()}: "
            "renders and contact physics are bit-exact only on the same machine and libraries"
        )
    assert got == want


if __name__ == "__main__":
    import sys

    print(record(sys.argv[1]))
