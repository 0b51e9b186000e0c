"""No seed fails to lay out, and the seeds the scene procedure places keep their recorded layouts.

Layout only: no world is built, nothing rendered or stepped (but one ``reset``). Episode seeds
become layout seeds as ``SortingEnv.reset`` draws them (:func:`layout_seed`).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
from gymnasium.utils import seeding

import ipbench.envs.layout as layout_module
from ipbench.assets.objects import CATEGORIES
from ipbench.envs.layout import (
    LayoutError,
    _footprint,
    _overlaps,
    _pick,
    _pick_v1,
    _place_in_rows,
    sample_layout,
)
from ipbench.envs.sorting import workcell_places
from ipbench.envs.sorting_scenes import SCENES, STANDARD_SCENES, SceneConfig

DATA = Path(__file__).parent / "data" / "layout_digests.json"
PLACES = workcell_places()
AREA = PLACES.spawn_area
CHUNK = 500
"""Seeds per test case (so that ``pytest -n`` spreads a long range over its workers)."""
SEED_RANGES: dict[tuple[str, str], int] = {
    ("v1", "uncluttered"): 3000,
    ("v1", "cluttered"): 3000,
    ("v2", "uncluttered"): 1000,
    ("v2", "cluttered"): 100,
}
"""Episode seeds 0 .. N-1 tested per (catalogue, scene). The released ids' catalogue (v1):
0-2999 (about 3 and 14 ms a seed; cluttered 138 is the one seed the scene procedure cannot
place). v2 on fewer seeds, to keep the file near a minute: its cluttered pile costs about 45 ms
a seed, because a v2 pile often does not fit and about 10 of a seed's 11 placement attempts
fail, each after 300 tries of its last object; those draws fix the recorded layouts, so they
stay. Episode seeds 0-2999 of both v2 scenes lay out without the fallback (a scan of about 3
minutes, not run here)."""


def layout_seed(episode_seed: int) -> int:
    """The layout seed ``SortingEnv.reset(seed=episode_seed)`` passes to ``sample_layout``."""
    rng, _ = seeding.np_random(episode_seed)
    return int(rng.integers(2**31 - 1))


def _layout(scene, episode_seed: int, catalog: str = "v1"):
    return sample_layout(
        scene,
        layout_seed(episode_seed),
        AREA.center,
        AREA.half,
        PLACES.table_height,
        catalog=catalog,
    )


def digest(layout) -> str:
    """Hash of what and where every object is (values rounded to 1e-9 m or rad, so that last-bit
    differences of maths libraries do not count)."""
    rows = [
        [
            o.object_id,
            o.instance.name,
            o.resting.name,
            [round(float(v), 9) for v in (*o.position, o.yaw, *o.quat)],
        ]
        for o in layout.objects
    ]
    return hashlib.sha256(json.dumps(rows).encode()).hexdigest()[:16]


def assert_valid(layout, scene: SceneConfig) -> None:
    """The scene's composition, ids 0 .. n-1, every footprint inside the spawn area and none
    closer than the scene's gap to another, every object on the table."""
    counts = [sum(o.instance.category == c for o in layout.objects) for c in CATEGORIES]
    assert tuple(counts) == scene.counts
    assert [o.object_id for o in layout.objects] == list(range(scene.n_objects))
    half = AREA.half[:2] * np.asarray(scene.area_fraction)
    rects = []
    for obj in layout.objects:
        offset, (hx, hy) = _footprint(obj.instance, obj.resting)
        c, s = np.cos(obj.yaw), np.sin(obj.yaw)
        mid = np.array(obj.position[:2]) + [
            c * offset[0] - s * offset[1],
            s * offset[0] + c * offset[1],
        ]
        extent = np.array([abs(c) * hx + abs(s) * hy, abs(s) * hx + abs(c) * hy])
        assert np.all(np.abs(mid - AREA.center[:2]) <= half - extent + 1e-9)
        rect = (mid[0], mid[1], hx, hy, obj.yaw)
        assert not _overlaps(rect, np.array(rects).reshape(-1, 5), scene.gap - 1e-6)
        rects.append(rect)
        assert obj.position[2] == pytest.approx(PLACES.table_height + obj.resting.height)


