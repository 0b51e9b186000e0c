"""The perception models a run needs, rendered and trained in one pool of workers.

From an empty cache a sorting run renders the training views (each known instance alone on
the table, and in hand) and trains a table-top and an in-hand model. One after the other,
one core idles while a model trains (one thread: minutes for the table-top GP). Here they
share one pool (:func:`ipbench.eval.workers.run_tasks` with dependencies): every isolated
part first, then the table-top models start training as soon as the last isolated part is
saved while the other workers go on rendering the in-hand parts, and the in-hand models train
when those are saved. The views and the models are those the stages would have produced one
after the other (the same files, the same bytes): each training task runs
:func:`ipbench.eval.perception.evaluate.trained_models`, which reads the saved parts. Tasks that
only
read the table-top models (the sorting run's validation episodes, ``then``) come last in
priority, so a worker runs them while the in-hand models train instead of idling.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from tqdm import tqdm

from ipbench.assets.objects import CATEGORIES
from ipbench.eval.capture.dataset import missing_parts, render_part, save_part
from ipbench.eval.perception.evaluate import (
    CONDITIONS,
    PerceptionEvalConfig,
    model_key,
    model_path,
    trained_models,
)
from ipbench.eval.schedule import pool_worker
from ipbench.eval.workers import run_tasks

__all__ = ["prepare_perception"]


def _render(kind, inst, config) -> tuple:
    return "part", render_part(kind, inst, config)


def _train(cache: Path, config: PerceptionEvalConfig, classifiers, condition: str) -> tuple:
    trained_models(cache, config, CATEGORIES, classifiers, condition, workers=1, progress=False)
    return "model", None


def _then(fn, *args) -> tuple:
    return "then", fn(*args)


def _call(fn, *args):
    return fn(*args)


def prepare_perception(
    cache: Path,
    config: PerceptionEvalConfig,
    wanted: Sequence[tuple[str, tuple[str, ...]]],
    workers: int,
    progress: bool = False,
    then: Sequence[tuple] = (),
) -> list:
    """Render the missing training parts and train the missing models of ``wanted``
    (``(condition, classifiers)`` pairs, conditions of
    :data:`~ipbench.eval.perception.evaluate.CONDITIONS`) into ``cache``, in ``workers`` processes
    (see the module docstring). Models already cached are not touched; a corrupt one is
    retrained later by :func:`~ipbench.eval.perception.evaluate.trained_models`, which loads them.

    ``then``: tasks ``(fn, *args)`` that read the table-top models (e.g. the validation
    episodes that choose a threshold), run in the same pool once those are saved, after
    everything else in priority: a worker runs them while the in-hand models train instead
    of idling. Returns their results, in the order of ``then``."""
    cache = Path(cache)
    cache.mkdir(parents=True, exist_ok=True)
    unknown = [c for c, _ in wanted if c not in CONDITIONS]
    if unknown:
        raise ValueError(f"unknown conditions {unknown}; valid: {', '.join(CONDITIONS)}")
    trainings = [
        (condition, missing)
        for condition, classifiers in wanted
        if (
            missing := tuple(
                c
                for c in classifiers
                if not model_path(cache, model_key(config, CATEGORIES, c, condition)).exists()
            )
        )
    ]
    if not trainings and not then:
        return []
    dataset = config.dataset
    read = {CONDITIONS["scene"]} | {CONDITIONS[c] for c, _ in trainings}
    parts = (
        [p for p in missing_parts(cache, dataset, training_only=True) if p[0] in read]
        if trainings
        else []
    )
    # isolated parts first; each training right after the last part it reads (or first)
    entries: list[tuple[float, tuple]] = [(j, ("part", j)) for j in range(len(parts))]
    for condition, classifiers in trainings:
        reads = {CONDITIONS["scene"], CONDITIONS[condition]}
        deps = [j for j, (kind, _) in enumerate(parts) if kind in reads]
        entries.append((max(deps, default=-1) + 0.5, ("train", condition, classifiers, deps)))
    entries.sort(key=lambda e: e[0])
    index = {e[1][1]: k for k, e in enumerate(entries) if e[1][0] == "part"}
    tasks: list[tuple] = []
    after: list[list[int]] = []
    jobs: list = []  # per task: the (kind, inst) part it renders, or None for a training
    for _, entry in entries:
        if entry[0] == "part":
            kind, inst = parts[entry[1]]
            tasks.append((_render, kind, inst, dataset))
            after.append([])
            jobs.append((kind, inst))
        else:
            _, condition, classifiers, deps = entry
            tasks.append((_train, cache, config, classifiers, condition))
            after.append([index[j] for j in deps])
            jobs.append(None)
    table_top = [k for k, job in enumerate(tasks) if job[0] is _train and job[4] == "scene"]
    first_then = len(tasks)
    for fn, *args in then:
        tasks.append((_then, fn, *args))
        after.append(table_top)
        jobs.append(None)
    desc = (
        "views, models, validation"
        if then and trainings
        else ("views and models" if trainings else "validation episodes")
    )
    bar = tqdm(total=len(tasks), desc=desc, unit="task", disable=not progress)
    results = run_tasks(
        _call,
        tasks,
        workers,
        pool_worker if workers > 1 else None,
        what="preparation task",
        after=after,
    )
    out: list = [None] * len(then)
    for i, (what, value) in results:
        if what == "part":
            kind, inst = jobs[i]
            save_part(cache, dataset, kind, inst, value)
        elif what == "then":
            out[i - first_then] = value
        bar.update()
    bar.close()
    return out
