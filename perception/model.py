"""A trained perception model on disk: codebook, GP classifier, and the hash that made them.

:func:`load_or_train` returns the saved model when its hash matches the configuration that
asks for it; a stale file (another configuration or format version) or a corrupt one is
reported and the model is trained again, so nothing silently uses a wrong model.
"""

from __future__ import annotations

import pickle
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ipbench.perception.classifiers import Classifier
from ipbench.perception.cloud import PerceptionError
from ipbench.perception.features import Codebook
from ipbench.perception.gpc import MulticlassLaplaceGPC

__all__ = [
    "MODEL_VERSION",
    "ModelFileError",
    "PerceptionModel",
    "load_or_train",
    "posterior_prefix",
]

MODEL_VERSION = 2
"""Format version of the saved file; bumped when the layout changes."""

_CODEBOOK, _GP, _PICKLE = "codebook__", "gp__", "pickle__"


class ModelFileError(PerceptionError):
    """A saved model that is stale (other configuration or version) or unreadable."""


@dataclass(frozen=True)
class PerceptionModel:
    """Codebook + classifier for ``classes`` (category names, in label order).

    The classifier is our GP (saved as its arrays) or any other object with
    ``predict_proba`` (e.g. the SVM baseline; saved pickled — the file is a local cache that
    only ipbench writes). ``key`` is the hash of the configuration (dataset, features,
    classes, classifier) that trained it.
    """

    classes: tuple[str, ...]
    codebook: Codebook
    classifier: MulticlassLaplaceGPC | Classifier
    key: str

    def probabilities(self, views: list[np.ndarray]) -> np.ndarray:
        """(m, C) class probabilities of ``m`` views, each given as its (n_i, 33) FPFHs."""
        if not views:
            return np.zeros((0, len(self.classes)))
        return self.classifier.predict_proba(np.stack([self.codebook.encode(v) for v in views]))

    def save(self, path: str | Path) -> Path:
        """Write atomically (a temporary file renamed into place); a GP's predictive factor
        goes to a file beside it (:func:`posterior_prefix`), which loading maps."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = {f"{_CODEBOOK}{k}": v for k, v in self.codebook.to_arrays().items()}
        if isinstance(self.classifier, MulticlassLaplaceGPC):
            arrays.update({f"{_GP}{k}": v for k, v in self.classifier.get_state().items()})
        else:
            arrays[_PICKLE] = np.frombuffer(pickle.dumps(self.classifier), np.uint8)
        tmp = path.with_name(path.stem + ".tmp.npz")
        np.savez(
            tmp,
            classes=np.array(self.classes),
            key=np.array(self.key),
            version=np.array(MODEL_VERSION),
            **arrays,
        )
        tmp.replace(path)
        if isinstance(self.classifier, MulticlassLaplaceGPC):
            _drop_stale_posteriors(path, self.classifier.map_posterior(posterior_prefix(path)))
        return path

    @classmethod
    def load(cls, path: str | Path, key: str) -> PerceptionModel:
        """Load a model trained by configuration ``key``; :class:`ModelFileError` otherwise."""
        try:
            with np.load(path, allow_pickle=False) as data:
                arrays = {k: data[k] for k in data.files}
        except (OSError, ValueError, zipfile.BadZipFile) as err:
            raise ModelFileError(f"model file {path} is unreadable ({err})") from err
        version = int(arrays.get("version", -1))
        if version != MODEL_VERSION or str(arrays.get("key")) != key:
            raise ModelFileError(
                f"model file {path} is stale: trained by configuration "
                f"{arrays.get('key')!s} (format {version}), expected {key} "
                f"(format {MODEL_VERSION})"
            )
        try:
            codebook = Codebook.from_arrays(
                {k[len(_CODEBOOK) :]: v for k, v in arrays.items() if k.startswith(_CODEBOOK)}
            )
            if _PICKLE in arrays:
                clf = pickle.loads(arrays[_PICKLE].tobytes())
            else:
                clf = MulticlassLaplaceGPC.from_state(
                    {k[len(_GP) :]: v for k, v in arrays.items() if k.startswith(_GP)},
                    posterior=posterior_prefix(path),
                )
                _drop_stale_posteriors(Path(path), clf.posterior_file)
        except (KeyError, ValueError, pickle.UnpicklingError, EOFError) as err:
            raise ModelFileError(f"model file {path} is incomplete ({err})") from err
        return cls(tuple(str(c) for c in arrays["classes"]), codebook, clf, key)


def posterior_prefix(path: str | Path) -> Path:
    """Where the GP of the model file ``path`` keeps its predictive factor: files
    ``STEM.posterior-DIGEST.npy`` beside it (see
    :meth:`~ipbench.perception.gpc.MulticlassLaplaceGPC.map_posterior`)."""
    path = Path(path)
    return path.with_name(f"{path.stem}.posterior")


def _drop_stale_posteriors(path: Path, keep: Path | None) -> None:
    """Remove the factors that other models saved at ``path`` before left beside it."""
    prefix = posterior_prefix(path)
    for old in prefix.parent.glob(f"{prefix.name}-*.npy"):
        if old != keep and not old.name.endswith(".tmp.npy"):
            old.unlink(missing_ok=True)


def load_or_train(
    path: str | Path,
    key: str,
    train: Callable[[], PerceptionModel],
    log: Callable[[str], None] = print,
    kind: type = PerceptionModel,
):
    """The model saved at ``path`` if it was trained by ``key``, else ``train()`` (saved).
    ``kind``: the model class whose ``load(path, key)`` reads it (raising
    :class:`ModelFileError` on a stale or corrupt file, which is reported and replaced)."""
    path = Path(path)
    if path.exists():
        try:
            return kind.load(path, key)
        except ModelFileError as err:
            log(f"ipbench: {err}; training a new model")
    model = train()
    model.save(path)
    return model
