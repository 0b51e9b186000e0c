"""A PointNet deep ensemble that classifies a segment from its points (classifier
``pointnet_ensemble``).

Each member is a compact PointNet (:mod:`ipbench.perception._pointnet_net`) trained from its
own seed on the same views as the GP; the ensemble's probabilities are the members' softmax
outputs averaged (Lakshminarayanan et al., NeurIPS 2017), optionally with every member's logits
divided by one temperature fitted on held-out *known* instances (Guo et al., ICML 2017):
``PointNetConfig(calibrate=True)`` holds out ``holdout`` of the training instances (whole
instances, so the temperature sees unseen objects), trains the members on the rest and fits
the temperature by log loss on the held-out views. MC dropout (dropout left on at prediction,
Gal & Ghahramani 2016) would be the cheaper alternative to several members; it is not
implemented here, since independent members were measured to fit the training budget.

Input: any number of (n_i, 3) world-frame point arrays (m, z up), e.g. segments of an
episode's wrist cloud or the :attr:`~ipbench.perception.viewset.ViewSet.points` samples. Each is
sampled to ``n_points`` by a generator seeded with ``config.seed`` (so a segment's probabilities
do not depend on the other segments), centred on its centroid and scaled by ``scale`` (size
stays a cue). Training and prediction run torch deterministically on one thread
(:func:`~ipbench.perception._pointnet_net.deterministic_cpu`; the previous settings are
restored), so the same seed on the same machine gives the same model.
"""

from __future__ import annotations

import json
import zipfile
from collections.abc import Callable, Sequence
from dataclasses import asdict
from pathlib import Path

import numpy as np
from scipy.optimize import minimize_scalar

try:
    import torch
except ModuleNotFoundError as _missing:  # torch is the optional extra "deep"
    if _missing.name != "torch":
        raise
    raise ModuleNotFoundError(
        "the PointNet ensemble (classifier pointnet_ensemble, policy deep-ipm) needs torch, "
        "which is ipbench's optional extra 'deep': pip install 'ipbench[deep]'",
        name="torch",
    ) from _missing

from ipbench.perception._pointnet_config import PointNetConfig
from ipbench.perception._pointnet_net import PointNet, centre, deterministic_cpu, train_member
from ipbench.perception.model import ModelFileError, load_or_train
from ipbench.perception.viewset import sample_points

__all__ = [
    "POINTNET_VERSION",
    "PointNetConfig",
    "PointNetEnsemble",
    "load_or_train_pointnet",
]

POINTNET_VERSION = 1
"""Format version of a saved ensemble; bumped when the layout or the network changes."""


_CHUNK = 256
"""Clouds per forward pass at prediction."""


