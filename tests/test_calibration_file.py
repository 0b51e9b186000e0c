"""The calibration file: exact round trip, readable JSON, every refusal with its message."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from ipbench.envs.cell.calibration_file import (
    FORMAT_VERSION,
    CalibrationFile,
    CalibrationFileError,
    CameraCalibration,
    HandEyeEntry,
    StereoEntry,
)

CAMERAS = ("head_left", "head_right", "wrist")


def rigid(rng: np.random.Generator, scale: float = 0.5) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(rng.normal(0, 1, 3))[0]
    T[:3, 3] = rng.normal(0, scale, 3)
    return T


def make(seed: int = 0) -> CalibrationFile:
    """A calibration with values like a run's: non-round floats everywhere."""
    rng = np.random.default_rng(seed)
    cameras = []
    for name, (w, h), f in (("head_left", (1024, 680), 1519.0), ("head_right", (1024, 680), 1519.0),
                            ("wrist", (640, 480), 577.0)):  # fmt: skip
        K = np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1.0]])
        K[:2] += np.array([[rng.normal(0, 3), 0, rng.normal(0, 2)], [0, rng.normal(0, 3), 1.7]])
        cameras.append(CameraCalibration(name, K, rng.normal(0, 0.05, 5), (w, h), rng.random()))
    hand_eye = {
        "wrist": HandEyeEntry("tsai", "eye_in_hand", rigid(rng, 0.1), 0.13, 1.21, 10),
        "head_left": HandEyeEntry("park", "eye_to_hand", rigid(rng, 2.0), 0.051, 0.73, 12),
    }
    stereo = StereoEntry("head_left", "head_right", rigid(rng, 0.29), 0.21)
    return CalibrationFile(tuple(cameras), hand_eye, stereo, seed=seed)


def test_round_trip_is_exact(tmp_path):
    original = make()
    path = original.save(tmp_path / "calib.json")
    loaded = CalibrationFile.load(path, expect_cameras=CAMERAS)
    assert loaded.to_dict() == original.to_dict()
    assert loaded.camera_names == CAMERAS
    for name in CAMERAS:
        a, b = original.camera(name), loaded.camera(name)
        assert np.array_equal(a.K, b.K) and np.array_equal(a.dist, b.dist)
        assert (a.image_size, a.rms_px) == (b.image_size, b.rms_px)
    for name, entry in original.hand_eye.items():
        assert np.array_equal(loaded.hand_eye[name].X, entry.X)
        assert loaded.hand_eye[name].method == entry.method
    assert np.array_equal(loaded.stereo.left_to_right, original.stereo.left_to_right)
    assert (loaded.created, loaded.seed, loaded.format_version) == (
        original.created, 0, FORMAT_VERSION,
    )  # fmt: skip
    # saved again, the text is identical
    assert loaded.save(tmp_path / "again.json").read_text() == path.read_text()


def test_file_is_readable_json_with_one_matrix_row_per_line(tmp_path):
    path = make().save(tmp_path / "calib.json")
    text = path.read_text()
    data = json.loads(text)
    assert data["format"] == "ipbench-calibration" and data["format_version"] == 1
    assert set(data["cameras"]) == set(CAMERAS)
    assert data["hand_eye"]["wrist"]["method"] == "tsai"
    row = json.dumps(data["stereo"]["left_to_right"][0])
    assert any(line.strip().rstrip(",") == row for line in text.splitlines())
    assert len(text.splitlines()) < 80


def test_a_run_without_hand_eye_or_stereo_round_trips(tmp_path):
    wrist = make().camera("wrist")
    original = CalibrationFile((wrist,))
    loaded = CalibrationFile.load(original.save(tmp_path / "c.json"), expect_cameras=["wrist"])
    assert loaded.to_dict() == original.to_dict()
    assert loaded.stereo is None and dict(loaded.hand_eye) == {} and loaded.seed is None


def test_existing_file_is_not_overwritten_unless_asked(tmp_path):
    path = tmp_path / "calib.json"
    path.write_text("precious")
    with pytest.raises(
        CalibrationFileError, match="exists and was not overwritten.*overwrite=True"
    ):
        make().save(path)
    assert path.read_text() == "precious"
    make(1).save(path, overwrite=True)
    assert CalibrationFile.load(path).seed == 1
    assert [p.name for p in tmp_path.iterdir()] == ["calib.json"]  # no temporary left


def test_missing_file_and_folder(tmp_path):
    with pytest.raises(CalibrationFileError, match=r"nope.json does not exist; make one with "
                       r"`ipbench calibrate --out .*nope.json`"):  # fmt: skip
        CalibrationFile.load(tmp_path / "nope.json")
    with pytest.raises(CalibrationFileError, match="is a folder"):
        CalibrationFile.load(tmp_path)
    with pytest.raises(CalibrationFileError, match="folder .* does not exist"):
        make().save(tmp_path / "no" / "calib.json")


