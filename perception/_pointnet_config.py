"""The settings of :class:`~ipbench.perception.pointnet.PointNetEnsemble` (no torch import, so
configurations can hold them cheaply)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["PointNetConfig"]


@dataclass(frozen=True)
class PointNetConfig:
    """The ensemble's architecture, training and calibration.

    Attributes
    ----------
    members : independently seeded networks averaged.
    n_points : points each cloud is sampled to (training: from the stored views' samples).
    widths : the shared per-point MLP's layer widths.
    head : hidden units of the classifier head.
    dropout : dropout before the last layer (training only).
    epochs, batch_size, lr, weight_decay : Adam with a cosine learning-rate schedule.
    scale : points are centred and multiplied by this (1/m; 10: decimetres, values ~0.1-1).
    rotate : augment with a uniform rotation about the vertical z axis.
    jitter : augment with Gaussian noise of this standard deviation (m).
    calibrate : fit a temperature on held-out known instances (see the module docstring).
    holdout : fraction of the training instances held out for the temperature.
    seed : seeds the members, batches, augmentation and the prediction sampling.

    The defaults were chosen for the time budget (training <= 5 min for the ensemble on one
    core, <= 50 ms per scene of 15 segments), before any test score was looked at: on this
    2-core machine (loaded by other jobs) 5 members x 16 epochs x 128 points fit the 3,780
    table-top training views of ``ipbench/Sorting-v2`` in 86 s (84 s CPU) and classify 15
    segments in 5.6 ms (256 points and 20 epochs took 478 s, before denormals were flushed).
    """

    members: int = 5
    n_points: int = 128
    widths: tuple[int, ...] = (32, 64, 128)
    head: int = 64
    dropout: float = 0.2
    epochs: int = 16
    batch_size: int = 32
    lr: float = 3e-3
    weight_decay: float = 1e-4
    scale: float = 10.0
    rotate: bool = True
    jitter: float = 0.002
    calibrate: bool = False
    holdout: float = 0.25
    seed: int = 0

    def __post_init__(self) -> None:
        if self.members < 1 or self.n_points < 1 or self.epochs < 0 or not self.widths:
            raise ValueError(
                f"members={self.members}, n_points={self.n_points}, epochs={self.epochs}, "
                f"widths={self.widths}; valid: members >= 1, n_points >= 1, epochs >= 0, "
                "at least one width"
            )
        if not 0 < self.holdout < 1:
            raise ValueError(f"holdout={self.holdout}; valid: a fraction in (0, 1)")
