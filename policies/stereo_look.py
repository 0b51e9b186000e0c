"""One look with the stereo head: features of both eyes, recognised instances, their 3-D places.

:func:`look` runs the thesis' recognition on an observation of ``ipbench/Exploration-v0``:
local features of both images (:mod:`ipbench.perception.features2d`), multiple same-class
object instances in each (:func:`~ipbench.perception.recognition.recognise`), left/right
correspondence of the hypotheses (same class, epipolar agreement:
:func:`~ipbench.perception.stereo.match_hypotheses`) and each pair's world position by
triangulation (:func:`~ipbench.perception.stereo.hypothesis_position`), with the cameras' K and
poses as the robot knows them (the observation's). A hypothesis seen by one eye only has no
3-D place and is not a :class:`Candidate`; nor is a pair whose triangulated place is off the
work table (:func:`~ipbench.policies.gaze.on_table`: a false correspondence).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ipbench.perception.features2d import DEFAULT_MAX_FEATURES, Features, detect
from ipbench.perception.object_database import ObjectDatabase
from ipbench.perception.recognition import Recognition, RecognitionConfig, recognise
from ipbench.perception.stereo import StereoRig, hypothesis_position, match_hypotheses
from ipbench.policies.gaze import on_table

__all__ = ["Candidate", "Look", "look"]


@dataclass(frozen=True, eq=False)
class Candidate:
    """A recognised object seen by both eyes.

    Attributes
    ----------
    label : database class name.
    position : (3,) world position, m (triangulated).
    left_centre : (2,) its centre in the left image, px.
    inliers : left-image keypoints verified by the homography (the evidence).
    """

    label: str
    position: np.ndarray
    left_centre: np.ndarray
    inliers: int


@dataclass(frozen=True, eq=False)
class Look:
    """What one stereo observation shows (module docstring)."""

    left: Features
    right: Features
    recognition_left: Recognition
    recognition_right: Recognition
    rig: StereoRig
    candidates: tuple[Candidate, ...]

    @property
    def unexplained_left(self) -> np.ndarray:
        """(U, 2) px: left keypoints no recognised object explains (saliency's input)."""
        return self.left.xy[self.recognition_left.unmatched]


def look(
    obs: dict,
    database: ObjectDatabase,
    config: RecognitionConfig | None = None,
    max_features: int = DEFAULT_MAX_FEATURES,
) -> Look:
    """Recognise and localise the database objects in an exploration observation."""
    kind = database.feature_type
    left = detect(obs["head_left"], kind, max_features=max_features)
    right = detect(obs["head_right"], kind, max_features=max_features)
    rec_l, rec_r = recognise(left, database, config), recognise(right, database, config)
    rig = StereoRig(  # the lenses, when the robot knows them (extrinsics="calibrated")
        obs["head_left_K"],
        obs["head_left_pose"],
        obs["head_right_K"],
        obs["head_right_pose"],
        obs.get("head_left_dist"),
        obs.get("head_right_dist"),
    )
    candidates = []
    for i, j in match_hypotheses(rec_l.hypotheses, rec_r.hypotheses, rig):
        hl, hr = rec_l.hypotheses[i], rec_r.hypotheses[j]
        position = hypothesis_position(hl, hr, rig, left, right)
        if np.all(np.isfinite(position)) and on_table(position):
            candidates.append(Candidate(hl.class_name, position, hl.centre.copy(), hl.inliers))
    candidates.sort(key=lambda c: -c.inliers)
    return Look(left, right, rec_l, rec_r, rig, tuple(candidates))