def written(tmp_path, data) -> str:
    path = tmp_path / "calib.json"
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return path


def mutate(change):
    data = make().to_dict()
    change(data)
    return data


def _set(keys, value):
    def change(data):
        d = data
        for k in keys[:-1]:
            d = d[k]
        d[keys[-1]] = value

    return change


def _del(keys):
    def change(data):
        d = data
        for k in keys[:-1]:
            d = d[k]
        del d[keys[-1]]

    return change


SCALED = (np.eye(4) * [1.01, 1.0, 1.0, 1.0]).tolist()


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ("{not json", r"is not JSON \(Expecting property name"),
        ("", r"is not JSON"),
        ([1, 2], r"not an ipbench calibration file \(\"format\" is 'list'\)"),
        ({"format": "other"}, r"not an ipbench calibration file \(\"format\" is 'other'\)"),
        (mutate(_set(["format_version"], 2)), r"format version 2; this ipbench reads version 1"),
        (mutate(_del(["stereo"])), r"the file lacks keys \['stereo'\]; valid keys"),
        (mutate(_set(["extra"], 1)), r"the file has unknown keys \['extra'\]; valid keys"),
        (mutate(_del(["cameras", "wrist", "K"])), r"cameras.wrist lacks keys \['K'\]"),
        (mutate(_set(["cameras"], {})), r"cameras is \{\}; valid: .* with one or more cameras"),
        (mutate(_set(["cameras", "wrist", "K"], [[1.0, 0, 0], [0, 1.0, 0]])),
         r"cameras.wrist.K has shape \(2, 3\); valid: shape \(3, 3\)"),
        (mutate(_set(["cameras", "wrist", "K"], [[1, 0, 0], [0, 1, 0], [0, 0, 2]])),
         r"cameras.wrist.K = .* is not a camera matrix"),
        (mutate(_set(["cameras", "head_left", "dist"], [0.1, 0.2, 0.3])),
         r"cameras.head_left.dist has 3 entries; valid: a flat list of 4, 5, 8, 12, 14"),
        (mutate(_set(["cameras", "head_left", "dist"], [[0.1, 0.2, 0.3, 0.4, 0.5]])),
         r"cameras.head_left.dist has 1 entries"),
        (mutate(_set(["cameras", "wrist", "image_size"], [640, -480])),
         r"cameras.wrist.image_size\[1\] \(height\) is -480; valid: an integer >= 1"),
        (mutate(_set(["cameras", "wrist", "rms_px"], "0.2")), r"cameras.wrist.rms_px is '0.2'"),
        (mutate(_set(["cameras", "wrist", "K"], [[float("nan"), 0, 0], [0, 1, 0], [0, 0, 1]])),
         r"cameras.wrist.K has non-finite values"),
        (mutate(_set(["stereo", "rms_px"], float("inf"))), r"stereo.rms_px is inf"),
        (mutate(_set(["stereo", "left_to_right"], SCALED)),
         r"stereo.left_to_right has a rotation part that is not a proper rotation"),
        (mutate(_set(["hand_eye", "wrist", "X"], SCALED)),
         r"hand_eye.wrist.X has a rotation part that is not a proper rotation"),
        (mutate(_set(["hand_eye", "wrist", "X"], "eye")),
         r"hand_eye.wrist.X is not an array of numbers"),
        (mutate(_set(["hand_eye", "wrist", "method"], "magic")),
         r"hand_eye.wrist.method is 'magic'; valid: tsai, park, horaud, andreff, daniilidis"),
        (mutate(_set(["hand_eye", "wrist", "n_poses"], 2)),
         r"hand_eye.wrist.n_poses is 2; valid: an integer >= 3"),
        (mutate(_set(["hand_eye", "kinect"], {"n_poses": 2})), r"hand_eye.kinect lacks keys"),
        (mutate(_set(["stereo", "right"], "wrist_right")),
         r"stereo names camera 'wrist_right', which the file does not calibrate"),
        (mutate(_set(["created"], "yesterday")), r"created is 'yesterday'; valid: an ISO 8601"),
        (mutate(_set(["seed"], -1)), r"seed is -1; valid: an integer >= 0"),
    ],
)  # fmt: skip
def test_bad_files_are_refused_with_what_was_wrong(tmp_path, data, message):
    path = written(tmp_path, data)
    with pytest.raises(CalibrationFileError, match=message) as caught:
        CalibrationFile.load(path)
    assert f"ipbench calibrate --out {path}" in str(caught.value)
    assert str(path) in str(caught.value)


