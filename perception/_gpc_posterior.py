"""The GP's predictive factor in a file, memory-mapped read-only (private to :mod:`.gpc`).

A fitted :class:`~ipbench.perception.gpc.MulticlassLaplaceGPC` predicts from its
:class:`~ipbench.perception._gpc_laplace.LaplaceFactor`: ``E`` (C, n, n) and ``M`` (n, n),
``(C + 1) n^2`` float64 numbers (686 MB for 3,780 training views and 5 classes). Computing
it from the saved state takes C Choleskys and inverses (12 s on one core for that size), and
pickling it to a worker process copies all of it. Kept in one ``.npy`` file and mapped, it is
read from the page cache instead: every process that maps it shares one copy, and a pickle of
the model carries the path.

File layout: one flat float64 array ``[E.ravel(), M.ravel(), log_det, log_det_book]``; the
name holds a digest of the model's state (training inputs and labels, mode, hyperparameters),
so a file can only be read back by the model that wrote it.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np

from ipbench.perception._gpc_laplace import LaplaceFactor

__all__ = ["factor_file", "read_factor", "state_digest", "write_factor"]


def state_digest(*arrays: np.ndarray) -> str:
    """16 hex digits of a SHA-256 over the arrays' dtypes, shapes and bytes (in order)."""
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()[:16]


def factor_file(prefix: str | Path, digest: str) -> Path:
    """The file of the factor of the model with state digest ``digest``: ``PREFIX-DIGEST.npy``."""
    prefix = Path(prefix)
    return prefix.with_name(f"{prefix.name}-{digest}.npy")


def write_factor(path: str | Path, fac: LaplaceFactor) -> None:
    """Write ``fac`` to ``path`` atomically (a temporary file renamed into place)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    n_cls, n, _ = fac.E.shape
    tmp = path.with_name(f"{path.stem}.{os.getpid()}.tmp.npy")
    out = np.lib.format.open_memmap(
        tmp, mode="w+", dtype=np.float64, shape=((n_cls + 1) * n * n + 2,)
    )
    out[: n_cls * n * n] = fac.E.ravel()
    out[n_cls * n * n : (n_cls + 1) * n * n] = fac.M.ravel()
    out[-2:] = (fac.log_det, fac.log_det_book)
    out.flush()
    del out
    tmp.replace(path)


def read_factor(path: str | Path, n: int, n_cls: int) -> LaplaceFactor | None:
    """The factor in ``path``, mapped read-only, or None when the file is missing or is not
    a factor of ``n`` training points and ``n_cls`` classes (then it must be recomputed)."""
    try:
        flat = np.load(path, mmap_mode="r", allow_pickle=False)
    except (OSError, ValueError):
        return None
    if flat.dtype != np.float64 or flat.shape != ((n_cls + 1) * n * n + 2,):
        return None
    log_det, log_det_book = (float(v) for v in flat[-2:])
    if not (np.isfinite(log_det) and np.isfinite(log_det_book)):
        return None
    E = flat[: n_cls * n * n].reshape(n_cls, n, n)
    M = flat[n_cls * n * n : (n_cls + 1) * n * n].reshape(n, n)
    return LaplaceFactor(E=E, M=M, log_det=log_det, log_det_book=log_det_book)
