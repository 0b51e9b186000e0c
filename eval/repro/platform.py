"""What bit-exact results depend on, read off the running platform (``ipbench check``)."""

from __future__ import annotations

import os
import platform
from pathlib import Path

__all__ = ["platform_info"]

_CPU_FLAGS = ("sse4_2", "avx", "fma", "avx2", "avx512f", "avx512vl", "avx512_fp16", "amx_tile")
"""The instruction-set flags that decide which kernels numpy, OpenBLAS, OpenCV, numba and
Mesa dispatch to."""


def _cpuinfo() -> tuple[str, list[str]]:
    """The first CPU's model name and which of :data:`_CPU_FLAGS` it has (Linux)."""
    fields: dict[str, str] = {}
    path = Path("/proc/cpuinfo")
    for line in path.read_text().splitlines() if path.exists() else []:
        key, _, value = line.partition(":")
        fields.setdefault(key.strip(), value.strip())
    flags = fields.get("flags", "").split()
    return fields.get("model name", platform.processor() or "unknown"), [
        f for f in _CPU_FLAGS if f in flags
    ]


def _version(module: str) -> str:
    try:
        return str(__import__(module).__version__)
    except Exception:  # noqa: BLE001 - a missing or broken library is reported, not fatal
        return "missing"


def _gl_renderer() -> str:
    """The OpenGL renderer and version (e.g. Mesa llvmpipe) of the MuJoCo backend."""
    try:
        import mujoco
        from OpenGL import GL

        ctx = mujoco.GLContext(16, 16)
        try:
            ctx.make_current()
            return " / ".join(GL.glGetString(k).decode() for k in (GL.GL_RENDERER, GL.GL_VERSION))
        finally:
            ctx.free()
    except Exception as err:  # noqa: BLE001
        return f"unknown ({type(err).__name__})"


def platform_info() -> dict[str, object]:
    """What bit-exact results depend on: CPU model and instruction-set flags, the kernels the
    libraries dispatch to (BLAS, numpy SIMD, numba's LLVM target), library versions, libc,
    the OpenGL renderer and ``MUJOCO_GL``."""
    from importlib.metadata import PackageNotFoundError, version

    cpu, flags = _cpuinfo()
    info: dict[str, object] = {
        "cpu": cpu,
        "cpu_flags": flags,
        "cores": os.cpu_count(),
        "machine": platform.machine(),
        "system": f"{platform.system()} {platform.release()}",
        "libc": " ".join(platform.libc_ver()),
        "python": platform.python_version(),
    }
    try:
        info["ipbench"] = version("ipbench")
    except PackageNotFoundError:
        info["ipbench"] = "unknown"
    for name, module in (
        ("numpy", "numpy"),
        ("scipy", "scipy"),
        ("mujoco", "mujoco"),
        ("opencv", "cv2"),
        ("numba", "numba"),
        ("open3d", "open3d"),
        ("scikit-learn", "sklearn"),
        ("gymnasium", "gymnasium"),
    ):
        info[name] = _version(module)
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__

        info["numpy_simd"] = [f for f in __cpu_dispatch__ if __cpu_features__.get(f)]
    except ImportError:
        info["numpy_simd"] = "unknown"
    try:
        from threadpoolctl import threadpool_info

        info["blas"] = sorted(
            f"{p.get('internal_api')} {p.get('version')} {p.get('architecture')} "
            f"({Path(p['filepath']).parent.name})"
            for p in threadpool_info()
            if p.get("user_api") == "blas"
        )
    except Exception:  # noqa: BLE001
        info["blas"] = "unknown"
    try:
        import llvmlite.binding as llvm

        info["numba_cpu"] = llvm.get_host_cpu_name()
    except Exception:  # noqa: BLE001
        info["numba_cpu"] = "unknown"
    info["mujoco_gl"] = os.environ.get("MUJOCO_GL", "")
    info["gl"] = _gl_renderer()
    return info
