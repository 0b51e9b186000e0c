"""A foveated camera: the whole field at low resolution, full resolution around the optical axis.

An active eye exists because it cannot process its whole field at full resolution at once
(thesis ch. 3, after Aloimonos et al. 1988 and Ballard 1991): where it looks decides what it
sees in detail. :func:`foveate` turns one full-resolution image (H, W) into the two images a
foveated observation carries:

* the **periphery**: the whole field, downsampled ``factor`` times in each direction by
  averaging each ``factor`` x ``factor`` block (``cv2.INTER_AREA``, exact block means when
  ``factor`` divides H and W), (H/f, W/f);
* the **fovea**: the central window of (H/f, W/f) pixels at full resolution, i.e. the central
  1/f of the field's width and height (:func:`fovea_window`).

Both have the same pixel count, so the detector's cost per image is that of one image of
(H/f, W/f); at the thesis' 4928x3264 Nikon D5100 frames and ``factor = 4`` each is 1232x816.
Each image comes with its own intrinsics: the periphery's K is the full K scaled by 1/f
(:func:`scale_intrinsics`, pixel centres at integer coordinates as
:func:`~ipbench.envs.sensors.cameras.intrinsics`), the fovea's is the full K with its principal
point moved by the window's corner. A point's pixel in either image therefore follows from its
camera-frame direction alone; :func:`fovea_to_periphery` maps fovea pixels into the periphery.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ipbench.envs.sensors.cameras import SensorError

__all__ = ["Foveated", "foveate", "fovea_to_periphery", "fovea_window", "scale_intrinsics"]


def scale_intrinsics(K: np.ndarray, scale: float) -> np.ndarray:  # noqa: N803
    """K (3, 3) of the same camera with its image scaled by ``scale`` (pixel centres at integer
    coordinates: a pixel ``u`` becomes ``(u + 0.5) * scale - 0.5``)."""
    out = np.array(K, dtype=float, copy=True)
    out[:2, :2] *= scale
    out[:2, 2] = (out[:2, 2] + 0.5) * scale - 0.5
    return out


def fovea_window(height: int, width: int, factor: int) -> tuple[int, int, int, int]:
    """(row0, col0, rows, cols): the fovea of a (height, width) image, its central 1/factor of
    each side. ``factor`` must divide both sides and leave an even border (a centred window)."""
    if not (isinstance(factor, (int, np.integer)) and factor >= 2):
        raise SensorError(f"fovea factor {factor!r}; valid: an int >= 2")
    rows, cols = height // factor, width // factor
    if (
        rows * factor != height
        or cols * factor != width
        or (height - rows) % 2
        or (width - cols) % 2
    ):
        raise SensorError(
            f"a {height}x{width} image has no centred 1/{factor} fovea; valid: height and width"
            f" divisible by {factor}, with an even border (e.g. 3264x4928 with factor 4)"
        )
    return (height - rows) // 2, (width - cols) // 2, rows, cols


@dataclass(frozen=True, eq=False)
class Foveated:
    """The two images of a foveated camera (module docstring).

    Attributes
    ----------
    periphery : (H/f, W/f, ...) the whole field, block means.
    periphery_K : (3, 3) its intrinsics, px.
    fovea : (H/f, W/f, ...) the central window at full resolution.
    fovea_K : (3, 3) its intrinsics, px.
    """

    periphery: np.ndarray
    periphery_K: np.ndarray  # noqa: N815
    fovea: np.ndarray
    fovea_K: np.ndarray  # noqa: N815


def foveate(image: np.ndarray, K: np.ndarray, factor: int) -> Foveated:  # noqa: N803
    """Periphery and fovea of a full-resolution ``image`` (H, W[, C]) with intrinsics ``K``."""
    h, w = image.shape[:2]
    r0, c0, rows, cols = fovea_window(h, w, factor)
    periphery = cv2.resize(image, (cols, rows), interpolation=cv2.INTER_AREA)
    fovea = np.ascontiguousarray(image[r0 : r0 + rows, c0 : c0 + cols])
    fovea_K = np.array(K, dtype=float, copy=True)  # noqa: N806
    fovea_K[0, 2] -= c0
    fovea_K[1, 2] -= r0
    return Foveated(periphery, scale_intrinsics(K, 1.0 / factor), fovea, fovea_K)


def fovea_to_periphery(
    xy: np.ndarray,
    fovea_K: np.ndarray,  # noqa: N803
    periphery_K: np.ndarray,  # noqa: N803
) -> np.ndarray:
    """(N, 2) fovea pixels -> the same directions' pixels in the periphery (both K of one
    camera: same rotation, no skew)."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    normalised = (xy - fovea_K[:2, 2]) / np.diag(fovea_K)[:2]
    return normalised * np.diag(periphery_K)[:2] + periphery_K[:2, 2]
