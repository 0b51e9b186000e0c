"""The speed benchmark's measurement of manipulation physics (figures live in ``ipbench bench``,
never in timed tests: here only that it measures what it says)."""

from __future__ import annotations

import mujoco

from ipbench.eval import bench


def test_manipulation_rate_times_raw_steps_from_a_held_pick(monkeypatch):
    calls = []
    raw = mujoco.mj_step

    def counting(model, data, *args):
        calls.append(bool(model.opt.enableflags & int(mujoco.mjtEnableBit.mjENBL_SLEEP)))
        raw(model, data, *args)

    rate = bench.manipulation_step_rate("ipbench/Sorting-v2", seeds=(0,), steps=30, repeats=2)
    assert rate > 0  # the scripted pick reached the pads-on-object state
    monkeypatch.setattr(bench.mujoco, "mj_step", counting)
    assert bench._pick_contact_rate("ipbench/Sorting-v2", 0, 30, 2, 50) > 0
    # the timed loops are 2 x 30 raw steps of the v2 model (sleeping on), after the pick's
    assert len(calls) >= 60 and all(calls[-60:])
