"""The simulated CloPeMa work cell as Gymnasium environments.

Importing this package registers the environments::

    import gymnasium as gym
    import ipbench.envs  # noqa: F401  (registers the ids)

    env = gym.make("ipbench/Sorting-v0", scene="cluttered", render_mode="rgb_array")

``ipbench/Sorting-v0`` takes the scene as a keyword (``"uncluttered"`` or ``"cluttered"``);
the standard scenes are also registered as their own ids. A released id never changes
behaviour: a change bumps the version.
"""

from gymnasium.envs.registration import register

__all__ = ["ENV_IDS"]

ENV_IDS: dict[str, dict] = {
    "ipbench/Sorting-v0": {},
    "ipbench/SortingUncluttered-v0": {"scene": "uncluttered"},
    "ipbench/SortingCluttered-v0": {"scene": "cluttered"},
}
"""Every registered id and the keyword arguments it fixes."""

for _id, _kwargs in ENV_IDS.items():
    register(id=_id, entry_point="ipbench.envs.sorting:SortingEnv", kwargs=_kwargs)
