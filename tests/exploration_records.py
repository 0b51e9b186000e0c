"""Synthetic exploration episode records for the report tests: consistent SIFT records whose
performances are known by hand."""

from __future__ import annotations

BUDGET = 4
N = 10  # database instances per episode


def record(scene: str, policy: str, seed: int, tp: int, fp: int) -> dict:
    """A consistent SIFT record with ``tp`` of N instances found and ``fp`` false positives."""
    return {
        "scene": scene,
        "policy": policy,
        "feature": "sift",
        "seed": seed,
        "n_database": N,
        "true_positives": tp,
        "false_positives": fp,
        "not_found": N - tp,
        "performance": tp / (N + fp),
        "recovered": 0,
        "fp_reasons": {"wrong_class": fp, "already_reported": 0, "nothing_there": 0},
        "saccades": 2,
        "sim_time_s": 3.0,
        "wall_time_s": 3.0,
        "steps": 3,
        "recall_curve": [0.0, tp / N / 2, tp / N],
        "saccades_to_all": 2 if tp == N else None,
        "sim_s_to_all": 3.0 if tp == N else None,
        "refixation_rate": 0.0,
        "localisation_mm": [10.0] * tp,
        "halted": True,
        "truncated": False,
        "video": None,
        "cycle_s": 0.5,
    }


def sample_records(seeds=range(20), late_drop: int = 0) -> list[dict]:
    """active-vision finds 5 + seed % 3 instances; random-gaze 2 fewer, and ``late_drop``
    fewer again on seeds 10 and up; oracle-gaze finds 8; raster-scan only ran seeds 0-9."""
    out = []
    for seed in seeds:
        av = 5 + seed % 3
        out.append(record("simple", "active-vision", seed, av, 0))
        out.append(record("simple", "random-gaze", seed, av - 2 - late_drop * (seed >= 10), 0))
        out.append(record("simple", "oracle-gaze", seed, 8, 0))
        if seed < 10:
            out.append(record("simple", "raster-scan", seed, av, 0))
    return out
