"""The lab room and its posters (``ipbench.assets.room``) against their published numbers."""

import math

import mujoco
import numpy as np
import pytest

from ipbench.assets.room import (
    CEILING_HEIGHT,
    POSTER_CENTRE_HEIGHT,
    POSTER_SIZES,
    ROOM_HALF,
    WALLS,
    Poster,
    RoomError,
    add_room,
    layout_posters,
    poster_image,
)
from ipbench.envs.exploration_scene import LEVELS, build_model, sample_scene


def test_the_room_and_poster_numbers_are_the_sources():
    # room_ug.urdf.xacro: walls at x_base +-2.95, y_base +-2.3, ceiling 3.0; world = r750 frame
    assert ROOM_HALF == (2.3, 2.95) and CEILING_HEIGHT == 3.0
    # ISO 216: A1 = 594 x 841 mm, A2 = 420 x 594 mm; each half the area of the one before
    assert POSTER_SIZES == {"A1": (0.594, 0.841), "A2": (0.420, 0.594)}
    a1, a2 = (w * h for w, h in POSTER_SIZES.values())
    assert a1 == pytest.approx(0.5, rel=0.002) and a2 == pytest.approx(a1 / 2, rel=0.002)
    assert POSTER_CENTRE_HEIGHT == pytest.approx(57 * 0.0254, abs=0.005)  # 57 in on centre


def _inner_faces(model: mujoco.MjModel) -> dict[str, float]:
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    out = {}
    for name in ("front", "back", "left", "right", "ceiling"):
        g = model.geom(f"room_{name}")
        pos, half = data.geom(f"room_{name}").xpos, g.size
        out[name] = {
            "front": pos[0] - half[0],
            "back": pos[0] + half[0],
            "left": pos[1] - half[1],
            "right": pos[1] + half[1],
            "ceiling": pos[2] - half[2],
        }[name]
        assert g.contype == 0 and g.conaffinity == 0  # visual only
    return out


def test_walls_stand_where_the_description_puts_them():
    spec = mujoco.MjSpec()
    add_room(spec)
    faces = _inner_faces(spec.compile())
    assert faces == pytest.approx(
        {"front": 2.3, "back": -2.3, "left": 2.95, "right": -2.95, "ceiling": 3.0}, abs=1e-9
    )


@pytest.mark.parametrize("level", list(LEVELS))
def test_scene_posters_hang_on_the_walls_without_overlap_facing_the_room(level):
    for seed in range(5):
        scene = sample_scene(level, seed)
        assert len(scene.posters) == LEVELS[level].n_posters
        model = build_model(scene)
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
        for k, p in enumerate(scene.posters):
            assert p.wall in WALLS
            w, h = POSTER_SIZES[p.size]
            g = model.geom(f"room_poster_{k:02d}_visual")
            mesh = model.mesh(g.dataid[0])
            start, n = int(mesh.vertadr[0]), int(mesh.vertnum[0])
            local = model.mesh_vert[start : start + n]
            world = data.geom_xpos[g.id] + local @ data.geom_xmat[g.id].reshape(3, 3).T
            lo, hi = world.min(0), world.max(0)
            assert hi[2] - lo[2] == pytest.approx(h, abs=1e-6)
            assert 0.5 * (lo[2] + hi[2]) == pytest.approx(POSTER_CENTRE_HEIGHT, abs=1e-6)
            axis, inward = {"front": (1, -1), "left": (0, -1), "right": (0, 1)}[p.wall]
            across = 1 - axis  # the coordinate normal to the wall
            wall = ROOM_HALF[across] * -inward
            assert np.all(np.abs(world[:, across] - wall) < 0.01)  # on its wall
            assert hi[axis] - lo[axis] == pytest.approx(w, abs=1e-6)
            assert -ROOM_HALF[axis] < lo[axis] and hi[axis] < ROOM_HALF[axis]
            # the first face's normal points into the room: it is seen from inside
            face = model.mesh_face[int(mesh.faceadr[0])]
            a, b, c = world[face]
            normal = np.cross(b - a, c - a)
            assert normal[across] * inward > 0
        for i, p in enumerate(scene.posters):
            for q in scene.posters[i + 1 :]:
                if p.wall == q.wall:
                    gap = abs(p.along - q.along) - 0.5 * (
                        POSTER_SIZES[p.size][0] + POSTER_SIZES[q.size][0]
                    )
                    assert gap >= 0.1 - 1e-9


def test_posters_leave_the_objects_of_a_seed_where_they_were():
    a = sample_scene("complex", 3)
    assert a.objects == sample_scene("complex", 3).objects
    assert a.posters == sample_scene("complex", 3).posters
    assert a.posters != sample_scene("complex", 4).posters


def test_poster_prints_are_deterministic_textured_and_distinct():
    a, b = poster_image(1), poster_image(2)
    assert a.shape == (362, 256, 3) and a.dtype == np.uint8
    assert np.array_equal(a, poster_image(1)) and not np.array_equal(a, b)
    assert math.isclose(a.shape[0] / a.shape[1], math.sqrt(2), rel_tol=0.01)
    assert a.std() > 20  # printed, not blank


def test_bad_posters_get_clear_errors():
    with pytest.raises(RoomError, match="valid: front, left, right"):
        add_room(mujoco.MjSpec(), (Poster("floor", 0.0, "A1", 0),))
    with pytest.raises(RoomError, match="valid"):
        add_room(mujoco.MjSpec(), (Poster("front", 0.0, "A0", 0),))
    with pytest.raises(RoomError, match="use fewer"):
        layout_posters(np.random.default_rng(0), 40)
