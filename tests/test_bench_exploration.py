"""ipbench bench exploration: the figures of each exploration id, named by its version."""

from __future__ import annotations

import pytest

from ipbench.eval.bench.exploration import bench_exploration
from ipbench.eval.bench.sim import TARGETS
from ipbench.eval.exploration.evaluate import ExplorationEvalError


def test_a_foveated_id_is_measured_with_its_cameras_and_named_by_its_version(tmp_path):
    figures = bench_exploration(
        tmp_path, ("sift",), cycles=1, frames=1, env_id="ipbench/Exploration-v1",
        head_size=(256, 384),
    )  # fmt: skip
    assert set(figures) == {"stereo_fps_v1", "cycle_s_sift_v1", "cycle_s_v1"}
    assert all(v > 0 for v in figures.values())
    # the database was captured at the bench's size with v1's upright prints: one cache entry
    assert len(list(tmp_path.glob("exploration-db-sift-*.npz"))) == 1


def test_v0s_figures_keep_the_names_its_targets_use(tmp_path):
    figures = bench_exploration(tmp_path, ("sift",), cycles=1, frames=1, head_size=(256, 384))
    assert set(figures) == {"stereo_fps", "cycle_s_sift", "cycle_s"}
    assert set(figures) & set(TARGETS) == {"stereo_fps", "cycle_s"}


def test_an_unknown_id_says_which_are_valid(tmp_path):
    with pytest.raises(ExplorationEvalError, match="valid: ipbench/Exploration-v0"):
        bench_exploration(tmp_path, ("orb",), env_id="ipbench/Exploration-v9")
