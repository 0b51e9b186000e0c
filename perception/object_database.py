"""A database of known objects for recognition: local features of views of each object alone.

Each :class:`ObjectView` (an image of one object on its own, a binary mask of the object and
its class name; capturing them with the simulator is done by the evaluation rigs) becomes a
:class:`ModelView`: the features detected inside the mask, each keypoint's offset to the
object's centre (the mask's centroid) for Hough voting of the centre, and the object's
outline (the corners of the mask's bounding box) for the homography check (thesis ch. 3
§3.3, MSCOI).

Saved as ``.npz`` (no pickles) with :data:`FORMAT_VERSION`; a file that is not a database,
is damaged, has another version or another feature type raises :class:`DatabaseFileError`.
"""

from __future__ import annotations

import os
import zipfile
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from ipbench.perception.features2d import (
    DEFAULT_MAX_FEATURES,
    FEATURE_TYPES,
    ActiveVisionError,
    Features,
    detect,
)
from ipbench.perception.matching import TrainSet

__all__ = [
    "FORMAT_VERSION",
    "DatabaseFileError",
    "ModelView",
    "ObjectDatabase",
    "ObjectView",
]

FORMAT_VERSION = 1
_KEYS = (
    "version", "feature_type", "classes", "view_class", "view_count", "centres", "outlines",
    "xy", "size", "angle", "response", "descriptors",
)  # fmt: skip


class DatabaseFileError(ActiveVisionError):
    """A database file that cannot be read as this version's :class:`ObjectDatabase`."""


@dataclass(frozen=True, eq=False)
class ObjectView:
    """One view of one object alone: ``image`` uint8 (H, W) or (H, W, 3) RGB, ``mask`` (H, W)
    non-zero on the object, ``class_name`` the object's class."""

    image: np.ndarray
    mask: np.ndarray
    class_name: str


@dataclass(frozen=True, eq=False)
class ModelView:
    """A view in the database.

    Attributes
    ----------
    class_name : str
        The object's class.
    features : Features
        Keypoints detected inside the object's mask (N of them).
    offsets : (N, 2) float32 array
        ``centre - xy`` of every keypoint, px (in the view's image).
    centre : (2,) float64 array
        The object's centre in the view (centroid of the mask), px.
    outline : (4, 2) float64 array
        Corners of the mask's bounding box, clockwise on screen from the top left, px.
    """

    class_name: str
    features: Features
    offsets: np.ndarray
    centre: np.ndarray
    outline: np.ndarray

    @property
    def radius(self) -> float:
        """Half the diagonal of the outline, px: the object's size in this view."""
        return 0.5 * float(np.linalg.norm(self.outline[2] - self.outline[0]))


def _model_view(view: ObjectView, index: int, feature_type: str, max_features: int) -> ModelView:
    if not isinstance(view, ObjectView):
        raise ActiveVisionError(f"view {index} is a {type(view).__name__}; valid: ObjectView")
    if not (isinstance(view.class_name, str) and view.class_name):
        raise ActiveVisionError(
            f"view {index} has class name {view.class_name!r}; valid: non-empty str"
        )
    image = np.asarray(view.image)
    mask = np.asarray(view.mask) != 0
    if mask.shape != image.shape[:2]:
        raise ActiveVisionError(
            f"view {index} ({view.class_name}): mask shape {mask.shape} is not the image's"
            f" {image.shape[:2]}; valid: a (H, W) mask of the image"
        )
    if not mask.any():
        raise ActiveVisionError(f"view {index} ({view.class_name}): the mask is empty")
    features = detect(image, feature_type, mask=mask, max_features=max_features)
    moments = cv2.moments(mask.astype(np.uint8), binaryImage=True)
    centre = np.array([moments["m10"] / moments["m00"], moments["m01"] / moments["m00"]])
    x, y, w, h = cv2.boundingRect(mask.astype(np.uint8))
    outline = np.array([[x, y], [x + w - 1, y], [x + w - 1, y + h - 1], [x, y + h - 1]], float)
    offsets = (centre[None, :] - features.xy).astype(np.float32)
    return ModelView(view.class_name, features, offsets, centre, outline)


