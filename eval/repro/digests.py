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

import time
from collections.abc import Callable, Iterable

from ipbench.eval.repro import stages_perception as perception
from ipbench.eval.repro import stages_sim as sim
from ipbench.eval.repro.platform import platform_info
from ipbench.eval.repro.stage import (
    EPISODE_STEPS,
    LAYOUT_SEEDS,
    PHYSICS_STEPS,
    Stage,
    StageResult,
    digest_arrays,
)
from ipbench.eval.repro.stages_perception import synthetic_cloud
from ipbench.eval.repro.stages_sim import synthetic_depth_images

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

# -- the registry -----------------------------------------------------------------------------
# Tolerances (abs, rel): "close" is what round-off differences alone do to a summary, measured
# on the reference machine by perturbing each stage's input at round-off level (1e-12 m on the
# objects' reset poses, 1e-15 relative on the GP's inputs, 1e-12 m on the cloud) and by running
# BLAS on 2 threads instead of 1; the measurements are in
# ipbench.eval.repro.check's docstring. Summaries
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
            sim.stage_model,
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
            sim.stage_layout,
            f"object layouts, every scene and catalogue, seeds 0-{LAYOUT_SEEDS[-1]}",
            {k: (1e-6, 0.0) for k in ("x_mean_m", "y_mean_m", "z_mean_m", "yaw_mean_rad")},
            cheap=True,
        ),
        Stage(
            "physics_settle",
            sim.stage_physics_settle,
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
            sim.stage_physics_skill,
            "one scripted pick-and-place after that reset",
            {"others_moved_mean_m": (1e-4, 0.0), "sim_time_s": (0.1, 0.0)},
            depends_on=("physics_settle",),
        ),
        Stage(
            "render_fixed",
            sim.stage_render_fixed,
            "overview RGB-D of the v1 and v2 models at the home keyframe (no physics)",
            {f"{c}_{k}": tol for c in ("v1", "v2") for k, tol in _IMG.items()},
            depends_on=("model",),
        ),
        Stage(
            "render_reset",
            sim.stage_render_reset,
            "wrist RGB, depth and segmentation after reset(seed=0)",
            {**_IMG, "object_fraction": (1e-3, 0.0)},
            depends_on=("physics_settle",),
        ),
        Stage(
            "noise_synthetic",
            sim.stage_noise_synthetic,
            "v1 and v2 depth noise on five synthetic images",
            {f"{s}_{k}": tol for s in ("v1", "v2") for k, tol in _NOISE.items()},
            cheap=True,
        ),
        Stage(
            "noise_rendered",
            sim.stage_noise_rendered,
            "v1 and v2 depth noise on the rendered wrist depth",
            {f"{s}_{k}": tol for s in ("v1", "v2") for k, tol in _NOISE.items()},
            depends_on=("render_reset",),
        ),
        Stage(
            "perception",
            perception.stage_perception,
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
            perception.stage_codebook,
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
            perception.stage_gpc,
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
            perception.stage_threshold,
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
                (lambda v=v: sim.stage_episode(f"ipbench/Sorting-{v}")),
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
