"""Object database and MSCOI recognition on synthetic scenes of textured patches."""

from __future__ import annotations

import numpy as np
import pytest
from test_features2d import background, object_mask, paste, textured_patch

from ipbench.perception.features2d import FEATURE_TYPES, ActiveVisionError, detect
from ipbench.perception.matching import match_many
from ipbench.perception.object_database import (
    DatabaseFileError,
    ObjectDatabase,
    ObjectView,
)
from ipbench.perception.recognition import RecognitionConfig, recognise

CLASSES = {"cereal": 11, "tea": 12, "soap": 13}
UNKNOWN = 99


def _views() -> list[ObjectView]:
    """Two views of each class alone on a plain background: upright, and turned and shrunk."""
    views = []
    for name, seed in CLASSES.items():
        patch = textured_patch(seed)
        for angle, scale in ((0.0, 1.0), (25.0, 0.8)):
            canvas = np.full((280, 300), 128, np.uint8)
            image, M = paste(canvas, patch, (150, 140), angle, scale)
            views.append(ObjectView(image, object_mask(canvas.shape, patch, M), name))
    return views


@pytest.fixture(scope="module", params=FEATURE_TYPES)
def database(request):
    return ObjectDatabase.build(_views(), request.param)


def test_two_instances_side_by_side_are_found_separately(database):
    patch = textured_patch(CLASSES["tea"])
    # two tea boxes touching (200 px wide, centres 205 px apart), a soap box, clutter
    scene, _ = paste(background(5), patch, (300, 340), 10.0, 1.0)
    scene, _ = paste(scene, patch, (505, 345), -5.0, 1.0)
    scene, _ = paste(scene, textured_patch(CLASSES["soap"]), (820, 200), 0.0, 0.9)
    found = recognise(detect(scene, database.feature_type), database)
    tea = sorted((h for h in found.hypotheses if h.class_name == "tea"), key=lambda h: h.centre[0])
    assert [h.class_name for h in found.hypotheses].count("tea") == 2
    np.testing.assert_allclose(tea[0].centre, (300, 340), atol=3.0)
    np.testing.assert_allclose(tea[1].centre, (505, 345), atol=3.0)
    assert not set(tea[0].inlier_indices) & set(tea[1].inlier_indices)
    assert all(h.inliers >= 10 and 0 < h.score <= 1 for h in found.hypotheses)
    soap = [h for h in found.hypotheses if h.class_name == "soap"]
    assert len(soap) == 1 and np.linalg.norm(soap[0].centre - (820, 200)) < 3.0
    assert {h.class_name for h in found.hypotheses} == {"tea", "soap"}
    # the outline is the 200 x 160 patch's box turned by the paste
    sides = np.linalg.norm(np.diff(tea[0].outline, axis=0, append=tea[0].outline[:1]), axis=1)
    np.testing.assert_allclose(sides, (199, 159, 199, 159), atol=4.0)


def test_an_unknown_patch_yields_no_hypothesis_and_stays_unmatched(database):
    scene, M = paste(background(6), textured_patch(UNKNOWN), (512, 340), 15.0, 1.2)
    features = detect(scene, database.feature_type)
    found = recognise(features, database)
    assert found.hypotheses == ()
    np.testing.assert_array_equal(found.unmatched, np.arange(len(features)))


def test_unmatched_are_the_keypoints_no_hypothesis_explains(database):
    scene, _ = paste(background(7), textured_patch(CLASSES["cereal"]), (300, 340))
    scene, M = paste(scene, textured_patch(UNKNOWN), (750, 340))
    features = detect(scene, database.feature_type)
    found = recognise(features, database)
    assert [h.class_name for h in found.hypotheses] == ["cereal"]
    on_unknown = object_mask(scene.shape, textured_patch(UNKNOWN), M)
    cols, rows = np.round(features.xy[found.unmatched]).astype(int).T
    inside = on_unknown[rows.clip(0, 679), cols.clip(0, 1023)]
    assert (
        inside.sum()
        >= 0.9
        * on_unknown[
            np.round(features.xy[:, 1]).astype(int).clip(0, 679),
            np.round(features.xy[:, 0]).astype(int).clip(0, 1023),
        ].sum()
    )
    assert np.intersect1d(found.unmatched, found.hypotheses[0].inlier_indices).size == 0


def test_database_round_trip(database, tmp_path):
    path = tmp_path / "db.npz"
    database.save(path)
    loaded = ObjectDatabase.load(path, feature_type=database.feature_type)
    assert loaded.classes == database.classes == tuple(sorted(CLASSES))
    assert loaded.stats() == database.stats() and database.stats()["views"] == 6
    for a, b in zip(database.views, loaded.views, strict=True):
        assert a.class_name == b.class_name
        for name in ("xy", "size", "angle", "response", "descriptors"):
            np.testing.assert_array_equal(getattr(a.features, name), getattr(b.features, name))
        np.testing.assert_array_equal(a.offsets, b.offsets)
        np.testing.assert_array_equal(a.outline, b.outline)