@pytest.mark.parametrize(
    ("catalog", "scene", "start"),
    [(c, s, a) for (c, s), n in SEED_RANGES.items() for a in range(0, n, CHUNK)],
)
def test_every_seed_lays_out(catalog, scene, start):
    stop = min(start + CHUNK, SEED_RANGES[catalog, scene])
    for seed in range(start, stop):
        try:
            layout = _layout(scene, seed, catalog)
        except LayoutError as err:
            pytest.fail(f"{catalog} {scene} episode seed {seed}: {err}")
        assert len(layout.objects) == SCENES[scene].n_objects


@pytest.mark.parametrize(
    "key", ["v1/uncluttered", "v1/cluttered", "v2/uncluttered", "v2/cluttered"]
)
def test_layouts_of_seeds_that_always_laid_out_are_unchanged(key):
    """Episode seeds 0-20, recorded before the fallback and the faster placement."""
    catalog, scene = key.split("/")
    expected = json.loads(DATA.read_text())["layouts"][key]
    assert [digest(_layout(scene, s, catalog)) for s in range(len(expected))] == expected


def test_the_seed_the_procedure_cannot_place_gets_a_frozen_fallback_layout():
    """Cluttered episode seed 138 fails the scene procedure's 50 attempts; it gets further
    attempts from a stream of its own, and its layout is frozen like any other's."""
    scene = SCENES["cluttered"]
    a, b = _layout("cluttered", 138), _layout("cluttered", 138)
    assert a == b
    assert_valid(a, scene)
    assert sum(o.resting.name == "side" for o in a.objects) == 2  # a pile like any other
    assert digest(a) == json.loads(DATA.read_text())["fallback"]["v1/cluttered/138"]


@pytest.mark.parametrize("catalog", ["v1", "v2"])
@pytest.mark.parametrize("scene", sorted(STANDARD_SCENES))  # (a pile lays out without rows)
def test_rows_fit_every_draw_of_the_standard_scenes(scene, catalog):
    """The last resort stands each object in its category's slot, so whether the rows fit
    depends on the scene's counts and the catalogue only: fitting here, they fit every seed."""
    config = SCENES[scene]
    rng = np.random.default_rng(0)
    picks = _pick_v1(config, rng) if catalog == "v1" else _pick(config, rng, catalog)
    placed = _place_in_rows(config, picks, rng, AREA.center, AREA.half, PLACES.table_height)
    assert placed is not None
    assert_valid(layout_module.Layout(scene, 0, placed), config)
    assert all(o.resting.name == "upright" for o in placed)


def test_a_seed_no_attempt_places_gets_rows(monkeypatch):
    calls = []

    def never(*args):
        calls.append(args[2])  # the stream each attempt draws from
        return None

    monkeypatch.setattr(layout_module, "_place", never)
    a, b = _layout("cluttered", 5), _layout("cluttered", 5)
    assert a == b
    assert_valid(a, SCENES["cluttered"])
    # the scene's own 50 attempts, then the fallback's from another stream
    assert len(calls) == 2 * (50 + layout_module._FALLBACK_ATTEMPTS)
    assert calls[0] is calls[49] and calls[50] is not calls[0]


def test_a_scene_that_cannot_fit_says_what_to_change():
    tiny = SceneConfig("tiny", (5, 1, 0, 4, 0), area_fraction=(0.2, 0.2))
    with pytest.raises(LayoutError, match="objects of scene 'tiny'.*enlarge area_fraction"):
        sample_layout(tiny, 0, AREA.center, AREA.half, PLACES.table_height)


def test_reset_with_a_seed_the_procedure_cannot_place():
    """``reset(seed=138)`` of the cluttered scene (released ids), which only the fallback lays
    out, does not raise and lays out what :func:`layout_seed` says."""
    import gymnasium as gym

    import ipbench.envs  # noqa: F401  (registers the environments)

    env = gym.make("ipbench/Sorting-v1", scene="cluttered")
    try:
        env.reset(seed=138)
        assert env.unwrapped.world.layout.seed == layout_seed(138)
        assert env.unwrapped.world.layout == _layout("cluttered", 138)
    finally:
        env.close()
