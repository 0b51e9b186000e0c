"""The simulated CloPeMa work cell as Gymnasium environments.

Importing this package registers the environments::

    import gymnasium as gym
    import ipbench.envs  # noqa: F401  (registers the ids)

    env = gym.make("ipbench/Sorting-v1", scene="cluttered", render_mode="rgb_array")

``ipbench/Sorting-v1`` takes the scene as a keyword (``"uncluttered"`` or ``"cluttered"``);
the standard scenes are also registered as their own ids. A released id never changes
behaviour: a change bumps the version. ``-v0`` ids keep the first manipulation (fully opened
jaws, blind descents; see :data:`ipbench.envs.sorting.V0`).
"""

from gymnasium.envs.registration import register

from ipbench.envs.sorting import V0

__all__ = ["ENV_IDS", "LATEST"]

LATEST = "ipbench/Sorting-v1"
"""The id the benchmark runs."""

ENV_IDS: dict[str, dict] = {
    "ipbench/Sorting-v0": dict(V0),
    "ipbench/SortingUncluttered-v0": {"scene": "uncluttered", **V0},
    "ipbench/SortingCluttered-v0": {"scene": "cluttered", **V0},
    "ipbench/Sorting-v1": {},
    "ipbench/SortingUncluttered-v1": {"scene": "uncluttered"},
    "ipbench/SortingCluttered-v1": {"scene": "cluttered"},
}
"""Every registered id and the keyword arguments it fixes."""

for _id, _kwargs in ENV_IDS.items():
    register(id=_id, entry_point="ipbench.envs.sorting:SortingEnv", kwargs=_kwargs)
