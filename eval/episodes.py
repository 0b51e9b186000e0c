"""The episode machinery every task family shares: output folder, episode log, executors.

An evaluation (``ipbench eval sorting``, ``ipbench eval exploration``, ...) runs tasks as
episodes, each a pure function of its task and of a context (models, configuration) that is
the same for all of them, and appends each record to ``episodes.jsonl`` as soon as it
finishes, so an interrupted run resumes where it stopped:

- :func:`check_out`: the output folder is writable and holds no episodes of another
  configuration (``run.json``'s fingerprint);
- :class:`EpisodeLog`: the append-only JSON-lines log (a record cut short by a kill is
  dropped and run again; every record is flushed and synced; the finished log is sorted by
  the task key, so it does not depend on the order workers finish in);
- :func:`run_episodes`: the executors, serially here, in local worker processes
  (:func:`ipbench.eval.workers.run_tasks`: longest first, crash-tolerant) or as Ray tasks.

A family supplies its episode function (module level, so it pickles), its task type, the key
of a record and the expected cost of a task (:mod:`ipbench.eval.schedule`).
"""

from __future__ import annotations

import json
import os
import warnings
from collections.abc import Callable, Hashable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

from ipbench.eval.files import ensure_writable
from ipbench.eval.schedule import longest_first, pool_worker, single_thread_worker
from ipbench.eval.workers import run_tasks

__all__ = [
    "BACKENDS",
    "EpisodeLog",
    "check_out",
    "load_episodes",
    "open_run",
    "record_episodes",
    "run_episodes",
    "run_grid",
]

BACKENDS: tuple[str, ...] = ("process", "ray")
"""Where episodes run when ``workers > 1``: local worker processes, or Ray tasks."""

Episode = Callable[..., dict]
"""``episode(task, *context) -> record`` (a JSON-serialisable dict)."""


def check_out(out: Path, fingerprint: str, error: type[Exception] = ValueError) -> None:
    """Check that ``out`` can be written and holds no episodes of another configuration.

    Raises ``error`` saying what to do (another ``--out``, or which log to delete)."""
    try:
        ensure_writable(out)
    except OSError as err:
        raise error(
            f"cannot write to the output folder {out} ({err.strerror}); pass a writable --out"
        ) from err
    run = out / "run.json"
    if run.exists():
        try:
            previous = json.loads(run.read_text()).get("fingerprint")
        except (ValueError, AttributeError):
            previous = None
        if previous != fingerprint and (out / "episodes.jsonl").exists():
            raise error(
                f"{out} holds episodes of another configuration (fingerprint {previous}, this "
                f"run {fingerprint}); pass another --out, or delete {out / 'episodes.jsonl'}"
            )


def load_episodes(path: Path) -> list[dict]:
    """Episode records of a JSONL file (one JSON object per line, blank lines ignored).

    A last line that does not parse is taken for a record cut short by an interrupted
    writer: it is skipped with a warning.

    Raises
    ------
    ValueError
        On a line before the last that is not a JSON object, naming the file and line.
    """
    path = Path(path)
    numbered = [
        (i, line) for i, line in enumerate(path.read_text("utf-8").splitlines(), 1) if line.strip()
    ]
    records = []
    for k, (lineno, line) in enumerate(numbered):
        try:
            record = json.loads(line)
        except json.JSONDecodeError as err:
            if k == len(numbered) - 1:
                warnings.warn(
                    f"{path}:{lineno}: skipping a truncated last line (interrupted writer?): "
                    f"{err.msg}",
                    stacklevel=2,
                )
                break
            raise ValueError(f"{path}:{lineno}: not valid JSON ({err.msg})") from err
        if not isinstance(record, dict):
            raise ValueError(
                f"{path}:{lineno}: expected a JSON object, got {type(record).__name__}"
            )
        records.append(record)
    return records


class EpisodeLog:
    """``episodes.jsonl``: one JSON record a line, appended as episodes finish.

    ``key(record)`` identifies the task a record belongs to (e.g. scene, policy, seed)."""

    def __init__(self, path: Path, key: Callable[[dict], Hashable]) -> None:
        self.path = Path(path)
        self.key = key

    def records(self) -> list[dict]:
        """Every record in the log (none if there is no log yet)."""
        return load_episodes(self.path) if self.path.exists() else []

    def done(self) -> set:
        """Keys of the finished episodes, after cutting a record left half-written by an
        interrupted run (that episode runs again)."""
        self._drop_partial_line()
        return {self.key(r) for r in self.records()}

    def append(self, records: Iterable[dict], each: Callable[[dict], None] | None = None) -> None:
        """Append ``records`` one by one, each flushed and synced to disk before the next;
        ``each(record)`` is called after each is written (e.g. a progress bar)."""
        with self.path.open("a") as f:
            for record in records:
                f.write(json.dumps(record) + "\n")
                f.flush()
                os.fsync(f.fileno())
                if each is not None:
                    each(record)

    def sort(self) -> None:
        """Rewrite the log in key order, atomically: workers finish in any order, the log of a
        finished run does not depend on it."""
        if not self.path.exists():
            return
        records = self.records()
        records.sort(key=self.key)
        tmp = self.path.with_suffix(".jsonl.tmp")
        tmp.write_text("".join(json.dumps(e) + "\n" for e in records))
        os.replace(tmp, self.path)

    def _drop_partial_line(self) -> None:
        if not self.path.exists():
            return
        data = self.path.read_bytes()
        if data and not data.endswith(b"\n"):
            cut = data.rfind(b"\n") + 1
            print(
                f"ipbench: {self.path}: dropping an unfinished last record (it will be run again)"
            )
            with self.path.open("r+b") as f:
                f.truncate(cut)


