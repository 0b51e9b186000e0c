"""Sorting policies: random sorting, GP-IPM (in hand / in the inspection area), SVM-IPM,
deep-IPM (the GP-IPM loop on a PointNet deep ensemble's confidences), the two inspection
references (``oracle-inspect``, ``random-inspect@P``), the oracle, and the scripted
ground-truth sorter of the demo.

:func:`make_policy` builds one by name from the trained perception models. A confidence-driven
policy (:data:`INTERACTIVE`) runs at its validated threshold under its plain name and at a
threshold ``T`` of the user's as ``name@T`` (``gp-ipm@0.8``); ``random-inspect@P`` inspects a
fraction ``P`` of the objects (:func:`split_policy_name`). A policy of the user's own is named
``module:attribute`` (``mypkg.policies:MyPolicy``, :mod:`ipbench.policies.custom`): a plain
policy, with no validated threshold, that never reads the ground truth.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from ipbench.envs.sorting import COMMANDS
from ipbench.perception.features import DEFAULT_FEATURES, FeatureConfig
from ipbench.perception.model import PerceptionModel
from ipbench.perception.segmentation import DEFAULT_SEGMENTATION, SegmentationConfig
from ipbench.policies.base import Decision, NothingToSort, Policy, PolicyError
from ipbench.policies.custom import (
    check_policy_reference,
    is_reference,
    make_custom_policy,
    split_reference,
)
from ipbench.policies.fusion import FUSIONS
from ipbench.policies.inspection_references import OracleInspectSorter, RandomInspectSorter
from ipbench.policies.interactive import InteractiveConfig, InteractiveSorter
from ipbench.policies.oracle import OracleSorter
from ipbench.policies.perceiver import Detection, Perceiver
from ipbench.policies.random_sorting import RandomSorter
from ipbench.references import ReferenceLoadError

if TYPE_CHECKING:  # torch is an optional extra: only deep-ipm's runs import it
    from ipbench.perception.pointnet import PointNetEnsemble

__all__ = [
    "EVAL_CAMERAS",
    "FUSIONS",
    "INSPECTING",
    "INTERACTIVE",
    "POLICIES",
    "POLICY_VERSION",
    "Decision",
    "Detection",
    "NothingToSort",
    "Policy",
    "PolicyError",
    "PolicyModels",
    "READS_INFO",
    "check_policy_name",
    "make_policy",
    "policy_classifier",
    "split_policy_name",
]

POLICIES: tuple[str, ...] = (
    "random",
    "gp-ipm",
    "gp-ipm-area",
    "svm-ipm",
    "deep-ipm",
    "oracle-inspect",
    "random-inspect",
    "oracle",
    "oracle-scene",
)
"""Policy names of the benchmark (``random-inspect`` only with its fraction,
``random-inspect@P``)."""
POLICY_VERSION = 3
"""Version of what the policies do with an observation (perception, grasp planning, decision
rules), for every env version: part of an evaluation run's fingerprint and of its cached
threshold evidence, so a run or a cache from other policy code is never mixed with this one's.
2: grasp planning with the palm's volume, short objects held with the pads under their top,
short round objects centred on their rim circle. 3: area inspection (``gp-ipm-area``) aims
every command after the first at the object where the area view shows it (its grasp planned
there), not at its old place on the table, which a failed re-pick from the area grasped."""
READS_INFO: frozenset[str] = frozenset({"oracle", "oracle-scene", "oracle-inspect"})
"""The policies that read ``info`` (ground truth): ``act(observation, info)``."""
EVAL_CAMERAS: tuple[str, ...] = ("wrist",)
"""The cameras the policies of :data:`POLICIES` read (``observation["wrist_*"]`` and ``qpos``;
the oracle also ``info["wrist_mask"]``; none reads the head's stereo pair): what the
evaluation and its capture rigs ask the environment to render
(``gym.make(env_id, cameras=EVAL_CAMERAS)``, see :data:`ipbench.envs.sorting_config.CAMERAS`)."""
INTERACTIVE: dict[str, tuple[str, str]] = {
    "gp-ipm": ("gp", "hand"),
    "gp-ipm-area": ("gp", "area"),
    "svm-ipm": ("svm", "hand"),
    "deep-ipm": ("pointnet_ensemble", "hand"),
}
"""The interactive policies: name -> (classifier, inspection mode, see
:data:`~ipbench.policies.interactive.INSPECTIONS`)."""
INSPECTING: dict[str, tuple[str, str]] = {
    **INTERACTIVE,
    "oracle-inspect": ("gp", "hand"),
    "random-inspect": ("gp", "hand"),
}
"""Every policy that inspects: name -> (classifier, inspection mode); the two references run
the GP-IPM loop with the GP's labels."""


def split_policy_name(name: str) -> tuple[str, float | None]:
    """``"gp-ipm@0.8"`` -> ``("gp-ipm", 0.8)``; a plain name or a ``module:attribute``
    reference -> ``(name, None)`` (a reference's form is checked, nothing imported). Raises
    :class:`PolicyError` for a name that is not one of :data:`POLICIES` nor a reference, an
    ``@`` on a policy that takes no value, a value outside [0, 1], or ``random-inspect``
    without its fraction."""
    if is_reference(name):  # the user's own policy, module:attribute (form only: no import)
        if "@" in name:
            raise PolicyError(
                f"{name!r}: a policy of your own takes no @value (thresholds and fractions "
                f"go with the built-in {', '.join((*INTERACTIVE, 'random-inspect'))})"
            )
        try:
            split_reference(name, "policy", "mypkg.policies:MyPolicy")
        except ReferenceLoadError as err:
            raise PolicyError(str(err)) from err
        return name, None
    base, at, value = name.partition("@")
    if base not in POLICIES:
        raise PolicyError(
            f"unknown policy {name!r}; valid: {', '.join(POLICIES)}, or a policy of your own "
            "as module:attribute (e.g. mypkg.policies:MyPolicy, see docs/custom.md)"
        )
    takes = (*INTERACTIVE, "random-inspect")
    if not at:
        if base == "random-inspect":
            raise PolicyError(
                "random-inspect needs the fraction of objects it inspects: random-inspect@P, "
                "P in [0, 1] (e.g. random-inspect@0.3)"
            )
        return base, None
    if base not in takes:
        raise PolicyError(
            f"policy {base!r} takes no @value; thresholds (name@T) go with "
            f"{', '.join(INTERACTIVE)}, fractions with random-inspect@P"
        )
    try:
        number = float(value)
    except ValueError:
        number = float("nan")
    if not 0.0 <= number <= 1.0:
        raise PolicyError(
            f"{name!r}: the value after @ must be a number in [0, 1], e.g. {base}@0.5"
        )
    return base, number


def check_policy_name(name: str) -> str:
    """``name`` if it names a policy (:func:`split_policy_name`; a ``module:attribute``
    reference is imported and its protocol checked, :mod:`ipbench.policies.custom`), else
    :class:`PolicyError`."""
    split_policy_name(name)
    if is_reference(name):
        try:
            check_policy_reference(name)
        except ReferenceLoadError as err:
            raise PolicyError(str(err)) from err
    return name


def policy_classifier(name: str) -> tuple[str, str] | None:
    """(classifier, inspection mode) of an inspecting policy (``name@T`` included), else None."""
    return INSPECTING.get(split_policy_name(name)[0])


@dataclass(frozen=True)
class PolicyModels:
    """What the policies perceive with.

    ``gp``/``svm``: trained models for views of the table (``svm`` only needed by
    ``svm-ipm``; ``pointnet_ensemble`` by ``deep-ipm``: a
    :class:`~ipbench.perception.pointnet.PointNetEnsemble` on the segments' points);
    ``gp_hand``/``svm_hand``/``pointnet_ensemble_hand``: the same classifiers trained on in-hand
    views, for in-hand inspections (None: the table model classifies those too); ``thresholds``: the
    validated confidence threshold per classifier (``{"gp": 0.7, "svm": 0.8}``);
    ``inspection_area``: (3,) centre of the inspection area (world, m).
    """

    gp: PerceptionModel
    inspection_area: tuple[float, float, float]
    thresholds: dict[str, float]
    svm: PerceptionModel | None = None
    gp_hand: PerceptionModel | None = None
    svm_hand: PerceptionModel | None = None
    pointnet_ensemble: PointNetEnsemble | None = None
    pointnet_ensemble_hand: PointNetEnsemble | None = None
    segmentation: SegmentationConfig = DEFAULT_SEGMENTATION
    features: FeatureConfig = DEFAULT_FEATURES


def make_policy(
    name: str,
    models: PolicyModels,
    n_views: int = 3,
    fusion: str = "majority",
    commands: tuple[str, ...] = COMMANDS,
) -> Policy:
    """The policy ``name`` (one of :data:`POLICIES`, or a ``module:attribute`` reference built
    as ``attribute(perceiver, name)`` with the GP's perceiver) for an env whose
    ``action["command"]`` values mean ``commands`` (``env.unwrapped.commands``; the oracle
    picks first where it can, see :mod:`ipbench.policies.oracle`)."""

    def perceiver(model: PerceptionModel | PointNetEnsemble | None, what: str) -> Perceiver:
        if model is None:
            raise PolicyError(f"policy {name!r} needs a trained {what} model (PolicyModels.{what})")
        return Perceiver(
            model,
            models.inspection_area,
            models.segmentation,
            models.features,
            hand_model=getattr(models, f"{what}_hand"),
        )

    base, value = split_policy_name(name)
    if is_reference(base):
        try:
            return make_custom_policy(base, perceiver(models.gp, "gp"))
        except ReferenceLoadError as err:
            raise PolicyError(str(err)) from err

    def config(classifier: str, inspection: str, threshold: float | None) -> InteractiveConfig:
        if threshold is None:
            if classifier not in models.thresholds:
                raise PolicyError(f"policy {name!r} needs thresholds[{classifier!r}]")
            threshold = models.thresholds[classifier]
        return InteractiveConfig(
            threshold=threshold, inspection=inspection, n_views=n_views, fusion=fusion
        )

    if base == "random":
        return RandomSorter(perceiver(models.gp, "gp"), name)
    if base in ("oracle", "oracle-scene"):
        return OracleSorter(perceiver(models.gp, "gp"), name, name == "oracle", commands)
    classifier, inspection = INSPECTING[base]
    if base == "oracle-inspect":  # the threshold is never read: the truth decides
        return OracleInspectSorter(
            perceiver(models.gp, "gp"), config(classifier, inspection, 1.0), name
        )
    if base == "random-inspect":
        return RandomInspectSorter(
            perceiver(models.gp, "gp"), value, config(classifier, inspection, 1.0), name
        )
    return InteractiveSorter(
        perceiver(getattr(models, classifier), classifier),
        config(classifier, inspection, value),
        name,
    )
