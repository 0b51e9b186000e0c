"""MJCF models of the CloPeMa work cell and the procedural household objects.

The robot (``motoman/``), the stereo head (``head/``) and the work cell (``scenes/``) are
hand-written MJCF built from primitives with the numbers of the Glasgow CloPeMa robot
description (G. Aragon-Camarasa, ``gerac83/ug_bluerobot``, ``clopema_description``);
:mod:`ipbench.assets.compose` joins them with :class:`mujoco.MjSpec`, and
:mod:`ipbench.assets.objects` generates the household objects.
"""

from pathlib import Path

__all__ = ["ASSETS_DIR"]

ASSETS_DIR: Path = Path(__file__).resolve().parent
"""Folder that holds the MJCF files (shipped as package data)."""
