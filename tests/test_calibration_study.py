"""The hand-eye study of ``ipbench eval calibration`` on a small config.

One small study (both rigs, all five methods, 3/10/20 poses, OpenCV's test noise x1 and x0.1,
spreads 2° and 45°) is shared by the tests; the noiseless and bad-input tests build their own.
"""

from __future__ import annotations

import json
import re

import mujoco
import numpy as np
import pytest

from ipbench.assets.compose import build_robot_spec
from ipbench.eval.calibration.study import (
    HEAD_LEFT_RIG,
    TARGETS,
    WRIST_RIG,
    CalibrationStudyError,
    HandEyeRig,
    HandEyeStudyConfig,
    metrics_view,
    run_hand_eye_study,
)
from ipbench.perception.calibration.hand_eye import HAND_EYE_METHODS, TSAI_ROTATION_RANGE_DEG
from ipbench.perception.calibration.poses import rotation_angle_deg

SMALL = HandEyeStudyConfig(
    pose_counts=(3, 10, 20), trials=24, diversity_spreads_deg=(2.0, 45.0), seed=3
)
CAMERAS = ("wrist", "head_left")
CV_FROM_MUJOCO = np.diag([1.0, -1.0, -1.0, 1.0])  # MuJoCo camera (-z ahead, +y up) to OpenCV


@pytest.fixture(scope="module")
def study() -> dict:
    return run_hand_eye_study(SMALL)


def _pose(data: mujoco.MjData, kind: str, name: str) -> np.ndarray:
    model_obj = getattr(data, kind)(name)
    T = np.eye(4)
    T[:3, :3] = model_obj.xmat.reshape(3, 3)
    T[:3, 3] = model_obj.xpos
    return T


def test_rig_geometry_is_the_cell_model():
    """X of both rigs against the compiled MJCF at home (joints, pan and tilt at 0)."""
    model = build_robot_spec().compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    flange = _pose(data, "site", "right_flange")
    wrist = _pose(data, "cam", "right_wrist_camera") @ CV_FROM_MUJOCO
    assert np.allclose(WRIST_RIG.X, np.linalg.inv(flange) @ wrist, atol=1e-9)
    assert np.linalg.norm(WRIST_RIG.X[:3, 3]) == pytest.approx(0.122, abs=1e-3)  # ~0.1 m
    head = _pose(data, "cam", "head_left_camera") @ CV_FROM_MUJOCO
    assert np.allclose(HEAD_LEFT_RIG.X, head, atol=1e-9)
    assert 2.3 < HEAD_LEFT_RIG.X[2, 3] < 2.4  # m above the floor
    # the nominal presenting poses: the board at 0.8 m (wrist) / 1.0 m (head), facing the
    # camera, and the flange within the MA1400's 1.434 m reach of its arm's L axis
    for rig, arm, distance in ((WRIST_RIG, "right", 0.8), (HEAD_LEFT_RIG, "left", 1.0)):
        seen = rig.target_to_camera(rig.nominal_gripper_to_base[None])[0]
        assert np.allclose(seen, rig.nominal_target_to_camera, atol=1e-12)
        assert seen[2, 3] == pytest.approx(distance)
        shoulder = data.joint(f"{arm}_joint_l").xanchor
        assert np.linalg.norm(rig.nominal_gripper_to_base[:3, 3] - shoulder) < 1.434


def test_structure_and_keys(study):
    json.dumps(study, allow_nan=False)  # JSON-ready, no NaN
    assert set(study["cameras"]) == set(CAMERAS)
    assert study["cameras"]["wrist"]["setup"] == "eye_in_hand"
    assert study["cameras"]["head_left"]["setup"] == "eye_to_hand"
    for camera in study["cameras"].values():
        assert set(camera["poses"]) == {"3", "10", "20"}
        for by_scale in camera["poses"].values():
            assert set(by_scale) == {"1", "0.1"}
            for cells in by_scale.values():
                assert tuple(cells) == HAND_EYE_METHODS
                for cell in cells.values():
                    assert cell["trials"] == SMALL.trials
                    assert 0 <= cell["failures"] < SMALL.trials
                    assert cell["failure_rate"] == cell["failures"] / SMALL.trials
                    assert (cell["failure_example"] is None) == (cell["failures"] == 0)
                    for error in ("rotation_deg", "translation_mm"):
                        assert 0 < cell[error]["median"] <= cell[error]["p90"]
        assert set(camera["diversity"]) == {"2", "45"}
        for cells in camera["diversity"].values():
            assert tuple(cells) == ("tsai", "park")
            for cell in cells.values():
                assert set(cell["opencv_unchecked"]) == {
                    "rotation_deg",
                    "translation_mm",
                    "non_finite",
                }
    view = metrics_view(study)
    assert set(view) == {"hand_eye", "targets"}
    for camera in CAMERAS:
        assert tuple(view["hand_eye"][camera]) == HAND_EYE_METHODS
        for method, entry in view["hand_eye"][camera].items():
            cell = study["cameras"][camera]["poses"]["10"]["1"][method]
            assert entry == {
                "rotation_deg": cell["rotation_deg"]["median"],
                "translation_mm": cell["translation_mm"]["median"],
            }
    json.dumps(view, allow_nan=False)


