"""What is left of the errors after the controller compensates: tool-point position and platform rotation.

Three compensation modes (DESIGN.md, "Compensation and calibration"), all linear in the error
parameters ``δ`` (n) and, for a real calibration, in the tracker noise ``ν`` (M coordinates):

``ideal``
    the paper's Eq. 25: the actuators are corrected by ``−Λ_a⁻¹ G_a η_a``, which leaves the twist
    ``W⁻ᵀ [0; G_c η_c]`` (``Separation.uncompensated_map``);
``none``
    the traditional method: commands unchanged, twist ``T δ`` (``Separation.twist_map``);
``calibrated``
    a least-squares calibration from tracker measurements (built by
    :func:`pkmtol.calibration.postcal.calibrated_maps`).

Each gives, at every evaluation pose ``k``, the position error of P, ``e_k = L_k δ + N_k ν`` [m],
and the rotation of the platform, ``θ_k = Lr_k δ + Nr_k ν`` [rad] (a rotation vector in K). The
tool axis ``a`` (platform frame) moves by ``θ_k × (R_k a)``; its norm is the tilt: rotation about
the axis itself does not tilt it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pkmtol.error_model.sweep import Sweep
from pkmtol.exceptions import InvalidRequestError

COMPENSATIONS = ("ideal", "calibrated", "none")


@dataclass(frozen=True, eq=False)
class AccuracyMaps:
    """Errors left after compensation at ``m`` poses (``n`` parameters, ``M`` noise coordinates).

    Attributes:
        mode: ``ideal``, ``calibrated`` or ``none``.
        position: Shape (m, 3, n): P's position error per unit parameter [m per m or rad].
        rotation: Shape (m, 3, n): platform rotation vector (in K) per unit parameter [rad per unit].
        position_noise: Shape (m, 3, M): P's position error per unit of tracker noise (M = 0 for
            ``ideal`` and ``none``) [m per m].
        rotation_noise: Shape (m, 3, M): platform rotation per unit of tracker noise [rad per m].
        noise_m: σ_m of each noise coordinate [m] (0 without a calibration).
        rotations: Shape (m, 3, 3): nominal platform orientation at each pose (platform → K).
    """

    mode: str
    position: np.ndarray
    rotation: np.ndarray
    position_noise: np.ndarray
    rotation_noise: np.ndarray
    noise_m: float
    rotations: np.ndarray

    def __len__(self) -> int:
        return int(self.position.shape[0])

    def position_covariance(self, sigma: np.ndarray) -> np.ndarray:
        """Covariance of P's position error for independent ``δ_i ~ N(0, σ_i²)``: (m, 3, 3) [m²].

        ``L diag(σ²) Lᵀ + σ_m² N Nᵀ``; a parameter with ``σ_i = inf`` is held at 0 (free).
        """
        return _covariance(self.position, self.position_noise, sigma, self.noise_m)

    def tilt_maps(self, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The tilt of the tool axis ``axis`` (platform frame, unit vector): ``(map (m,3,n), noise (m,3,M))``.

        Rows: ``θ_k × (R_k a) = −[R_k a]× θ_k``, the displacement of the unit tool axis, whose norm
        is the tilt angle [rad] to first order.
        """
        a = np.asarray(axis, dtype=float)
        a = a / np.linalg.norm(a)
        ak = np.einsum("kij,j->ki", self.rotations, a)
        sk = -skew_batch(ak)
        return np.einsum("kij,kjn->kin", sk, self.rotation), np.einsum(
            "kij,kjn->kin", sk, self.rotation_noise
        )

    def tilt_covariance(self, axis: np.ndarray, sigma: np.ndarray) -> np.ndarray:
        """Covariance of the tool axis's displacement ``θ_k × (R_k a)``: (m, 3, 3) [rad²] (rank 2)."""
        t, tn = self.tilt_maps(axis)
        return _covariance(t, tn, sigma, self.noise_m)

    def subset(self, columns: np.ndarray) -> AccuracyMaps:
        """The same maps restricted to the parameters ``columns`` (the others held at 0)."""
        c = np.asarray(columns, dtype=int)
        return AccuracyMaps(
            mode=self.mode,
            position=self.position[:, :, c],
            rotation=self.rotation[:, :, c],
            position_noise=self.position_noise,
            rotation_noise=self.rotation_noise,
            noise_m=self.noise_m,
            rotations=self.rotations,
        )


def _covariance(L: np.ndarray, N: np.ndarray, sigma: np.ndarray, noise_m: float) -> np.ndarray:
    s = np.asarray(sigma, dtype=float)
    s = np.where(np.isfinite(s), s, 0.0)
    a = L * s[None, None, :]
    cov = a @ np.swapaxes(a, 1, 2)
    if N.shape[2] and noise_m > 0:
        cov = cov + noise_m**2 * (N @ np.swapaxes(N, 1, 2))
    return cov


def skew_batch(v: np.ndarray) -> np.ndarray:
    """``[v]×`` for vectors of shape (..., 3), shape (..., 3, 3)."""
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def mode_maps(grid: Sweep, mode: str) -> AccuracyMaps:
    """The ``ideal`` or ``none`` maps of every pose of a sweep (``calibrated``: see the calibration stage).

    Raises:
        InvalidRequestError: unknown mode, or ``calibrated`` (it needs a calibration plan).
    """
    if mode == "ideal":
        twists = np.array([s.uncompensated_map for s in grid.separations])
        position = grid.J
    elif mode == "none":
        twists = np.array([s.twist_map for s in grid.separations])
        position = grid.J_total
    elif mode == "calibrated":
        raise InvalidRequestError(
            "the calibrated maps need a calibration plan: use pkmtol.calibration.postcal.calibrated_maps"
        )
    else:
        raise InvalidRequestError(f"unknown compensation {mode!r}; use one of {', '.join(COMPENSATIONS)}")
    m = len(grid.poses)
    return AccuracyMaps(
        mode=mode,
        position=np.asarray(position),
        rotation=twists[:, 3:, :],
        position_noise=np.zeros((m, 3, 0)),
        rotation_noise=np.zeros((m, 3, 0)),
        noise_m=0.0,
        rotations=np.array([p.oMp.rotation for p in grid.poses]),
    )
