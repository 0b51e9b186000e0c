"""A sorting policy of the user's own, named ``module:attribute`` (``mypkg.policies:MyPolicy``).

The protocol is what the evaluation's episode loop
(:func:`ipbench.eval.sorting.evaluate.run_episode`) calls::

    policy = MyPolicy(perceiver, name)   # once per episode, in the worker that runs it
    policy.reset(seed)                   # the episode's seed
    obs, info = env.reset(seed=seed)
    while not done:
        action = policy.act(obs, None)   # raise NothingToSort to end the episode early
        ...
        policy.decisions                 # read after every step

``perceiver`` is the :class:`~ipbench.policies.perceiver.Perceiver` the built-in policies see
with (the trained GP on table views, the in-hand GP for objects held up to the camera) and
``name`` the reference as given. ``act`` returns an action of the env's action space
(:func:`~ipbench.policies.base.place_action` builds one); ``info`` is always None: a custom
policy is evaluated on what it perceives, never on the ground truth. ``decisions`` is a list of
:class:`~ipbench.policies.base.Decision`, one appended per object the policy selects; the
evaluation fills in their true categories and scores them. ``detections`` (what the policy
sees now, a list of :class:`~ipbench.policies.perceiver.Detection`) is drawn by ``--video``.
Subclassing :class:`~ipbench.policies.base.SceneSorter` provides all of it but ``act``.
"""

from __future__ import annotations

from ipbench.policies.base import Policy
from ipbench.policies.perceiver import Perceiver
from ipbench.references import (
    DOCS,
    Method,
    ReferenceLoadError,
    check_methods,
    is_reference,
    load_reference,
    split_reference,
)

__all__ = [
    "EXAMPLE",
    "POLICY_METHODS",
    "POLICY_NEEDS",
    "check_policy_reference",
    "is_reference",
    "load_policy",
    "make_custom_policy",
    "split_reference",
]

POLICY_METHODS: tuple[Method, ...] = (
    Method("reset", 1, "reset(seed)"),
    Method("act", 2, "act(observation, info)"),
)
"""The methods the episode loop calls."""
POLICY_NEEDS = (
    "a sorting policy is built as MyPolicy(perceiver, name) and needs reset(seed), "
    "act(observation, info) and a decisions list"
)
_CONSTRUCT = ("perceiver", "name")
EXAMPLE = "mypkg.policies:MyPolicy"


def load_policy(ref: str):
    """The class (or factory) ``ref`` names, checked (:func:`ipbench.references.load_reference`).

    Raises :class:`~ipbench.references.ReferenceLoadError` saying what is missing."""
    return load_reference(ref, "policy", _CONSTRUCT, POLICY_METHODS, POLICY_NEEDS, EXAMPLE)


def check_policy_reference(ref: str) -> str:
    """``ref`` if it names a usable policy (:func:`load_policy`), else
    :class:`~ipbench.references.ReferenceLoadError`."""
    load_policy(ref)
    return ref


def make_custom_policy(ref: str, perceiver: Perceiver) -> Policy:
    """The policy ``ref`` names, built for one run (``ref(perceiver, ref)``) and checked."""
    policy = load_policy(ref)(perceiver, ref)
    check_methods(policy, ref, "policy", POLICY_METHODS, POLICY_NEEDS)
    if not isinstance(getattr(policy, "decisions", None), list):
        raise ReferenceLoadError(
            f"{ref} has no decisions list after it is built; {POLICY_NEEDS}: set "
            f"self.decisions = [] in __init__ (see {DOCS})"
        )
    if not hasattr(policy, "detections"):
        policy.detections = []  # drawn by --video only
    return policy
