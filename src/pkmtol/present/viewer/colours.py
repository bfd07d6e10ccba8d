"""Colours of the 3D scene: viridis without matplotlib, and the fixed colours of each layer."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

#: Documented API of this module (the other names serve the scene's own modules).
__all__ = ["viridis"]

# viridis at 9 equally spaced stops (matplotlib's table; no matplotlib needed here)
VIRIDIS = np.array(
    [
        (0.267, 0.005, 0.329),
        (0.279, 0.175, 0.483),
        (0.230, 0.322, 0.546),
        (0.173, 0.449, 0.558),
        (0.128, 0.567, 0.551),
        (0.158, 0.684, 0.502),
        (0.369, 0.789, 0.383),
        (0.678, 0.864, 0.190),
        (0.993, 0.906, 0.144),
    ]
)

SAFE_RGB = (0.10, 0.65, 0.25)
FAILED_RGB = (0.85, 0.10, 0.10)
P_RGB = (0.85, 0.0, 0.85)
#: The limbs' links, joint frame to joint frame (steel blue: apart from the URDF's own colours).
LINK_RGB = (0.20, 0.33, 0.60)
BACKGROUND_RGB = (1.0, 1.0, 1.0)
GROUND_RGB = (0.62, 0.62, 0.62)


def viridis(t: np.ndarray) -> np.ndarray:
    """Viridis colours for values ``t`` in [0, 1], shape (..., 3) RGB in [0, 1]."""
    t = np.clip(np.asarray(t, dtype=float), 0.0, 1.0)
    x = np.linspace(0.0, 1.0, len(VIRIDIS))
    return np.stack([np.interp(t, x, VIRIDIS[:, c]) for c in range(3)], axis=-1)


def hex_colour(rgb: Sequence[float]) -> int:
    """``0xRRGGBB`` of an RGB triple in [0, 1] (meshcat's colour format)."""
    r, g, b = (int(round(255 * float(np.clip(c, 0.0, 1.0)))) for c in rgb[:3])
    return (r << 16) | (g << 8) | b