def test_a_corrupt_or_mismatched_database_file_gives_a_clear_error(tmp_path):
    database = ObjectDatabase.build(_views()[:2], "orb")
    good = tmp_path / "db.npz"
    database.save(good)
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"this is not a zip file at all")
    with pytest.raises(DatabaseFileError, match="damaged"):
        ObjectDatabase.load(garbage)
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    with pytest.raises(DatabaseFileError, match="damaged"):
        ObjectDatabase.load(truncated)
    with pytest.raises(DatabaseFileError, match="holds 'orb'"):
        ObjectDatabase.load(good, feature_type="sift")
    with pytest.raises(DatabaseFileError, match="does not exist"):
        ObjectDatabase.load(tmp_path / "missing.npz")
    other = tmp_path / "other.npz"
    np.savez(other, x=np.zeros(3))
    with pytest.raises(DatabaseFileError, match="lacks"):
        ObjectDatabase.load(other)
    with np.load(good) as data:
        arrays = dict(data)
    np.savez(tmp_path / "old.npz", **{**arrays, "version": np.int64(0)})
    with pytest.raises(DatabaseFileError, match="version 0"):
        ObjectDatabase.load(tmp_path / "old.npz")
    np.savez(tmp_path / "cut.npz", **{**arrays, "xy": arrays["xy"][:-1]})
    with pytest.raises(DatabaseFileError, match="inconsistent"):
        ObjectDatabase.load(tmp_path / "cut.npz")


def test_bad_views_and_settings_get_clear_errors():
    with pytest.raises(ActiveVisionError, match="valid: sift"):
        ObjectDatabase.build(_views(), "surf")
    blank = np.full((100, 100), 128, np.uint8)
    with pytest.raises(ActiveVisionError, match="texture-less"):
        ObjectDatabase.build([ObjectView(blank, np.ones_like(blank), "plain")], "sift")
    with pytest.raises(ActiveVisionError, match="mask is empty"):
        ObjectDatabase.build([ObjectView(blank, np.zeros_like(blank), "plain")], "sift")
    with pytest.raises(ActiveVisionError, match="mask shape"):
        ObjectDatabase.build([ObjectView(blank, np.ones((5, 5)), "plain")], "sift")
    with pytest.raises(ActiveVisionError, match="min_inliers"):
        RecognitionConfig(min_inliers=3)
    database = ObjectDatabase.build(_views()[:2], "orb")
    with pytest.raises(ActiveVisionError, match="database's feature type"):
        recognise(detect(textured_patch(1), "sift"), database)


def _summary(found):
    return [
        (h.class_name, h.centre.round(6).tolist(), h.inliers, h.view, h.inlier_indices.tolist())
        for h in found.hypotheses
    ] + [found.unmatched.tolist()]


def _two_tea_scene():
    patch = textured_patch(CLASSES["tea"])
    scene, _ = paste(background(5), patch, (300, 340), 10.0, 1.0)
    scene, _ = paste(scene, patch, (505, 345), -5.0, 1.0)
    return paste(scene, textured_patch(CLASSES["cereal"]), (800, 250), 30.0, 0.9)[0]


_CHILD = """
import json, sys
sys.path.insert(0, {tests!r})
from test_recognition import _summary, _two_tea_scene, _views
from ipbench.perception.features2d import detect
from ipbench.perception.object_database import ObjectDatabase
from ipbench.perception.recognition import recognise
db = ObjectDatabase.build(_views(), "sift")
print(json.dumps(_summary(recognise(detect(_two_tea_scene(), "sift"), db))))
"""


def test_recognition_is_the_same_in_another_process():
    import json
    import subprocess
    import sys
    from pathlib import Path

    database = ObjectDatabase.build(_views(), "sift")
    here = json.loads(json.dumps(_summary(recognise(detect(_two_tea_scene(), "sift"), database))))
    code = _CHILD.format(tests=str(Path(__file__).parent))
    child = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert json.loads(child.stdout) == here
    assert sorted(h[0] for h in here[:-1]) == ["cereal", "tea", "tea"]


def test_incremental_hough_clustering_equals_recounting_every_round(database):
    """_cluster keeps the live votes per bin up to date; a plain recount each round (the
    definition) must pick the same clusters in the same order."""
    from ipbench.perception import recognition as r

    config = RecognitionConfig()
    scene = detect(_two_tea_scene(), database.feature_type)
    picked_fast, picked_plain = [], []
    verify = r._verify

    def spy(scene_, database_, votes_, members, config_):
        picked_fast.append(members.tolist())
        return verify(scene_, database_, votes_, members, config_)

    for name in database.classes:
        views = [i for i, v in enumerate(database.views) if v.class_name == name]
        size = 2.0 * max(database.views[i].radius for i in views)
        matches = match_many(scene, [database.views[i].features for i in views])
        votes = r._votes(scene, database, views, matches, config)
        r._verify = spy
        try:
            fast = r._cluster(scene, database, votes, size, config)
        finally:
            r._verify = verify
        plain = []
        if len(votes.scene) >= config.min_inliers:
            bin_of, by_bin, start = r._hough_bins(votes, size, config)
            owner = np.arange(len(bin_of)) % len(votes.scene)
            # the bin order lists each bin's entries between its bounds, bins numbered densely
            assert np.array_equal(np.sort(by_bin), np.arange(len(bin_of)))
            assert np.array_equal(
                bin_of[by_bin], np.repeat(np.arange(len(start) - 1), np.diff(start))
            )
            alive = np.ones(len(votes.scene), bool)
            while alive.sum() >= config.min_inliers:
                live = alive[owner]
                counts = np.bincount(bin_of[live], minlength=int(bin_of.max()) + 1)
                best = int(np.argmax(counts))
                if counts[best] < config.min_inliers:
                    break
                members = np.unique(owner[live & (bin_of == best)])
                picked_plain.append(members.tolist())
                alive[members] = False
                h = verify(scene, database, votes, members, config)
                if h is not None:
                    plain.append(h)
                    alive &= ~np.isin(votes.scene, h.inlier_indices)
        assert [(h.view, h.inlier_indices.tolist()) for h in fast] == [
            (h.view, h.inlier_indices.tolist()) for h in plain
        ]
    assert picked_fast == picked_plain and len(picked_fast) >= 3
