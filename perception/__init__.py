"""Perception: depth to point cloud, segmentation, FPFH bag-of-words, GP classification.

Perception reads observations only (depth, intrinsics, camera pose, and for in-hand crops the
robot's own gripper pose), never simulator state. The rendered training data lives in
:mod:`ipbench.eval.capture.dataset`, which uses the simulator as a capture rig and is not
imported here.

- :mod:`~ipbench.perception.cloud`: depth → world-frame point cloud.
- :mod:`~ipbench.perception.segmentation`: table plane (RANSAC), prism, Euclidean clusters;
  foveated crops (inspection area, in hand); segment evaluation against ground truth.
- :mod:`~ipbench.perception.features`: FPFH, k-means codebook, max-pooled bag of words.
- :mod:`~ipbench.perception.gpc`: multi-class GP classification, Laplace approximation
  (GPML algorithms 3.3/3.4) with hyper-parameters fitted by L-BFGS.
- :mod:`~ipbench.perception.classifiers`: one interface for the GP and the SVM and
  scikit-learn GP baselines.
- :mod:`~ipbench.perception.metrics`: accuracy, log loss, calibration error, confusion.
- :mod:`~ipbench.perception.model`: a trained model on disk, checked against its config hash.

Active binocular vision (thesis ch. 3; imported from their modules, not here):

- :mod:`~ipbench.perception.features2d`: SIFT, KAZE, AKAZE, ORB keypoints; ratio-test matching.
- :mod:`~ipbench.perception.object_database`: views of known objects, their features, on disk.
- :mod:`~ipbench.perception.recognition`: multiple same-class object instances (Hough voting of
  the object centre, RANSAC homography).
- :mod:`~ipbench.perception.vergence`: disparity histograms, global and selective vergence.
- :mod:`~ipbench.perception.stereo`: triangulation, epipolar checks, left/right hypotheses.
- :mod:`~ipbench.perception.saliency`: saliency of unexplained features, inhibition of return.
"""

from ipbench.perception.classifiers import CLASSIFIERS, Classifier, make_classifier
from ipbench.perception.cloud import Cloud, PerceptionError, crop_box, depth_to_points
from ipbench.perception.features import Codebook, FeatureConfig, describe, fpfh
from ipbench.perception.gpc import GPCConfig, MulticlassLaplaceGPC
from ipbench.perception.metrics import (
    accuracy,
    confusion_matrix,
    expected_calibration_error,
    log_loss,
)
from ipbench.perception.model import ModelFileError, PerceptionModel, load_or_train
from ipbench.perception.segment_eval import match_segments
from ipbench.perception.segmentation import (
    Segment,
    SegmentationConfig,
    grasp_yaw,
    segment_in_hand,
    segment_region,
    segment_scene,
)

__all__ = [
    "CLASSIFIERS",
    "Classifier",
    "Cloud",
    "Codebook",
    "FeatureConfig",
    "GPCConfig",
    "ModelFileError",
    "MulticlassLaplaceGPC",
    "PerceptionError",
    "PerceptionModel",
    "Segment",
    "SegmentationConfig",
    "accuracy",
    "confusion_matrix",
    "crop_box",
    "depth_to_points",
    "describe",
    "expected_calibration_error",
    "fpfh",
    "grasp_yaw",
    "load_or_train",
    "log_loss",
    "make_classifier",
    "match_segments",
    "segment_in_hand",
    "segment_region",
    "segment_scene",
]
