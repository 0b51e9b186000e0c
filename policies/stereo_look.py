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

Every pixel setting downstream (the homography's reprojection threshold, the epipolar band,
vergence's bins, saliency's blur) is stated for an image :data:`WORK_WIDTH` px wide, the head
image of ``ipbench/Exploration-v0``. :func:`look` expresses keypoints, sizes and K in that
*working frame* (at 1024 px wide it is the image itself), so a setting means the same angle at
any resolution. A foveated observation (``head_*_fovea``, :mod:`ipbench.envs.sensors.foveation`)
gives each eye two images: the fovea's keypoints replace the periphery's inside the fovea's
window, mapped into the periphery by the two K.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ipbench.envs.sensors.foveation import fovea_to_periphery, scale_intrinsics
from ipbench.perception.features2d import DEFAULT_MAX_FEATURES, Features, detect
from ipbench.perception.object_database import ObjectDatabase
from ipbench.perception.recognition import Recognition, RecognitionConfig, recognise
from ipbench.perception.stereo import StereoRig, hypothesis_position, match_hypotheses
from ipbench.policies.gaze import on_table

__all__ = ["WORK_WIDTH", "Candidate", "Look", "eye_features", "look"]

WORK_WIDTH = 1024
"""Width of the working frame, px (module docstring)."""


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
    """What one stereo observation shows (module docstring). Pixels, keypoints and the rig's K
    are in the working frame: ``size`` (height, width) px, ``scale`` working px per pixel of
    ``head_left``."""

    left: Features
    right: Features
    recognition_left: Recognition
    recognition_right: Recognition
    rig: StereoRig
    candidates: tuple[Candidate, ...]
    size: tuple[int, int]
    scale: float

    @property
    def unexplained_left(self) -> np.ndarray:
        """(U, 2) px: left keypoints no recognised object explains (saliency's input)."""
        return self.left.xy[self.recognition_left.unmatched]


def _moved(features: Features, xy: np.ndarray, size_scale: float) -> Features:
    return Features(
        features.feature_type,
        np.asarray(xy, np.float32).reshape(-1, 2),
        (features.size * size_scale).astype(np.float32),
        features.angle,
        features.response,
        features.descriptors,
    )


def _joined(a: Features, b: Features) -> Features:
    fields = ("xy", "size", "angle", "response", "descriptors")
    return Features(
        a.feature_type, *(np.concatenate([getattr(a, k), getattr(b, k)]) for k in fields)
    )


def eye_features(
    obs: dict, side: str, feature_type: str, max_features: int = DEFAULT_MAX_FEATURES
) -> tuple[Features, np.ndarray, tuple[int, int], float]:
    """One eye's keypoints in the working frame (module docstring): (features, K (3, 3),
    working (height, width) px, working px per pixel of ``head_{side}``)."""
    image, K = obs[f"head_{side}"], np.asarray(obs[f"head_{side}_K"], float)  # noqa: N806
    features = detect(image, feature_type, max_features=max_features)
    if f"head_{side}_fovea" in obs:  # foveated: the fovea's keypoints inside its window
        fovea_image, fovea_K = obs[f"head_{side}_fovea"], obs[f"head_{side}_fovea_K"]  # noqa: N806
        fovea = detect(fovea_image, feature_type, max_features=max_features)
        fh, fw = fovea_image.shape[:2]
        lo, hi = fovea_to_periphery([[-0.5, -0.5], [fw - 0.5, fh - 0.5]], fovea_K, K)
        inside = np.all((features.xy >= lo) & (features.xy < hi), axis=1)
        mapped = fovea_to_periphery(fovea.xy, fovea_K, K)
        ratio = float(K[0, 0] / fovea_K[0, 0])
        features = _joined(features.subset(~inside), _moved(fovea, mapped, ratio))
    h, w = image.shape[:2]
    if w == WORK_WIDTH:
        return features, K, (h, w), 1.0
    s = WORK_WIDTH / w
    features = _moved(features, (features.xy.astype(float) + 0.5) * s - 0.5, s)
    return features, scale_intrinsics(K, s), (round(h * s), WORK_WIDTH), s


def look(
    obs: dict,
    database: ObjectDatabase,
    config: RecognitionConfig | None = None,
    max_features: int = DEFAULT_MAX_FEATURES,
) -> Look:
    """Recognise and localise the database objects in an exploration observation."""
    kind = database.feature_type
    left, K_left, size, scale = eye_features(obs, "left", kind, max_features)  # noqa: N806
    right, K_right, _, _ = eye_features(obs, "right", kind, max_features)  # noqa: N806
    rec_l, rec_r = recognise(left, database, config), recognise(right, database, config)
    rig = StereoRig(  # the lenses, when the robot knows them (extrinsics="calibrated")
        K_left,
        obs["head_left_pose"],
        K_right,
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
    return Look(left, right, rec_l, rec_r, rig, tuple(candidates), size, scale)