@dataclass(frozen=True, eq=False)
class ObjectDatabase:
    """Model views of known objects, all described with one ``feature_type``.

    Attributes
    ----------
    feature_type : str
        One of :data:`~ipbench.perception.features2d.FEATURE_TYPES`.
    views : tuple of ModelView
        In the order given to :meth:`build`.
    """

    feature_type: str
    views: tuple[ModelView, ...]

    @property
    def classes(self) -> tuple[str, ...]:
        """Class names, sorted."""
        return tuple(sorted({v.class_name for v in self.views}))

    def __len__(self) -> int:
        return len(self.views)

    @cached_property
    def train_set(self) -> TrainSet:
        """The views' features, prepared once for :func:`~ipbench.perception.matching.match_many`
        (in view order)."""
        return TrainSet(tuple(v.features for v in self.views))

    @classmethod
    def build(
        cls,
        views: Iterable[ObjectView],
        feature_type: str,
        max_features: int = DEFAULT_MAX_FEATURES,
    ) -> ObjectDatabase:
        """Detect the features of every view (inside its mask); raises if a class gets none."""
        if feature_type not in FEATURE_TYPES:
            raise ActiveVisionError(
                f"unknown feature type {feature_type!r}; valid: {', '.join(FEATURE_TYPES)}"
            )
        model = tuple(_model_view(v, i, feature_type, max_features) for i, v in enumerate(views))
        if not model:
            raise ActiveVisionError("no views given; valid: at least one ObjectView")
        counts: dict[str, int] = {}
        for v in model:
            counts[v.class_name] = counts.get(v.class_name, 0) + len(v.features)
        empty = sorted(c for c, n in counts.items() if n == 0)
        if empty:
            raise ActiveVisionError(
                f"no {feature_type} features in any view of {empty}: texture-less objects"
                " cannot be recognised; add textured views or drop these classes"
            )
        return cls(feature_type, model)

    def stats(self) -> dict[str, float]:
        """Sizes: classes, views, keypoints (total and per view min/median/max), descriptor MB."""
        per_view = np.array([len(v.features) for v in self.views])
        nbytes = sum(v.features.descriptors.nbytes for v in self.views)
        return {
            "classes": len(self.classes),
            "views": len(self.views),
            "keypoints": int(per_view.sum()),
            "keypoints_per_view_min": int(per_view.min()),
            "keypoints_per_view_median": float(np.median(per_view)),
            "keypoints_per_view_max": int(per_view.max()),
            "descriptor_mb": nbytes / 1e6,
        }

    def save(self, path: str | os.PathLike) -> None:
        """Write the database to ``path`` (``.npz``, compressed, no pickles)."""
        classes = self.classes
        feats = [v.features for v in self.views]
        np.savez_compressed(
            path,
            version=np.int64(FORMAT_VERSION),
            feature_type=np.str_(self.feature_type),
            classes=np.array(classes, dtype=np.str_),
            view_class=np.array([classes.index(v.class_name) for v in self.views], np.int64),
            view_count=np.array([len(f) for f in feats], np.int64),
            centres=np.array([v.centre for v in self.views], np.float64),
            outlines=np.array([v.outline for v in self.views], np.float64),
            xy=np.concatenate([f.xy for f in feats]),
            size=np.concatenate([f.size for f in feats]),
            angle=np.concatenate([f.angle for f in feats]),
            response=np.concatenate([f.response for f in feats]),
            descriptors=np.concatenate([f.descriptors for f in feats]),
        )

    @classmethod
    def load(cls, path: str | os.PathLike, feature_type: str | None = None) -> ObjectDatabase:
        """Read a database written by :meth:`save`; with ``feature_type``, check it matches."""
        try:
            with np.load(path, allow_pickle=False) as data:
                missing = [k for k in _KEYS if k not in data.files]
                if missing:
                    raise DatabaseFileError(
                        f"{path} is not an ipbench object database: it lacks {missing}"
                    )
                arrays = {k: data[k] for k in _KEYS}
        except DatabaseFileError:
            raise
        except FileNotFoundError as error:
            raise DatabaseFileError(
                f"{path} does not exist; build it with ObjectDatabase.build"
            ) from error
        except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as error:
            raise DatabaseFileError(
                f"{path} is damaged or not an .npz object database ({error}); rebuild it"
            ) from error
        version = int(arrays["version"])
        if version != FORMAT_VERSION:
            raise DatabaseFileError(
                f"{path} has format version {version}; valid: {FORMAT_VERSION} (rebuild it)"
            )
        stored = str(arrays["feature_type"])
        if stored not in FEATURE_TYPES or (feature_type is not None and stored != feature_type):
            raise DatabaseFileError(
                f"{path} holds {stored!r} features; expected {feature_type or FEATURE_TYPES!r}"
            )
        return cls(stored, _split_views(path, stored, arrays))


def _split_views(path, feature_type: str, a: dict[str, np.ndarray]) -> tuple[ModelView, ...]:
    count, n = a["view_count"], len(a["xy"])
    v = len(count)
    ok = (
        count.ndim == 1 and (count >= 0).all() and int(count.sum()) == n
        and a["view_class"].shape == (v,) and a["centres"].shape == (v, 2)
        and a["outlines"].shape == (v, 4, 2) and a["xy"].shape == (n, 2)
        and all(len(a[k]) == n for k in ("size", "angle", "response", "descriptors"))
        and ((a["view_class"] >= 0) & (a["view_class"] < len(a["classes"]))).all()
    )  # fmt: skip
    if not ok:
        raise DatabaseFileError(f"{path} has inconsistent array shapes (damaged); rebuild it")
    bounds = np.concatenate([[0], np.cumsum(count)])
    views = []
    for i in range(v):
        s = slice(int(bounds[i]), int(bounds[i + 1]))
        f = Features(
            feature_type, a["xy"][s], a["size"][s], a["angle"][s], a["response"][s],
            a["descriptors"][s],
        )  # fmt: skip
        centre = a["centres"][i]
        offsets = (centre[None, :] - f.xy).astype(np.float32)
        views.append(
            ModelView(str(a["classes"][a["view_class"][i]]), f, offsets, centre, a["outlines"][i])
        )
    return tuple(views)