def open_run(
    out: Path,
    fingerprint: str,
    info: dict,
    key: Callable[[dict], Hashable],
    error: type[Exception] = ValueError,
) -> EpisodeLog:
    """Check ``out`` (:func:`check_out`), write ``run.json`` (the fingerprint and ``info``) and
    return the run's episode log."""
    check_out(out, fingerprint, error)
    run = {"fingerprint": fingerprint, **info}
    (out / "run.json").write_text(json.dumps(run, indent=2, default=str))
    return EpisodeLog(out / "episodes.jsonl", key)


def record_episodes(
    log: EpisodeLog,
    records: Iterable[dict],
    total: int,
    done: int,
    describe: Callable[[dict], str],
    progress: bool = True,
) -> None:
    """Append ``records`` (``total`` of them; ``done`` were finished before) to ``log`` under a
    progress bar whose postfix is ``describe(record)``, then sort the log."""
    from tqdm import tqdm

    if done:
        print(f"ipbench: resuming: {done} episodes already in {log.path}, {total} to run")
    with tqdm(total=total, desc="episodes", unit="ep", disable=not progress) as bar:

        def advance(record: dict) -> None:
            bar.set_postfix_str(describe(record))
            bar.update()

        log.append(records, each=advance)
    log.sort()


def run_grid(
    out: Path,
    fingerprint: str,
    info: dict,
    key: Callable[[dict], Hashable],
    grid: Iterable[Hashable],
    make_task: Callable[[Hashable], Any],
    execute: Callable[[list], Iterable[dict]],
    describe: Callable[[dict], str],
    error: type[Exception] = ValueError,
    progress: bool = True,
) -> EpisodeLog:
    """The run skeleton every task family shares: open the run (:func:`open_run`), make a task
    of every key of ``grid`` not yet in its episode log (``key(record)`` of a finished record
    equals its grid key), run them (``execute(tasks)`` yields records, e.g. through
    :func:`run_episodes`) and record them (:func:`record_episodes`). Returns the log; the
    family writes its report from ``log.records()``."""
    log = open_run(out, fingerprint, info, key, error)
    done = log.done()
    tasks = [make_task(k) for k in grid if k not in done]
    record_episodes(log, execute(tasks), len(tasks), len(done), describe, progress)
    return log


# -- executors ------------------------------------------------------------------------------------
_WORKER: dict[str, Any] = {}


def _init_pool(episode: Episode, context: tuple) -> None:
    pool_worker()  # W workers on W cores, gone with the main (ipbench.eval.schedule)
    _WORKER["episode"], _WORKER["context"] = episode, context


def _pool_episode(task: Any) -> dict:
    return _WORKER["episode"](task, *_WORKER["context"])


def _ray_episode(episode: Episode, task: Any, *context: Any) -> dict:
    single_thread_worker()  # a Ray worker: one core, one thread per library
    return episode(task, *context)


def run_episodes(
    episode: Episode,
    tasks: Sequence[Any],
    context: tuple = (),
    *,
    workers: int = 1,
    backend: str = "process",
    ray_address: str | None = None,
    cost: Callable[[Any], float] | None = None,
    error: type[Exception] = ValueError,
) -> Iterator[dict]:
    """``episode(task, *context)`` for every task, yielding each record as it finishes.

    ``workers == 1`` (and the process backend) runs them here, in the given order; otherwise
    ``workers`` local processes or Ray tasks (``ray_address``: a cluster; None: a local
    instance with ``workers`` CPUs) take them longest first by ``cost`` (ties keep the given
    order). ``episode`` must be a module-level function (it is pickled by reference)."""
    if backend not in BACKENDS:
        raise error(f"backend {backend!r}; valid: {', '.join(BACKENDS)}")
    ordered = longest_first(tasks, cost) if cost is not None else list(tasks)
    if backend == "ray":
        yield from _run_ray(episode, ordered, context, workers, ray_address, error)
    elif workers == 1:
        for task in tasks:
            yield episode(task, *context)
    else:
        pool = run_tasks(
            _pool_episode,
            [(t,) for t in ordered],
            workers,
            _init_pool,
            (episode, context),
            what="episode",
        )
        for _, record in pool:
            yield record


def _run_ray(
    episode: Episode,
    tasks: list,
    context: tuple,
    workers: int,
    ray_address: str | None,
    error: type[Exception],
) -> Iterator[dict]:
    try:
        import ray
    except ImportError as err:
        raise error(
            "--backend ray needs Ray: pip install 'ipbench[ray]' (or use --backend process)"
        ) from err
    started = not ray.is_initialized()
    if started:
        kwargs = {"address": ray_address} if ray_address else {"num_cpus": workers}
        ray.init(
            **kwargs,
            include_dashboard=False,
            logging_level="ERROR",
            runtime_env={"env_vars": {"MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}},
        )
    try:
        remote = ray.remote(num_cpus=1)(_ray_episode)
        refs = [ray.put(c) for c in context]
        pending = [remote.remote(episode, t, *refs) for t in tasks]
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            yield ray.get(done[0])
    finally:
        if started:
            ray.shutdown()