def test_noiseless_trials_recover_X_exactly():
    config = HandEyeStudyConfig(
        pose_counts=(3, 10), noise_scales=(0.0,), trials=5, diversity_spreads_deg=(45.0,)
    )
    result = run_hand_eye_study(config)
    for camera in result["cameras"].values():
        for by_scale in camera["poses"].values():
            for cell in by_scale["0"].values():
                assert cell["failures"] < cell["trials"]  # Tsai may refuse some 3-pose sets
                assert cell["rotation_deg"]["p90"] < 1e-7
                assert cell["translation_mm"]["p90"] < 1e-6


def test_error_shrinks_with_more_poses(study):
    for camera in study["cameras"].values():
        for scale in ("1", "0.1"):
            for method in HAND_EYE_METHODS:
                few, many = (camera["poses"][n][scale][method] for n in ("3", "20"))
                for error in ("rotation_deg", "translation_mm"):
                    assert many[error]["median"] < few[error]["median"], (method, error)


def test_errors_scale_with_the_noise(study):
    """The draws are shared across noise scales, so at these small noise levels X's error is
    about proportional to the scale: x0.1 noise gives a tenth of the error. It is within 10 %
    for every method from 10 poses on, except Andreff's translation: its linear solve has the
    noisy poses in its matrix, so its error has a part that grows faster than the noise."""
    for camera in study["cameras"].values():
        for n, by_scale in camera["poses"].items():
            for method in HAND_EYE_METHODS:
                full, tenth = by_scale["1"][method], by_scale["0.1"][method]
                for error in ("rotation_deg", "translation_mm"):
                    ratio = tenth[error]["median"] / full[error]["median"]
                    assert 0.06 < ratio < 0.16, (method, error, n, ratio)
                    if int(n) >= 10 and (method, error) != ("andreff", "translation_mm"):
                        assert 0.09 < ratio < 0.11, (method, error, n, ratio)


def test_hand_eye_targets_at_a_tenth_of_the_noise(study):
    view = metrics_view(study)["targets"]["hand_eye"]
    assert {k: view[k] for k in TARGETS} == TARGETS
    for camera in CAMERAS:
        for method in HAND_EYE_METHODS:
            judged = view["cameras"][camera][method]
            assert set(judged["by_poses"]) == {"10", "20"}  # every pose count >= 10
            for n, entry in judged["by_poses"].items():
                cell = study["cameras"][camera]["poses"][n]["0.1"][method]
                assert entry["met"] == (
                    cell["failures"] == 0
                    and cell["rotation_deg"]["median"] <= TARGETS["rotation_deg"]
                    and cell["translation_mm"]["median"] <= TARGETS["translation_mm"]
                )
                assert entry["failures"] == 0
                # measured: the translation target holds from 10 poses on for every method
                # but Andreff (about 1.3 mm for the head at 10 poses, up to 1.6 mm over seeds)
                if method != "andreff":
                    assert entry["translation_mm"] <= TARGETS["translation_mm"], (camera, n)
            assert judged["met"] == all(e["met"] for e in judged["by_poses"].values())
            # measured: the rotation target holds at 20 poses for all but Daniilidis (the
            # noisiest rotation: 0.015-0.022° over seeds); at 10 poses every method sits
            # about the target (0.015-0.030°), so it is judged there but not asserted
            if method != "daniilidis":
                assert judged["by_poses"]["20"]["met"], (camera, method)


