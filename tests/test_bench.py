"""The speed benchmark's measurement of manipulation physics (figures live in ``ipbench bench``,
never in timed tests: here only that it measures what it says)."""

from __future__ import annotations

import mujoco

from ipbench.eval.bench import sim as bench


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


def test_bench_eval_reports_rates_and_where_the_two_worker_speedup_goes(monkeypatch, tmp_path):
    import itertools

    from ipbench.eval.bench import episodes as bench_eval

    clock = itertools.count()
    monkeypatch.setattr(bench_eval.time, "perf_counter", lambda: 60.0 * next(clock) / 2)

    def executor(config):
        # each run takes 0.5 wall minutes on the fake clock; an episode "takes" 10 s alone
        # and 12 s beside another one
        per_episode = 10.0 if config.workers == 1 else 12.0
        return lambda tasks, models, cfg: iter([{"wall_time_s": per_episode}] * len(tasks))

    monkeypatch.setattr(bench_eval, "_executor", executor)
    monkeypatch.setattr(bench_eval, "prepare_models", lambda cache, config: (None, {}))
    figures = bench_eval.bench_eval(tmp_path, ("random",), episodes=3)
    assert figures["random_w1_episodes_per_min"] == figures["episodes_per_min_2"] == 6.0
    assert figures["slowdown_2_workers"] == 1.2
    assert figures["busy_2_workers"] == round(3 * 12.0 / (2 * 30.0), 3)
    assert figures["speedup_2_workers"] == 1.0
    versions = {"episode_s_v1", "episode_s_v2", "episode_s_v3"}
    assert versions | {"episode_speedup_v2", "episode_speedup_v3"} <= set(figures)


def test_bench_eval_times_the_benchmarks_id():
    """The rates are of the id `make eval` runs, with the models of its own views."""
    from ipbench.envs import LATEST
    from ipbench.eval.bench.episodes import check_bench_eval

    assert check_bench_eval(("random",), 2).perception.dataset.env_id == LATEST
