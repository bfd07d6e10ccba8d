"""What the 3D scene draws: its layers, their meshcat paths and :class:`SceneOptions`."""

from __future__ import annotations

from dataclasses import dataclass

from pkmtol.design.verification import DISTRIBUTIONS
from pkmtol.exceptions import InvalidRequestError
from pkmtol.present.viewer.colours import BACKGROUND_RGB

#: Root of everything pkmtol draws, below meshcat's ``/meshcat``.
ROOT = "pkmtol"
#: The layers, each its own meshcat path ``pkmtol/<layer>``.
LAYERS = ("robot", "error_spheres", "verification", "reference", "legend", "ground")
#: Glyphs of the error layer: a sphere of radius ∝ σ[Δλ], or the 1σ ellipsoid of P's error.
GLYPHS = ("sphere", "ellipsoid")
#: Default radius of the largest glyph, relative to the smallest distance between two grid points.
GLYPH_SPACING = 0.2


@dataclass(frozen=True)
class SceneOptions:
    """What :func:`build_scene` draws and how.

    Attributes:
        sigma: ``"search"`` (η_c ~ N(0, 1), the paper's Fig. 7) or ``"design"`` (η_c at the
            design-β tolerances) for the error spheres.
        max_sphere_radius_m: Radius of the largest error sphere (or largest semi-axis of an
            ellipsoid) [m] (None: :data:`GLYPH_SPACING` = 0.2 × the smallest distance between two
            grid points, so that the mechanism stays visible between them).
        sphere_opacity: Opacity of the error spheres (1: opaque; the default 0.35 lets the
            mechanism show through).
        glyph: ``"sphere"`` (default) or ``"ellipsoid"``: the 1σ ellipsoid of P's error, from the
            covariance ``L Σ Lᵀ (+ σ_m² N Nᵀ)`` of the compensation mode's maps at each grid point,
            so that the direction of the error shows.
        distribution: Verification distribution drawn (one of ``montecarlo.DISTRIBUTIONS``).
        cloud_radius_m: Drawn radius of the Δλ* sphere of the verification cloud [m]
            (magnification = ``cloud_radius_m / Δλ*``).
        cloud_samples: Number of error vectors in the verification cloud.
        show_safe_samples: Show the safe task-space verification samples at first (they are
            always drawn; the viewer's controls toggle them).
        animate: Add the (paused) animation through the task-space grid.
        layers: Layers to draw (subset of :data:`LAYERS`).
        camera: Set the default camera to frame the mechanism.
        background_rgb: Background colour (None: meshcat's default gradient).
        seed: Random seed of the verification cloud.

    """

    sigma: str = "search"
    max_sphere_radius_m: float | None = None
    distribution: str = "gaussian"
    sphere_opacity: float = 0.35
    glyph: str = "sphere"
    cloud_radius_m: float = 0.15
    cloud_samples: int = 2000
    show_safe_samples: bool = False
    animate: bool = True
    layers: tuple[str, ...] = LAYERS
    camera: bool = True
    background_rgb: tuple[float, float, float] | None = BACKGROUND_RGB
    seed: int = 0

    def __post_init__(self) -> None:
        if self.sigma not in ("search", "design"):
            raise InvalidRequestError(f"sigma must be 'search' or 'design', got {self.sigma!r}")
        if self.distribution not in DISTRIBUTIONS:
            raise InvalidRequestError(
                f"distribution must be one of {', '.join(DISTRIBUTIONS)}, got {self.distribution!r}"
            )
        unknown = set(self.layers) - set(LAYERS)
        if unknown:
            raise InvalidRequestError(f"unknown layers {sorted(unknown)}; choose from {', '.join(LAYERS)}")
        if self.glyph not in GLYPHS:
            raise InvalidRequestError(f"glyph must be one of {', '.join(GLYPHS)}, got {self.glyph!r}")
        if not 0 < self.sphere_opacity <= 1:
            raise InvalidRequestError(f"sphere_opacity must be in (0, 1], got {self.sphere_opacity!r}")
        if self.max_sphere_radius_m is not None and not self.max_sphere_radius_m > 0:
            raise InvalidRequestError("max_sphere_radius_m must be > 0")
        if not self.cloud_radius_m > 0 or self.cloud_samples < 1:
            raise InvalidRequestError("cloud_radius_m must be > 0 and cloud_samples ≥ 1")
