"""In-hand ablation: where do in-hand views lose their information?

Held up to the wrist camera, out of the clutter and turned, an object should show at least
what a first look on the table shows; yet on ``ipbench/Sorting-v2`` the in-hand model labels
in-hand views of the test instances less often right than the table-top model labels the
table-top views. Each row of :data:`IN_HAND_ROWS` removes one factor of
:data:`~ipbench.eval.capture.hand_factors.IN_HAND_FACTORS` from the in-hand capture (``baseline``:
every factor as captured): the segmentation (``true_mask``), the jaws' points (``no_jaws``),
the sensor (``ideal_depth``) and the scale (``table_distance``). What no row removes is the
physics: the jaws hide part of the object.

Protocol (:data:`IN_HAND_ABLATION_PROTOCOL`): the sensor ablation's light capture
(:data:`~ipbench.eval.perception.evaluate.ABLATION_PROTOCOL`: 3 instances per category and split)
with 3 in-hand views per grasp and 2 grasps per resting pose. Every row's views come from one
pass of grasps and turns (:func:`~ipbench.eval.capture.dataset.render_in_hand_rows`), so the rows
differ in the removed factor alone, view for view; each row's parts are cached as those of
its own :class:`~ipbench.eval.capture.dataset.InHandAblationConfig`.

**The model is retrained per row**: each row's in-hand classifier trains on that row's
in-hand views of the *train* instances and is tested on its views of the *similar* and
*novel* instances, so a row measures the information the factor destroys, not the mismatch
between a model trained with the factor and views without it. The codebook is the same for
every row: fitted on the light protocol's table-top training views, as the in-hand models'
codebook is. Point classifiers (PointNet) are left out: the light protocol is far too small
for them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from ipbench.assets.objects import CATEGORIES
from ipbench.eval.capture.dataset import (
    DatasetConfig,
    InHandAblationConfig,
    load_or_build,
    missing_parts,
    render_in_hand_rows,
    save_part,
)
from ipbench.eval.capture.hand_factors import IN_HAND_FACTORS
from ipbench.eval.perception.evaluate import (
    ABLATION_PROTOCOL,
    POINT_CLASSIFIERS,
    PerceptionEvalConfig,
    _fit,
    _fit_codebook,
    _score,
    encode,
    training_views,
)
from ipbench.eval.perception.view_fusion import split_of_views
from ipbench.eval.schedule import pool_worker
from ipbench.eval.workers import run_tasks
from ipbench.perception.viewset import ViewSet

__all__ = [
    "IN_HAND_ABLATION_PROTOCOL",
    "IN_HAND_ROWS",
    "TEST_SPLITS",
    "ablation_dataset",
    "capture_rows",
    "in_hand_ablation",
]

IN_HAND_ROWS: tuple[str, ...] = ("baseline", *IN_HAND_FACTORS)
"""The rows of the ablation: ``baseline`` (every factor as captured), then each factor of
:data:`~ipbench.eval.capture.hand_factors.IN_HAND_FACTORS` removed."""

IN_HAND_ABLATION_PROTOCOL: dict = {**ABLATION_PROTOCOL, "in_hand_views": 3, "in_hand_placements": 2}
"""The light capture: :data:`~ipbench.eval.perception.evaluate.ABLATION_PROTOCOL`'s instances and
table-top views (they fit the codebook) with 3 in-hand views per grasp (30 deg apart, the
thesis' three) and 2 grasps per resting pose (the object turned 180 deg between them)."""

TEST_SPLITS: tuple[str, ...] = ("similar", "novel")
"""The test splits each row also reports on its own (``{split}_accuracy``, ``{split}_n``)."""


def ablation_dataset(dataset: DatasetConfig, row: str) -> InHandAblationConfig:
    """The capture of ``row`` (one of :data:`IN_HAND_ROWS`) for the env of ``dataset``: the
    light protocol of :data:`IN_HAND_ABLATION_PROTOCOL` with the row's factor removed."""
    if row not in IN_HAND_ROWS:
        raise ValueError(f"unknown in-hand ablation row {row!r}; valid: {', '.join(IN_HAND_ROWS)}")
    fields = {f: getattr(dataset, f) for f in DatasetConfig.__dataclass_fields__}
    fields.update(IN_HAND_ABLATION_PROTOCOL, in_hand_removed=_factor(row))
    return InHandAblationConfig(**fields)


def _factor(row: str) -> str | None:
    return None if row == "baseline" else row


def capture_rows(
    cache: Path, dataset: DatasetConfig, workers: int = 2, progress: bool = True
) -> dict[str, ViewSet]:
    """Every row's in-hand views (known and test instances) of the light protocol, cached:
    an instance any row lacks is captured for every row in one pass (``workers`` processes)."""
    configs = {row: ablation_dataset(dataset, row) for row in IN_HAND_ROWS}
    base = configs["baseline"]
    todo: dict[str, object] = {}
    for config in configs.values():
        for kind, inst in missing_parts(cache, config, training_only=False):
            if kind == "in_hand":
                todo.setdefault(inst.name, inst)
    factors = tuple(_factor(row) for row in IN_HAND_ROWS)
    jobs = [(inst, base, factors) for inst in todo.values()]
    if progress and jobs:
        print(f"in-hand ablation: capturing {len(jobs)} instances for {len(factors)} rows")
    for k, by_factor in run_tasks(
        render_in_hand_rows,
        jobs,
        workers,
        pool_worker if workers > 1 else None,
        what="in-hand ablation part",
    ):
        inst = jobs[k][0]
        for row, config in configs.items():
            save_part(cache, config, "in_hand", inst, by_factor[_factor(row)])
    return {
        row: load_or_build(cache, config, progress=False, workers=workers, kinds=("in_hand",))
        for row, config in configs.items()
    }


def in_hand_ablation(
    cache: Path, config: PerceptionEvalConfig, workers: int = 2, progress: bool = True
) -> dict:
    """5-class accuracy of the in-hand model with each in-hand factor removed in turn (see
    the module docstring): ``{row: {classifier: {"n", "accuracy", "log_loss", "ece",
    "train_n", "similar_accuracy", "similar_n", "novel_accuracy", "novel_n"}}}`` for each row
    of :data:`IN_HAND_ROWS` and each FPFH classifier of ``config.classifiers``."""
    with threadpool_limits(1):
        return _in_hand_ablation(cache, config, workers, progress)


def _in_hand_ablation(cache: Path, config: PerceptionEvalConfig, workers, progress) -> dict:
    dataset = config.dataset
    rows = capture_rows(cache, dataset, workers, progress)
    isolated = load_or_build(
        cache,
        ablation_dataset(dataset, "baseline"),
        progress=progress,
        workers=workers,
        training_only=True,
        kinds=("isolated",),
    )
    codebook = _fit_codebook(training_views(isolated, "scene"), config)
    index = {i: i for i in range(len(CATEGORIES))}
    names = [n for n in config.classifiers if n not in POINT_CLASSIFIERS]
    out: dict = {}
    for row, views in rows.items():
        train = training_views(views, "in_hand")
        split = split_of_views(views, dataset.catalog)
        test = views.subset(np.isin(split, TEST_SPLITS))
        test_split_of = split[np.isin(split, TEST_SPLITS)]
        x_train, x_test = encode(train, codebook), encode(test, codebook)
        fitted: dict = {}
        out[row] = {}
        for name in names:
            clf, _ = _fit(name, x_train, train, index, config, fitted)
            scores, probs, labels = _score(clf, test, x_test, index)
            entry = {k: scores[k] for k in ("n", "accuracy", "log_loss", "ece") if k in scores}
            entry["train_n"] = len(train)
            for part in TEST_SPLITS:
                sel = test_split_of == part
                entry[f"{part}_n"] = int(sel.sum())
                if sel.any():
                    right = probs[sel].argmax(axis=1) == labels[sel]
                    entry[f"{part}_accuracy"] = float(right.mean())
            out[row][name] = entry
    return out
