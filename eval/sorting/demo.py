"""The demo episode: scripted sorting with ground-truth labels, written to ``results/``.

``ipbench demo``: one episode per standard scene with
:class:`~ipbench.policies.scripted.GroundTruthSorter`, an MP4 of each from the overview camera
and a ``demo_summary.json``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import gymnasium as gym
from tqdm import tqdm

import ipbench.envs  # noqa: F401  (registers the environments)
from ipbench.eval.video import VideoRecorder
from ipbench.policies.scripted import GroundTruthSorter

__all__ = ["run_demo"]


def run_demo(
    out: Path,
    scenes=("uncluttered", "cluttered"),
    seed: int = 0,
    video: bool = True,
    max_steps: int | None = None,
) -> dict:
    """Run one scripted episode per scene; returns the summary written to ``out``.

    ``max_steps`` shortens the episodes (the environment's step limit; for quick checks).
    """
    out.mkdir(parents=True, exist_ok=True)
    summary = {}
    for scene in scenes:
        env = gym.make(
            "ipbench/Sorting-v1", scene=scene, render_mode="rgb_array", max_steps=max_steps
        )
        recorder = VideoRecorder(env, fps=20) if video else None
        policy = GroundTruthSorter()
        t0 = time.perf_counter()
        obs, info = env.reset(seed=seed)
        total, steps, failures = 0.0, 0, []
        bar = tqdm(total=len(info["objects"]), desc=f"demo {scene}", unit="object")
        terminated = truncated = False
        while not (terminated or truncated):
            obs, reward, terminated, truncated, info = env.step(policy.act(obs, info))
            total += reward
            steps += 1
            failures += [s for s in info["skills"] if not s["success"]]
            bar.n = sum(o["status"].startswith("in_bin:") for o in info["objects"].values())
            bar.refresh()
        bar.close()
        objects = info["objects"].values()
        correct = sum(o["status"] == f"in_bin:{o['category']}" for o in objects)
        summary[scene] = {
            "seed": seed,
            "objects": len(info["objects"]),
            "correct": correct,
            "accuracy": correct / len(info["objects"]),
            "steps": steps,
            "return": round(total, 3),
            "failed_skills": failures,
            "sim_time_s": round(info["sim_time"], 2),
            "wall_time_s": round(time.perf_counter() - t0, 2),
        }
        if recorder is not None:
            summary[scene]["video"] = str(recorder.save(out / f"demo_{scene}.mp4"))
        env.close()
    (out / "demo_summary.json").write_text(json.dumps(summary, indent=2))
    return summary
