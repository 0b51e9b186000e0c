"""Calibration figures over seeds: distributions and paired comparisons of per-seed records."""

from __future__ import annotations

import numpy as np
import pytest

from ipbench.eval.calibration.aggregate import aggregate, comparison, distribution
from ipbench.eval.stats import bootstrap_ci


def record(seed: int, true: float, encoders: float, checked: float, chosen: list[str]) -> dict:
    """A seed's record with the fields aggregate reads; ``chosen`` is each trial's check."""
    trials = [
        {
            "check": {"chosen": c},
            "board_distance_m": 1.4 + 0.1 * k + 0.01 * seed,
            "incidence_deg": 10.0 + 20.0 * k,
            "rmse_mm": {"true": true, "encoders": encoders, "dynamic_checked": checked}
            | ({"dynamic_both": checked + 0.01 * k} if c == "dynamic_both" else {}),
        }
        for k, c in enumerate(chosen)
    ]
    methods = {"true": true, "encoders": encoders, "dynamic_checked": checked,
               "dynamic_both": checked, "dynamic": encoders}  # fmt: skip
    cam = {"nominal": {"rotation_deg": 2.0 + seed, "translation_mm": 20.0},
           "calibrated": {"rotation_deg": 0.05, "translation_mm": 1.0 + seed}}  # fmt: skip
    return {
        "seed": seed,
        "hand_eye": {"wrist": {"tsai": {"rotation_deg": 0.2, "translation_mm": 7.0 + seed}}},
        "self_calibration": {"cameras": {"wrist": cam}},
        "reconstruction": {
            "head": {
                "methods": {m: {"rmse_mm": v} for m, v in methods.items()},
                "per_trial": trials,
            },  # fmt: skip
            "wrist_rmse_mm": 5.0,
            "wrist_robot_rmse_mm": 4.0 + seed,
            "wrist_robot_nominal_rmse_mm": 9.0,
        },
    }


RECORDS = [
    record(2, 0.10, 0.40, 0.20, ["dynamic_both", "encoders"]),
    record(0, 0.12, 0.30, 0.15, ["dynamic_both", "dynamic_both"]),
    record(1, 0.08, 0.50, 0.30, ["encoders", "encoders"]),
]


def test_every_figure_is_a_distribution_over_the_seeds_in_seed_order():
    metrics = aggregate(RECORDS, robot_seed=1)
    assert metrics["seeds"] == [0, 1, 2]
    head = metrics["reconstruction"]["head_encoders_rmse_mm"]
    assert head["values"] == [0.30, 0.50, 0.40] and head["n"] == 3
    assert head["mean"] == pytest.approx(0.4) and head["median"] == pytest.approx(0.4)
    mean, low, high = bootstrap_ci([0.30, 0.50, 0.40])
    assert (head["ci_low"], head["ci_high"]) == (low, high) and low < mean < high
    assert metrics["reconstruction"]["head_fallback_rate"]["values"] == [0.0, 1.0, 0.5]
    # against the truth: the update (0.21 on seed 0's second trial) is never worse than 0.30
    assert metrics["reconstruction"]["head_unchecked_worse_rate"]["values"] == [0.0, 0.0]
    he = metrics["hand_eye"]["wrist"]["tsai"]["translation_mm"]
    assert he["values"] == [7.0, 8.0, 9.0]
    sc = metrics["self_calibration"]["wrist"]
    assert sc["calibrated"]["translation_mm"]["values"] == [1.0, 2.0, 3.0]
    assert sc["nominal"]["rotation_deg"]["mean"] == pytest.approx(3.0)


def test_comparisons_are_paired_by_seed():
    metrics = aggregate(RECORDS, robot_seed=1)
    c = metrics["comparisons"]["head_dynamic_minus_encoders_rmse_mm"]
    assert c["values"] == pytest.approx([-0.15, -0.20, -0.20]) and c["n"] == 3
    assert c["mean"] == pytest.approx(np.mean([-0.15, -0.20, -0.20]))
    assert c["ci_high"] < 0 and 0 < c["p_value"] <= 1
    w = metrics["comparisons"]["wrist_calibrated_minus_nominal_translation_mm"]
    assert w["values"] == pytest.approx([-19.0, -18.0, -17.0])
    robot = metrics["comparisons"]["wrist_robot_calibrated_minus_nominal_rmse_mm"]
    assert robot["values"] == pytest.approx([-5.0, -4.0, -3.0])


def test_missing_values_are_left_out_and_one_value_has_no_interval():
    assert distribution([None, float("nan")]) is None
    one = distribution([0.3, None])
    assert one["n"] == 1 and one["mean"] == 0.3 and one["ci_low"] is None
    assert comparison({0: 1.0, 1: None}, {1: 2.0}) is None
    c = comparison({0: 1.0, 1: 3.0, 2: None}, {0: 0.5, 1: 2.0, 2: 1.0})
    assert c["n"] == 2 and c["values"] == [0.5, 1.0]


def test_the_floor_is_related_to_the_scored_boards_geometry():
    floor = aggregate(RECORDS, robot_seed=1)["head_floor"]
    assert floor["trials"] == 6
    assert floor["median_rmse_mm"] == pytest.approx(0.10)
    assert floor["board_distance_m"]["min"] == pytest.approx(1.40)
    assert floor["incidence_deg"]["max"] == pytest.approx(30.0)
    # each seed's floor is the same in both its trials: no rank relation with incidence
    assert floor["incidence_deg"]["spearman_rho"] == pytest.approx(0.0)
    assert aggregate(RECORDS[:1], robot_seed=1)["head_floor"] is None  # two trials: too few
