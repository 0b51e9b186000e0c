"""The simulated CloPeMa work cell as Gymnasium environments.

Importing this package registers the environments::

    import gymnasium as gym
    import ipbench.envs  # noqa: F401  (registers the ids)

    env = gym.make("ipbench/Sorting-v1", scene="cluttered", render_mode="rgb_array")

``ipbench/Sorting-v1`` takes the scene as a keyword (``"uncluttered"`` or ``"cluttered"``); the
standard scenes are also registered as their own ids. Every id takes ``cameras=`` (the observation
mode: ``("wrist", "head")`` by default, ``("wrist",)`` renders no head images). A released id never
changes behaviour: a change bumps the version. ``-v0`` ids keep the first manipulation (fully opened
jaws, blind descents; see :data:`ipbench.envs.sorting_config.V0`). ``-v2`` ids, the benchmark's
(:data:`LATEST`), add the v2 object catalogue and structured-light depth
(:data:`ipbench.envs.sorting_config.V2`), faster physics, the ``pick`` command, and a third scene,
``"pile"`` (twenty objects piled, some on others; ``ipbench/SortingPile-v2`` or ``scene="pile"``),
which v0/v1 ids refuse. ``-v3`` ids (:data:`V3_IDS`, under development, see
:data:`UNDER_DEVELOPMENT`) model bowls and mugs as a few convex pieces each and print labels upright
(:data:`ipbench.envs.sorting_config.V3`).

``ipbench/Exploration-v0`` (:data:`EXPLORATION_IDS`, thesis ch. 3) is the second task family:
the stereo head explores a table scene and reports the objects it recognises
(:mod:`ipbench.envs.exploration`; ``gym.make("ipbench/Exploration-v0", scene="complex")``).
It is released and frozen: a change of behaviour gets a new version; options whose default
keeps the behaviour, such as ``extrinsics``, may be added. ``ipbench/Exploration-v1``, released
and frozen as well, looks at the thesis' resolution through foveated cameras, with upright
prints (:data:`ipbench.envs.exploration.EXPLORATION_V1`).
:data:`ALL_IDS` lists every registered ipbench id.
"""

import warnings

from gymnasium.envs.registration import register

from ipbench.envs.exploration import EXPLORATION_V1
from ipbench.envs.sorting import V0, V2, V3, SortingConfig

__all__ = [
    "ALL_IDS",
    "ENV_IDS",
    "EXPLORATION_IDS",
    "LATEST",
    "UNDER_DEVELOPMENT",
    "V2_IDS",
    "V3_IDS",
    "EnvIdError",
    "env_config",
    "env_status",
]

LATEST = "ipbench/Sorting-v2"
"""The id the benchmark runs (``ipbench eval`` and ``make eval`` by default)."""

ENV_IDS: dict[str, dict] = {
    "ipbench/Sorting-v0": dict(V0),
    "ipbench/SortingUncluttered-v0": {"scene": "uncluttered", **V0},
    "ipbench/SortingCluttered-v0": {"scene": "cluttered", **V0},
    "ipbench/Sorting-v1": {},
    "ipbench/SortingUncluttered-v1": {"scene": "uncluttered"},
    "ipbench/SortingCluttered-v1": {"scene": "cluttered"},
    "ipbench/Sorting-v2": dict(V2),
    "ipbench/SortingUncluttered-v2": {"scene": "uncluttered", **V2},
    "ipbench/SortingCluttered-v2": {"scene": "cluttered", **V2},
    "ipbench/SortingPile-v2": {"scene": "pile", **V2},
    "ipbench/Sorting-v3": dict(V3),
    "ipbench/SortingUncluttered-v3": {"scene": "uncluttered", **V3},
    "ipbench/SortingCluttered-v3": {"scene": "cluttered", **V3},
    "ipbench/SortingPile-v3": {"scene": "pile", **V3},
}
"""Every registered id and the keyword arguments it fixes."""

V2_IDS: tuple[str, ...] = tuple(i for i in ENV_IDS if i.endswith("-v2"))
"""The v2 ids (released and frozen, as every id not in :data:`UNDER_DEVELOPMENT`)."""

V3_IDS: tuple[str, ...] = tuple(i for i in ENV_IDS if i.endswith("-v3"))
"""The v3 ids (:data:`~ipbench.envs.sorting_config.V3`: convex collision of hollow objects,
upright prints; under development until their headline measurement releases them)."""

EXPLORATION_IDS: dict[str, dict] = {
    "ipbench/Exploration-v0": {},
    "ipbench/Exploration-v1": dict(EXPLORATION_V1),
}
"""The exploration ids (thesis ch. 3) and the keyword arguments each fixes; entry point
:class:`ipbench.envs.exploration.ExplorationEnv`. Not in :data:`ENV_IDS` (Sorting's)."""

ALL_IDS: tuple[str, ...] = (*ENV_IDS, *EXPLORATION_IDS)
"""Every registered ipbench id."""

UNDER_DEVELOPMENT: tuple[str, ...] = V3_IDS
"""Ids whose behaviour may still change until their headline measurement releases them; every
other id is released and frozen (``tests/test_released_ids.py``)."""


class EnvIdError(ValueError):
    """An env id that is not registered; the message lists the registered ones."""


def env_config(env_id: str, **overrides) -> SortingConfig:
    """The :class:`~ipbench.envs.sorting_config.SortingConfig` that
    ``gym.make(env_id, **overrides)`` runs with (what a capture rig or a report needs to know
    about an id). Overrides are checked as ``gym.make`` checks them, e.g. ``cameras=("wrist",)``
    (the observation mode, see :data:`~ipbench.envs.sorting_config.CAMERAS`): a bad value is a
    ``ValueError`` listing the valid ones."""
    if env_id not in ENV_IDS:
        raise EnvIdError(f"unknown env id {env_id!r}; valid: {', '.join(ENV_IDS)}")
    return SortingConfig(**{**ENV_IDS[env_id], **overrides})


def env_status(env_id: str) -> str:
    """``"under development"`` for an id in :data:`UNDER_DEVELOPMENT`, else ``"released"``;
    an unregistered id is an :class:`EnvIdError` listing the registered ones."""
    if env_id not in ALL_IDS:
        raise EnvIdError(f"unknown env id {env_id!r}; valid: {', '.join(ALL_IDS)}")
    return "under development" if env_id in UNDER_DEVELOPMENT else "released"


# Gymnasium calls an id "out of date" once a higher version is registered; v0 to v2 stay
# released and reproducible (v0/v1's results are the thesis reproduction's, v2 is the
# benchmark's while v3 is under development), so no warning.
warnings.filterwarnings("ignore", message=r".*ipbench/\w+-v[012] is out of date")

for _id, _kwargs in ENV_IDS.items():
    register(id=_id, entry_point="ipbench.envs.sorting:SortingEnv", kwargs=_kwargs)

for _id, _kwargs in EXPLORATION_IDS.items():
    register(id=_id, entry_point="ipbench.envs.exploration:ExplorationEnv", kwargs=_kwargs)
