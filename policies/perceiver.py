"""The perception stage inside the policies: observation -> classified object hypotheses.

One RGB-D observation of the wrist camera becomes a world-frame cloud
(:func:`~ipbench.perception.cloud.depth_to_points`), then segments (the whole table, the
inspection area, or the object in the gripper), each described by FPFH bag-of-words and
classified by the trained model. Only the observation and static knowledge of the work cell
(where the inspection area is, the gripper's geometry and kinematics) are used — never the
simulator's state.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ipbench.perception.cloud import PerceptionError, depth_to_points
from ipbench.perception.features import DEFAULT_FEATURES, FeatureConfig, fpfh
from ipbench.perception.model import PerceptionModel
from ipbench.perception.segmentation import (
    DEFAULT_SEGMENTATION,
    Segment,
    SegmentationConfig,
    segment_in_hand,
    segment_region,
    segment_scene,
)
from ipbench.perception.split import DEFAULT_SPLIT, ObjectEnvelope, SplitConfig, split_merged
from ipbench.policies.envelopes import object_envelopes
from ipbench.policies.kinematics import HandKinematics

if TYPE_CHECKING:  # torch is an optional extra: only deep-ipm's runs import it
    from ipbench.perception.pointnet import PointNetEnsemble

__all__ = ["AREA_HALF", "Detection", "Perceiver"]

AREA_HALF = (0.17, 0.17, 0.35)
"""Half size of the box searched around the inspection area's centre (m): the area plus some
table around it, which the plane fit needs."""


@dataclass(frozen=True, eq=False)
class Detection:
    """A segment and its class probabilities ``probs`` (C,) over ``classes``.

    ``viewpoint``: (3,) camera centre of the view (world, m); ``inspected``: the detection
    comes from an inspection view (in hand or in the area).
    """

    segment: Segment
    probs: np.ndarray
    classes: tuple[str, ...]
    viewpoint: np.ndarray
    inspected: bool = False

    @property
    def label(self) -> str:
        """The most probable class."""
        return self.classes[int(np.argmax(self.probs))]

    @property
    def confidence(self) -> float:
        """Probability of :attr:`label`."""
        return float(np.max(self.probs))

    @property
    def points(self) -> np.ndarray:
        """(N, 3) world points of the segment, m."""
        return self.segment.points


class Perceiver:
    """Segments and classifies what the wrist camera sees.

    Parameters
    ----------
    model : the trained codebook + classifier for views of the table (and the inspection
        area), or a :class:`~ipbench.perception.pointnet.PointNetEnsemble`, which classifies a
        segment from its points (no FPFH).
    inspection_area : (3,) centre of the inspection area (world, m).
    segmentation, features : the settings the model's training views were made with.
    hand_model : the model for an object held up to the camera (trained on in-hand views);
        None classifies those with ``model``.
    split : how a table segment too large for one object is cut into objects
        (:mod:`ipbench.perception.split`); None keeps every segment whole.
    envelopes : the object sizes that decide "too large" (default:
        :func:`~ipbench.policies.envelopes.object_envelopes`).
    """

    def __init__(
        self,
        model: PerceptionModel | PointNetEnsemble,
        inspection_area: np.ndarray,
        segmentation: SegmentationConfig = DEFAULT_SEGMENTATION,
        features: FeatureConfig = DEFAULT_FEATURES,
        hand_model: PerceptionModel | PointNetEnsemble | None = None,
        split: SplitConfig | None = DEFAULT_SPLIT,
        envelopes: tuple[ObjectEnvelope, ...] | None = None,
    ) -> None:
        if hand_model is not None and hand_model.classes != model.classes:
            raise PerceptionError(
                f"hand_model classes {hand_model.classes} differ from model classes "
                f"{model.classes}; train both for the same classes"
            )
        self.model = model
        self.hand_model = hand_model or model
        self.segmentation = segmentation
        self.features = features
        self.inspection_area = np.asarray(inspection_area, dtype=float)
        self.kinematics = HandKinematics()
        self.split = split
        self.envelopes = envelopes if envelopes is not None else object_envelopes()

    @property
    def classes(self) -> tuple[str, ...]:
        return self.model.classes

    def _cloud(self, observation: dict):
        return depth_to_points(  # the lens (*_dist) is given when the robot knows one
            observation["wrist_depth"],
            observation["wrist_K"],
            observation["wrist_pose"],
            observation.get("wrist_dist"),
        )

    def _classify(
        self,
        segments: list[Segment],
        eye: np.ndarray,
        inspected: bool,
        model: PerceptionModel | PointNetEnsemble | None = None,
    ):
        model = model or self.model
        if getattr(model, "input", "fpfh") == "points":  # a network on the segments' points
            probs = model.probabilities([s.points for s in segments])
        else:  # FPFH bag of words (the thesis' pipeline)
            views = [fpfh(s.points, self.features, viewpoint=eye) for s in segments]
            probs = model.probabilities(views)
        return [
            Detection(s, p, self.classes, eye, inspected)
            for s, p in zip(segments, probs, strict=True)
        ]

    def scene(self, observation: dict, classify: bool = True) -> list[Detection]:
        """Every object hypothesis on the table (empty when no table plane is found), merged
        segments split (:attr:`split`); ``classify=False`` skips the features and the
        classifier (uniform probabilities: for a policy that labels segments otherwise)."""
        try:
            found = segment_scene(self._cloud(observation), self.segmentation)
        except PerceptionError:
            return []
        segments = list(found.segments)
        if self.split is not None:  # a pile too large to be one segment is split as well
            limit = self.segmentation.max_extent
            whole = split_merged(segments, found.plane, self.envelopes, self.split)
            piles = split_merged(found.oversized, found.plane, self.envelopes, self.split)
            parts = list(whole) + [p for p in piles if max(p.box_extent) <= limit]
            segments = sorted(parts, key=lambda s: -len(s.points))
        eye = observation["wrist_pose"][:3, 3]
        if not classify:
            uniform = np.full(len(self.classes), 1.0 / len(self.classes))
            return [Detection(s, uniform, self.classes, eye) for s in segments]
        return self._classify(segments, eye, inspected=False)

    def in_area(self, observation: dict) -> Detection | None:
        """The object in the inspection area (None when nothing is there)."""
        try:
            segment = segment_region(
                self._cloud(observation), self.inspection_area, AREA_HALF, self.segmentation
            )
        except PerceptionError:
            return None
        if segment is None:
            return None
        return self._classify([segment], observation["wrist_pose"][:3, 3], inspected=True)[0]

    def in_hand(self, observation: dict) -> Detection | None:
        """The object held by the gripper, classified by :attr:`hand_model` (None when the
        hand is empty or out of view)."""
        q = observation["qpos"]
        segment = segment_in_hand(
            self._cloud(observation),
            self.kinematics.tcp_pose(q),
            self.kinematics.jaw_opening(q),
            config=self.segmentation,
        )
        if segment is None:
            return None
        eye = observation["wrist_pose"][:3, 3]
        return self._classify([segment], eye, inspected=True, model=self.hand_model)[0]
