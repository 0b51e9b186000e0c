"""Shared test set-up: headless rendering through EGL (Mesa's software renderer)."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