class PointNetEnsemble:
    """A deep ensemble of PointNets over ``n_classes`` classes.

    Parameters
    ----------
    n_classes : number of classes (labels ``0 .. n_classes - 1``).
    config : architecture and training (None: the defaults).
    classes : class names in label order (default ``"0", "1", ...``).
    key : hash of the configuration that trained it (for the cache).
    """

    name = "pointnet_ensemble"
    input = "points"
    """What it classifies: the segments' points (the FPFH models classify bags of words)."""

    def __init__(
        self,
        n_classes: int,
        config: PointNetConfig | None = None,
        classes: Sequence[str] | None = None,
        key: str = "",
    ) -> None:
        if int(n_classes) < 2:
            raise ValueError(f"n_classes must be >= 2, got {n_classes}")
        self.n_classes = int(n_classes)
        self.config = PointNetConfig() if config is None else config
        self.classes = tuple(classes) if classes is not None else tuple(map(str, range(n_classes)))
        if len(self.classes) != self.n_classes:
            raise ValueError(f"{len(self.classes)} class names for {n_classes} classes")
        self.key = key
        self.temperature = 1.0
        self.members: list[PointNet] = []
        self.losses: list[list[float]] = []

    def _net(self) -> PointNet:
        c = self.config
        return PointNet(self.n_classes, c.widths, c.head, c.dropout)

    def fit(
        self, clouds: np.ndarray, labels: np.ndarray, groups: np.ndarray | None = None
    ) -> PointNetEnsemble:
        """Train on (n, P, 3) ``clouds`` (world frame, m) with (n,) ``labels``; ``groups``
        (n,) names each view's instance (needed with ``calibrate``: whole instances are held
        out)."""
        c = self.config
        clouds = np.asarray(clouds, np.float32)
        labels = np.asarray(labels, np.int64)
        if clouds.ndim != 3 or clouds.shape[2] != 3 or len(clouds) != len(labels):
            raise ValueError(
                f"clouds must be (n, P, 3) with one label each; got {clouds.shape} and "
                f"{labels.shape} labels"
            )
        if not len(clouds) or not np.isfinite(clouds).all():
            raise ValueError(
                "no training views, or views without points (NaN): render the dataset with "
                "points (ipbench.eval.capture.dataset, DATASET_VERSION >= 3)"
            )
        if labels.min() < 0 or labels.max() >= self.n_classes:
            raise ValueError(f"labels must lie in 0..{self.n_classes - 1}")
        train = np.ones(len(labels), bool)
        if c.calibrate:
            if groups is None:
                raise ValueError("calibrate=True needs groups (each view's instance name)")
            names = np.unique(np.asarray(groups))
            rng = np.random.default_rng([c.seed, 7])
            held = rng.choice(names, max(1, round(c.holdout * len(names))), replace=False)
            train = ~np.isin(groups, held)
            if not train.any():
                raise ValueError("calibrate=True needs at least two training instances")
        self.members, self.losses = [], []
        with deterministic_cpu(), torch.random.fork_rng(devices=[]):
            for m in range(c.members):
                torch.manual_seed(c.seed * 1000 + m)
                net = self._net()
                rng = np.random.default_rng([c.seed, m])
                self.losses.append(
                    train_member(
                        net,
                        clouds[train],
                        labels[train],
                        epochs=c.epochs,
                        batch_size=c.batch_size,
                        lr=c.lr,
                        weight_decay=c.weight_decay,
                        n_points=c.n_points,
                        scale=c.scale,
                        rotate=c.rotate,
                        jitter=c.jitter,
                        rng=rng,
                    )
                )
                self.members.append(net)
        self.temperature = 1.0
        if c.calibrate and (~train).any():
            self.temperature = _fit_temperature(self._logits(clouds[~train]), labels[~train])
        return self

    def _inputs(self, clouds: Sequence[np.ndarray] | np.ndarray) -> torch.Tensor:
        pts = []
        for i, cloud in enumerate(clouds):
            cloud = np.asarray(cloud, np.float64)
            if cloud.ndim != 2 or cloud.shape[1] != 3 or not len(cloud):
                raise ValueError(f"cloud {i}: expected a non-empty (n, 3) array, got {cloud.shape}")
            if not np.isfinite(cloud).all():
                raise ValueError(f"cloud {i} has non-finite points (views stored without points?)")
            rng = np.random.default_rng(self.config.seed)
            pts.append(sample_points(cloud, self.config.n_points, rng))
        return torch.from_numpy(centre(np.stack(pts).astype(np.float64), self.config.scale))

    def _logits(self, clouds: Sequence[np.ndarray] | np.ndarray) -> np.ndarray:
        """(M, m, C) logits of every member."""
        if not self.members:
            raise ValueError("PointNetEnsemble is not fitted: call fit(clouds, labels) first")
        out = []
        with deterministic_cpu(), torch.no_grad():
            for start in range(0, len(clouds), _CHUNK):  # bounded memory for large test sets
                x = self._inputs(clouds[start : start + _CHUNK])
                out.append(np.stack([net(x).numpy().astype(np.float64) for net in self.members]))
        return np.concatenate(out, axis=1)

    def predict_proba(self, clouds: Sequence[np.ndarray] | np.ndarray) -> np.ndarray:
        """(m, C) class probabilities of ``m`` clouds (each (n_i, 3), world frame, m); rows
        sum to one."""
        if len(clouds) == 0:
            return np.zeros((0, self.n_classes))
        return _ensemble_softmax(self._logits(clouds), self.temperature)

    probabilities = predict_proba
    """The :class:`~ipbench.perception.model.PerceptionModel`-like name: segments' points."""

    def predict(self, clouds: Sequence[np.ndarray] | np.ndarray) -> np.ndarray:
        """(m,) most probable classes."""
        return np.argmax(self.predict_proba(clouds), axis=1)

    def save(self, path: str | Path) -> Path:
        """Write the members' state dicts, config, classes, key and temperature to an .npz
        (atomically: a temporary file renamed into place)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = {
            f"m{m}.{name}": t.detach().numpy()
            for m, net in enumerate(self.members)
            for name, t in net.state_dict().items()
        }
        tmp = path.with_name(path.stem + ".tmp.npz")
        np.savez(
            tmp,
            version=np.array(POINTNET_VERSION),
            key=np.array(self.key),
            classes=np.array(self.classes),
            config=np.array(json.dumps(asdict(self.config))),
            temperature=np.array(self.temperature),
            **arrays,
        )
        tmp.replace(path)
        return path

    @classmethod
    def load(cls, path: str | Path, key: str) -> PointNetEnsemble:
        """The ensemble saved at ``path`` by configuration ``key``; :class:`ModelFileError`
        when it is unreadable, incomplete or stale."""
        try:
            with np.load(path, allow_pickle=False) as data:
                arrays = {k: data[k] for k in data.files}
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as err:
            raise ModelFileError(f"PointNet file {path} is unreadable ({err})") from err
        version = int(arrays.get("version", -1))
        if version != POINTNET_VERSION or str(arrays.get("key")) != key:
            raise ModelFileError(
                f"PointNet file {path} is stale: trained by configuration {arrays.get('key')!s}"
                f" (format {version}), expected {key} (format {POINTNET_VERSION})"
            )
        try:
            raw = json.loads(str(arrays["config"]))
            config = PointNetConfig(**{**raw, "widths": tuple(raw["widths"])})
            classes = tuple(str(c) for c in arrays["classes"])
            model = cls(len(classes), config, classes, key)
            model.temperature = float(arrays["temperature"])
            for m in range(config.members):
                net = model._net()
                state = {
                    name: torch.from_numpy(arrays[f"m{m}.{name}"]) for name in net.state_dict()
                }
                net.load_state_dict(state, strict=True)
                net.eval()
                model.members.append(net)
        except (KeyError, ValueError, TypeError, RuntimeError) as err:
            raise ModelFileError(f"PointNet file {path} is incomplete ({err})") from err
        return model


def _ensemble_softmax(logits: np.ndarray, temperature: float) -> np.ndarray:
    """Mean over members of softmax(logits / temperature); (M, m, C) -> (m, C)."""
    z = logits / temperature
    z = np.exp(z - z.max(axis=2, keepdims=True))
    p = (z / z.sum(axis=2, keepdims=True)).mean(axis=0)
    return p / p.sum(axis=1, keepdims=True)


def _fit_temperature(logits: np.ndarray, labels: np.ndarray) -> float:
    """The temperature in [0.05, 20] minimising the ensemble's log loss on held-out views."""

    def nll(log_t: float) -> float:
        p = _ensemble_softmax(logits, float(np.exp(log_t)))
        return float(-np.mean(np.log(np.clip(p[np.arange(len(labels)), labels], 1e-12, 1))))

    return float(np.exp(minimize_scalar(nll, bounds=(np.log(0.05), np.log(20.0))).x))


def load_or_train_pointnet(
    path: str | Path,
    key: str,
    train: Callable[[], PointNetEnsemble],
    log: Callable[[str], None] = print,
) -> PointNetEnsemble:
    """The ensemble saved at ``path`` if configuration ``key`` trained it, else ``train()``
    (saved there); a stale or corrupt file is reported through ``log`` and replaced."""
    return load_or_train(path, key, train, log, kind=PointNetEnsemble)