def test_tiny_rotation_spreads_are_refused_for_tsai(study):
    for name, rig in (("wrist", WRIST_RIG), ("head_left", HEAD_LEFT_RIG)):
        sweep = study["cameras"][name]["diversity"]
        # 2° about the nominal: no two poses differ by 2 x 2° = 4°, below Tsai's 17.3°
        assert 2 * 2.0 < TSAI_ROTATION_RANGE_DEG[0]
        tiny = sweep["2"]["tsai"]
        assert tiny["failure_rate"] == 1.0
        assert tiny["rotation_deg"]["median"] is None
        # refused by the motion check: Tsai's window, or no pair turning even 2°
        assert re.search(r"'tsai'.*17\.3°|smaller than 2°", tiny["failure_example"])
        # unchecked, OpenCV's Tsai answers with the identity: X's whole rotation is the error
        identity = rotation_angle_deg(np.eye(4), rig.X)
        unchecked = tiny["opencv_unchecked"]["rotation_deg"]
        assert unchecked["median"] == pytest.approx(identity, abs=1e-6)
        assert unchecked["p90"] == pytest.approx(identity, abs=1e-6)
        # 45° works for Tsai; small rotations also break Park, which runs but is far worse
        assert sweep["45"]["tsai"]["failures"] == 0
        park_tiny, park_wide = sweep["2"]["park"], sweep["45"]["park"]
        assert park_tiny["failure_rate"] < 1.0
        for error in ("rotation_deg", "translation_mm"):
            assert park_tiny[error]["median"] > 5 * park_wide[error]["median"]


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"pose_counts": (2, 10)}, r"pose count 2; valid: an integer >= 3"),
        ({"pose_counts": ()}, r"pose_counts \(\); valid: a non-empty tuple"),
        ({"methods": ("tsai", "surf")}, r"unknown method 'surf'; valid: tsai, park, horaud"),
        ({"diversity_methods": ("shah",)}, r"unknown method 'shah'; valid: tsai"),
        ({"noise_scales": (1.0, -0.1)}, r"noise scale -0.1; valid: a number in \[0, 1000\]"),
        ({"noise_scales": (0.1, 0.1)}, r"noise_scales \(0.1, 0.1\) repeat a value"),
        ({"trials": 0}, r"trials 0; valid: an integer >= 1"),
        ({"trials": 2.5}, r"trials 2.5; valid: an integer >= 1"),
        ({"rotation_spread_deg": 0.0}, r"rotation spread \(deg\) 0.0; valid: .*\(0, 180\]"),
        ({"diversity_spreads_deg": (5.0, 200.0)}, r"spread \(deg\) 200.0; valid"),
        ({"rigs": (WRIST_RIG, WRIST_RIG)}, r"rig names \['wrist', 'wrist'\] repeat"),
    ],
)
def test_bad_config_values_are_refused(changes, message):
    with pytest.raises(CalibrationStudyError, match=message):
        HandEyeStudyConfig(**changes)


def test_bad_rigs_and_studies_are_refused():
    good = dict(
        name="wrist",
        setup="eye_in_hand",
        X=np.eye(4),
        fixed=np.eye(4),
        nominal_target_to_camera=np.eye(4),
        position_half_extents_m=(0.1, 0.1, 0.1),
    )
    with pytest.raises(CalibrationStudyError, match="'eye_on_base'; valid: eye_in_hand, eye_to"):
        HandEyeRig(**{**good, "setup": "eye_on_base"})
    with pytest.raises(CalibrationStudyError, match="'wrist' X has a rotation part that is not"):
        HandEyeRig(**{**good, "X": np.diag([2.0, 1.0, 1.0, 1.0])})
    with pytest.raises(CalibrationStudyError, match="three finite lengths >= 0"):
        HandEyeRig(**{**good, "position_half_extents_m": (0.1, -0.1, 0.1)})
    with pytest.raises(CalibrationStudyError, match="valid: a HandEyeStudyConfig"):
        run_hand_eye_study({"trials": 3})
    with pytest.raises(CalibrationStudyError, match="not a run_hand_eye_study result"):
        metrics_view({"hand_eye": {}})
    no_ten = run_hand_eye_study(
        HandEyeStudyConfig(
            pose_counts=(3,), trials=1, methods=("park",), diversity_spreads_deg=(45.0,)
        )
    )
    with pytest.raises(CalibrationStudyError, match="no cell at 10 poses.*10 in pose_counts"):
        metrics_view(no_ten)
