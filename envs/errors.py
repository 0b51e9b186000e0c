"""The errors every ipbench environment raises for a misuse of the Gymnasium API.

Both task families (:mod:`ipbench.envs.sorting`, :mod:`ipbench.envs.exploration`) raise these,
and each lists them among its public names: a bad action is an :class:`InvalidActionError`, a
``step()`` or ``render()`` without an episode a :class:`ResetNeededError`. The messages say
what was wrong and what is valid.
"""

from __future__ import annotations

import gymnasium as gym

__all__ = ["InvalidActionError", "ResetNeededError"]


class InvalidActionError(ValueError):
    """An action outside the action space; the message says which field and what is valid."""


class ResetNeededError(RuntimeError, gym.error.ResetNeeded):
    """``step()`` or ``render()`` without an episode: before the first ``reset()`` or after
    ``close()``; the message says to call ``reset()``."""
