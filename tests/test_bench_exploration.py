"""ipbench bench exploration: the figures of each exploration id, named by its version."""

from __future__ import annotations

import pytest

from ipbench.eval.bench.exploration import bench_exploration, figure_suffix
from ipbench.eval.bench.sim import TARGETS
from ipbench.eval.exploration.evaluate import ExplorationEvalError


def test_a_foveated_id_is_measured_with_its_cameras_and_named_by_its_version(tmp_path):
    figures = bench_exploration(
        tmp_path, ("sift",), cycles=1, frames=1, env_id="ipbench/Exploration-v1",
        head_size=(256, 384),
    )  # fmt: skip
    assert set(figures) == {
        "stereo_fps_v1_256x384",
        "cycle_s_sift_v1_256x384",
        "cycle_s_v1_256x384",
    }
    assert all(v > 0 for v in figures.values())
    # the database was captured at the bench's size with v1's upright prints: one cache entry
    assert len(list(tmp_path.glob("exploration-db-sift-*.npz"))) == 1


def test_figures_are_named_by_version_and_size_so_only_v0_at_its_size_meets_the_targets(
    tmp_path,
):
    v0, v1 = (680, 1024), (3264, 4928)
    assert figure_suffix("ipbench/Exploration-v0", v0, v0) == ""
    assert figure_suffix("ipbench/Exploration-v0", (256, 384), v0) == "_256x384"
    assert figure_suffix("ipbench/Exploration-v1", v1, v1) == "_v1"
    assert figure_suffix("ipbench/Exploration-v1", (1632, 2464), v1) == "_v1_1632x2464"
    figures = bench_exploration(tmp_path, ("sift",), cycles=1, frames=1, head_size=(256, 384))
    assert set(figures) == {"stereo_fps_256x384", "cycle_s_sift_256x384", "cycle_s_256x384"}
    assert not set(figures) & set(TARGETS)  # a smaller image does not meet v0's targets
    assert {"stereo_fps", "cycle_s"} <= set(TARGETS)  # the names v0 at its size reports


def test_an_unknown_id_says_which_are_valid(tmp_path):
    with pytest.raises(ExplorationEvalError, match="valid: ipbench/Exploration-v0"):
        bench_exploration(tmp_path, ("orb",), env_id="ipbench/Exploration-v9")
