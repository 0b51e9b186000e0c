"""The network of :mod:`ipbench.perception.pointnet` and the training of one ensemble member.

A PointNet (Qi et al., CVPR 2017) without the input and feature transform nets: a per-point
MLP shared over the points, a max pool over them (order invariant), and a small classifier
head. Input points are centred on their centroid and multiplied by a fixed scale, never
normalised to a unit sphere: the object's metric size is a cue. Training is seeded and
deterministic on the CPU: the caller fixes torch's threads and algorithms
(:func:`deterministic_cpu`); batches, point subsets and augmentation (rotation about the
vertical z axis, Gaussian jitter) are drawn by a numpy generator.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager

import numpy as np
import torch
from torch import nn

__all__ = ["PointNet", "centre", "deterministic_cpu", "prepare_batch", "train_member"]


class PointNet(nn.Module):
    """Per-point MLP ``3 -> widths``, max pool, head ``widths[-1] -> head -> n_classes``.

    ``forward`` maps (B, N, 3) centred, scaled points to (B, n_classes) logits.
    """

    def __init__(self, n_classes: int, widths: Sequence[int], head: int, dropout: float) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        width = 3
        for w in widths:
            layers += [nn.Linear(width, w), nn.ReLU()]
            width = w
        self.point_mlp = nn.Sequential(*layers)
        self.head = nn.Sequential(
            nn.Linear(width, head), nn.ReLU(), nn.Dropout(dropout), nn.Linear(head, n_classes)
        )

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        return self.head(self.point_mlp(points).amax(dim=1))


@contextmanager
def deterministic_cpu(threads: int = 1) -> Iterator[None]:
    """torch on ``threads`` threads with deterministic algorithms and denormal floats flushed
    to zero; the threads and the algorithm setting are restored after, flushing is switched
    off again (torch's default; it has no getter).

    Flushing matters: weight decay leaves thousands of trained weights denormal, and on this
    CPU they made a scene's prediction 10x slower (44 ms instead of 4.4 ms)."""
    old_threads = torch.get_num_threads()
    old_det = torch.are_deterministic_algorithms_enabled()
    torch.set_num_threads(threads)
    torch.use_deterministic_algorithms(True)
    torch.set_flush_denormal(True)
    try:
        yield
    finally:
        torch.set_flush_denormal(False)
        torch.set_num_threads(old_threads)
        torch.use_deterministic_algorithms(old_det)


def centre(points: np.ndarray, scale: float) -> np.ndarray:
    """(B, N, 3) points minus each cloud's centroid, times ``scale`` (1/m), float32."""
    return ((points - points.mean(axis=1, keepdims=True)) * scale).astype(np.float32)


def prepare_batch(
    clouds: np.ndarray,
    n_points: int,
    scale: float,
    rng: np.random.Generator,
    rotate: bool,
    jitter: float,
) -> torch.Tensor:
    """A training batch from (B, P, 3) clouds (world frame, m): ``n_points`` of each cloud's P
    drawn without replacement, rotated about z by a uniform angle if ``rotate``, jittered by
    N(0, ``jitter`` m) per coordinate, then :func:`centre`-d."""
    b, p, _ = clouds.shape
    take = np.argsort(rng.random((b, p)), axis=1)[:, :n_points]
    pts = np.take_along_axis(clouds, take[:, :, None], axis=1).astype(np.float64)
    if rotate:
        angle = rng.uniform(0.0, 2 * np.pi, b)
        c, s = np.cos(angle), np.sin(angle)
        x, y = pts[..., 0].copy(), pts[..., 1].copy()
        pts[..., 0] = c[:, None] * x - s[:, None] * y
        pts[..., 1] = s[:, None] * x + c[:, None] * y
    if jitter > 0:
        pts += rng.normal(0.0, jitter, pts.shape)
    return torch.from_numpy(centre(pts, scale))


def train_member(
    net: PointNet,
    clouds: np.ndarray,
    labels: np.ndarray,
    *,
    epochs: int,
    batch_size: int,
    lr: float,
    weight_decay: float,
    n_points: int,
    scale: float,
    rotate: bool,
    jitter: float,
    rng: np.random.Generator,
) -> list[float]:
    """Train ``net`` in place with Adam and cross-entropy on (n, P, 3) ``clouds`` and (n,)
    ``labels``; returns the mean training loss of every epoch."""
    opt = torch.optim.Adam(net.parameters(), lr=lr, weight_decay=weight_decay)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=max(epochs, 1))
    target = torch.from_numpy(np.asarray(labels, np.int64))
    losses = []
    net.train()
    for _ in range(epochs):
        order = rng.permutation(len(clouds))
        total = 0.0
        for start in range(0, len(order), batch_size):
            idx = order[start : start + batch_size]
            x = prepare_batch(clouds[idx], n_points, scale, rng, rotate, jitter)
            loss = nn.functional.cross_entropy(net(x), target[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += float(loss.detach()) * len(idx)
        sched.step()
        losses.append(total / len(order))
    net.eval()
    return losses