def test_non_finite_json_tokens_are_refused(tmp_path):
    text = json.dumps(make().to_dict()).replace('"rms_px": 0.21', '"rms_px": NaN')
    assert "NaN" in text
    with pytest.raises(CalibrationFileError, match=r"stereo.rms_px is nan"):
        CalibrationFile.load(written(tmp_path, text))


def test_hand_eye_of_an_uncalibrated_camera_is_refused(tmp_path):
    data = make().to_dict()
    data["hand_eye"]["kinect"] = data["hand_eye"]["wrist"]
    with pytest.raises(CalibrationFileError, match=r"hand_eye names camera 'kinect'.*valid: \["):
        CalibrationFile.load(written(tmp_path, data))


def test_cameras_other_than_expected_are_refused(tmp_path):
    path = make().save(tmp_path / "calib.json")
    with pytest.raises(CalibrationFileError) as caught:
        CalibrationFile.load(path, expect_cameras=("head_left", "head_right"))
    text = str(caught.value)
    assert "calibrates cameras ['head_left', 'head_right', 'wrist']" in text
    assert "expected ['head_left', 'head_right']" in text
    assert "not expected: ['wrist']" in text
    assert f"ipbench calibrate --cameras ... --out {path}" in text
    with pytest.raises(CalibrationFileError, match=r"missing: \['kinect'\]"):
        CalibrationFile.load(path, expect_cameras=[*CAMERAS, "kinect"])
    assert CalibrationFile.load(path, expect_cameras=reversed(CAMERAS)).camera_names == CAMERAS


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: CameraCalibration("wrist", np.eye(4), np.zeros(5), (640, 480), 0.1),
         r"cameras.wrist.K has shape \(4, 4\)"),
        (lambda: CameraCalibration("wrist", np.eye(3), np.zeros(5), (640,), 0.1),
         r"image_size is \(640,\); valid: \[width, height\]"),
        (lambda: HandEyeEntry("tsai", "eye_on_head", np.eye(4), 0.1, 0.1, 5),
         r"setup is 'eye_on_head'; valid: eye_in_hand, eye_to_hand"),
        (lambda: StereoEntry("head_left", "head_left", np.eye(4), 0.1), r"both 'head_left'"),
        (lambda: CalibrationFile(()), r"valid: one or more CameraCalibration"),
        (lambda: CalibrationFile((make().camera("wrist"),) * 2), r"unique names"),
        (lambda: CalibrationFile((make().camera("wrist"),), format_version=2),
         r"format version 2"),
    ],
)  # fmt: skip
def test_bad_entries_are_refused_when_built(build, message):
    with pytest.raises(CalibrationFileError, match=message):
        build()


def test_opencv_shaped_distortion_is_flattened_and_arrays_are_read_only():
    dist = np.array([[0.1, -0.2, 0.001, 0.002, 0.05]])  # calibrateCamera's (1, 5)
    camera = CameraCalibration("wrist", np.eye(3), dist, (640, 480), 0.3)
    assert camera.dist.shape == (5,)
    with pytest.raises(ValueError, match="read-only"):
        camera.K[0, 0] = 2.0
    assert dist.flags.writeable  # the caller's array untouched


def test_the_files_vocabulary_is_the_routines():
    """The file (read by the envs, which may not import perception) names the methods and
    set-ups as ipbench.perception.calibration.hand_eye does."""
    from ipbench.envs.cell import calibration_file as f
    from ipbench.perception.calibration import hand_eye as h

    assert f.METHODS == h.HAND_EYE_METHODS + h.ROBOT_WORLD_METHODS
    assert f.SETUPS == h.SETUPS and f.MIN_POSES == h.MIN_POSES


@pytest.mark.parametrize("seed", [4, None])
def test_the_measured_cell_round_trips_and_older_files_lack_it(tmp_path, seed):
    wrist = make().camera("wrist")
    original = CalibrationFile((wrist,), cell={"robot_seed": seed})
    path = original.save(tmp_path / "c.json")
    assert json.loads(path.read_text())["cell"] == {"robot_seed": seed}
    loaded = CalibrationFile.load(path)
    assert dict(loaded.cell) == {"robot_seed": seed}
    data = json.loads(path.read_text())
    del data["cell"]
    assert CalibrationFile.from_dict(data).cell is None  # unknown, still loads


@pytest.mark.parametrize("cell", [{"robot_seed": -1}, {"robot_seed": 1.5}, {"seed": 1}, [1]])
def test_a_bad_cell_is_refused_with_the_valid_form(cell):
    with pytest.raises(CalibrationFileError, match=r"cell is .*valid: \{\"robot_seed\": R\}"):
        CalibrationFile((make().camera("wrist"),), cell=cell)
