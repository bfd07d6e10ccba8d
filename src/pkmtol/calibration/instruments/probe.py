"""``probe``: a touch probe at the tool point touching the spheres of an artifact of known size.

The artifact is a rigid set of spheres (a ball plate, a 3D ball artifact) whose centres ``s_j`` in
the artifact's frame and whose *effective* radius ``R`` (sphere radius + stylus-tip radius) are
known from its certificate. It is set up at an unknown pose ``A = A_ref · exp6(α)`` in K: the 6
nuisance parameters ``α`` are identified with the machine (as a tracker's frame, :mod:`.frame`,
so a global rigid motion of the machine stays unidentified). At a touch the probe triggers where
the tip centre P lies on the sphere: the actuator readings at the trigger satisfy
``‖P(u) − A s_j‖ = R``; the value of a pose is ``d = ‖P − A s_j‖``, and the residual of a real
touch is ``R − d``. With ``u = (P − A s_j)/d``, per unit platform twist ``dd = uᵀ [I, −[R b]×] $``
and per unit ``α``: ``dd = −uᵀ R_A [I, −[s_j]×] J_r(α) dα``. Noise: σ per touch along the normal
(default 1 µm: a touch-trigger probe's unidirectional repeatability is 0.25–1 µm 2σ, plus the
machine's trigger lag).

The plan chooses touches among approach directions: ``approach_directions`` directions spread over
the upper hemisphere of every sphere (the stylus comes from above or the side), P at
``A s_j + R n``. Default artifact: spheres at the task space's axis and four points at half its
radius, at three heights (:func:`~pkmtol.calibration.instruments.default_centres`). In a simulation
the probe reads the distance at the planned commands; data from a real probe gives the trigger
readings and the known radius.

CSV: ``pose,<actuated joints>…,station`` (the readings at the trigger, the sphere's index), one row
per touch (:mod:`pkmtol.calibration.instrument_files`).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import pinocchio as pin

from pkmtol.calibration.instruments.base import Candidates, Instrument, lever_rows, skew
from pkmtol.calibration.instruments.frame import rigid_fit
from pkmtol.exceptions import InvalidRequestError


class TouchSurface(Protocol):
    """What :func:`trigger_commands` needs of a probe: its radius and its surface's distance."""

    radius_m: float

    def surface(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(d (N,), its gradient in P (N, 3))`` at platform poses (see :meth:`SphereProbe.surface`)."""
        ...


#: Names of the artifact pose's six parameters (translation then rotation, artifact frame).
POSE_NAMES = ("artifact.dx", "artifact.dy", "artifact.dz", "artifact.rx", "artifact.ry", "artifact.rz")
#: σ of a simulated set-up error of the artifact: translation [m], rotation [rad].
SETUP_DRAW = (5e-4, 1e-3)


def hemisphere(count: int, min_elevation_rad: float = 0.0) -> np.ndarray:
    """``count`` unit vectors spread over the upper hemisphere (Fibonacci spiral), shape (count, 3)."""
    i = np.arange(count) + 0.5
    z_low = np.sin(min_elevation_rad)
    z = 1.0 - i / count * (1.0 - z_low)
    r = np.sqrt(np.clip(1.0 - z**2, 0.0, None))
    phi = np.pi * (1.0 + np.sqrt(5.0)) * i
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def touch_rows(normal: np.ndarray, rotation: np.ndarray, point_m: np.ndarray) -> np.ndarray:
    """A touch's value per unit platform twist: ``nᵀ [I, −[R b]×]`` per pose, (N, 1, 6).

    Args:
        normal: Shape (N, 3): the surface's gradient at the touch, in K (unit).
        rotation: Shape (N, 3, 3): the platform's orientation.
        point_m: Shape (3,): the probe tip's centre in the platform frame [m].
    """
    return np.einsum("ka,kab->kb", normal, lever_rows(rotation, point_m))[:, None, :]


class SphereProbe(Instrument):
    """Touches on the spheres of an artifact of effective radius ``radius_m``.

    Args:
        point_m: Shape (3,): the stylus tip centre in the platform frame (P) [m].
        centres_m: Shape (S, 3): the spheres' centres at the artifact's nominal pose, in K [m].
        radius_m: Effective radius (sphere + stylus tip) [m].
        directions: Candidate approach directions per sphere.
        noise_m: σ per touch [m].
        reference: The artifact pose ``A_ref`` the nuisance is relative to (default identity).

    Raises:
        InvalidRequestError: no sphere, a radius ≤ 0, or fewer than 4 directions.
    """

    name = "probe"
    value_names = ("d",)
    value_units = ("m",)
    refresh_rows = True
    nuisance_names = POSE_NAMES
    nuisance_units = ("m", "m", "m", "rad", "rad", "rad")

    def __init__(
        self,
        point_m: np.ndarray,
        centres_m: np.ndarray,
        radius_m: float,
        directions: int,
        noise_m: float,
        reference: pin.SE3 | None = None,
    ) -> None:
        if not radius_m > 0 or not np.isfinite(radius_m):
            raise InvalidRequestError(f"the artifact's radius must be > 0, got {radius_m!r} m")
        if directions < 4:
            raise InvalidRequestError(f"a sphere needs ≥ 4 approach directions, got {directions}")
        self.point_m = np.asarray(point_m, dtype=float).reshape(3)
        self.centres_m = np.asarray(centres_m, dtype=float).reshape(-1, 3)
        if not len(self.centres_m) or not np.all(np.isfinite(self.centres_m)):
            raise InvalidRequestError(
                "the probe needs at least one sphere centre [x, y, z] in metres; "
                "give [calibration] stations_m"
            )
        self.radius_m = float(radius_m)
        self.direction_count = int(directions)
        self.directions = hemisphere(int(directions), np.deg2rad(10.0))
        self.noise = np.array([float(noise_m)])
        self.nuisance_scale = np.array([SETUP_DRAW[0]] * 3 + [SETUP_DRAW[1]] * 3)
        self.reference = pin.SE3.Identity() if reference is None else reference

    def pose(self, alpha: np.ndarray) -> pin.SE3:
        """The artifact's pose ``A = A_ref · exp6(α)`` (artifact → K)."""
        return self.reference * pin.exp6(pin.Motion(np.asarray(alpha, dtype=float)))

    def _offsets(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, alpha: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, pin.SE3]:
        st = np.asarray(stations, dtype=int)
        if st.size and (st.min() < 0 or st.max() >= len(self.centres_m)):
            raise InvalidRequestError(
                f"sphere {int(st.max())} does not exist: the artifact has {len(self.centres_m)} "
                "([calibration] stations_m)"
            )
        A = self.pose(alpha)
        local = (self.centres_m - self.reference.translation) @ self.reference.rotation  # s_j
        centres = local @ A.rotation.T + A.translation
        point = origin + np.einsum("kab,b->ka", rotation, self.point_m)
        return point - centres[st], local[st], A

    def measure(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> np.ndarray:
        """``‖P − A s_j‖`` per pose, (N, 1) [m]."""
        r, _, _ = self._offsets(origin, rotation, stations, nuisance)
        return np.linalg.norm(r, axis=1)[:, None]

    def surface(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(d (N,), its gradient in P (N, 3))``: the distance to the centre and the unit ``u``."""
        r, _, _ = self._offsets(origin, rotation, stations, nuisance)
        d = np.linalg.norm(r, axis=1)
        return d, r / d[:, None]

    def twist_rows(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> np.ndarray:
        """``uᵀ [I, −[R b]×]`` per pose, (N, 1, 6)."""
        return touch_rows(self.surface(origin, rotation, stations, nuisance)[1], rotation, self.point_m)

    def nuisance_rows(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> np.ndarray:
        """``−uᵀ R_A [I, −[s_j]×] J_r(α)`` per pose, (N, 1, 6)."""
        r, s, A = self._offsets(origin, rotation, stations, nuisance)
        u = r / np.linalg.norm(r, axis=1)[:, None]
        moving = np.zeros((len(s), 3, 6))
        moving[:, :, :3] = np.eye(3)
        moving[:, :, 3:] = -skew(s)
        jr = np.asarray(pin.Jexp6(pin.Motion(np.asarray(nuisance, dtype=float))))
        rows = -np.einsum("ka,ab,kbc->kc", u, A.rotation, moving) @ jr
        return rows[:, None, :]

    def start(
        self, measured: np.ndarray, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray
    ) -> tuple[Instrument, np.ndarray]:
        """Place the artifact where the data puts it: a sphere fit per touched sphere, then a rigid fit.

        A set-up error of a millimetre is large beside a 14 mm sphere (the touch directions move by
        several degrees), so the linearisation starts at the artifact pose fitted to the touches
        (each sphere with ≥ 4 touches: its centre by Gauss–Newton on ``‖P − c‖ = d``; ≥ 3 such
        spheres not on a line: the rigid fit, else the mean translation).
        """
        st = np.asarray(stations, dtype=int)
        d = np.asarray(measured, dtype=float).reshape(-1)
        points = origin + np.einsum("kab,b->ka", rotation, self.point_m)
        nominal, fitted = [], []
        for s in np.unique(st):
            k = st == s
            if k.sum() < 4:
                continue
            c = self.centres_m[s].copy()
            for _ in range(20):
                r = points[k] - c
                dist = np.linalg.norm(r, axis=1)
                J = -r / dist[:, None]
                step = np.linalg.lstsq(J, d[k] - dist, rcond=None)[0]
                c += step
                if np.max(np.abs(step)) < 1e-13:
                    break
            nominal.append(self.centres_m[s])
            fitted.append(c)
        if not fitted:
            return self, np.zeros(6)
        a, b = np.array(nominal), np.array(fitted)
        spread = np.linalg.svd(a - a.mean(axis=0), compute_uv=False) if len(a) >= 3 else np.zeros(2)
        if len(a) >= 3 and spread[1] > 1e-6:
            fit = rigid_fit(a, b)
        else:
            fit = pin.SE3(np.eye(3), (b - a).mean(axis=0))
        moved = SphereProbe(
            self.point_m,
            self.centres_m,
            self.radius_m,
            self.direction_count,
            float(self.noise[0]),
            fit * self.reference,
        )
        moved.centres_m = self.centres_m @ fit.rotation.T + fit.translation
        moved.reference = fit * self.reference
        return moved, np.zeros(6)

    def draw_nuisance(self, rng: np.random.Generator) -> np.ndarray:
        """A set-up error of the artifact: σ 0.5 mm per axis, 1 mrad per rotation."""
        return rng.standard_normal(6) * self.nuisance_scale

    def candidates(self, task_points: np.ndarray, rng: np.random.Generator) -> Candidates:
        """Every sphere's touches: P at ``A_ref s_j + R n`` for each approach direction ``n``."""
        S, D = len(self.centres_m), len(self.directions)
        pts = (self.centres_m[:, None, :] + self.radius_m * self.directions[None, :, :]).reshape(-1, 3)
        stations = np.repeat(np.arange(S), D)
        return Candidates(points_m=pts, stations=stations, groups=np.arange(S * D))


def trigger_commands(
    machine: object,
    probe: TouchSurface,
    commands: np.ndarray,
    q: np.ndarray,
    stations: np.ndarray,
    nuisance: np.ndarray,
    actuation: np.ndarray,
    iterations: int = 8,
) -> np.ndarray:
    """The readings at which a machine's probe triggers on the true artifact (simulated touches).

    From the planned readings, each touch moves P along the surface's normal ``n`` (a sphere's
    radial direction, a face's normal) until the value ``d`` (:meth:`surface`) is the probe's
    ``R`` (Newton along the normal with the nominal command map ``C_k``: ``Δu = −(d − R) C_k⁺ n``).

    Args:
        machine: The true machine (:class:`pkmtol.calibration.machine.Machine`).
        probe: The probe and its artifact (spheres or planes).
        commands: Shape (N, f): planned readings.
        q: Shape (N, Σ nq): joint guesses there.
        stations: Shape (N,): the sphere (face) of each touch.
        nuisance: The artifact's true pose parameters (6,).
        actuation: Shape (N, 3, f): P's motion per command change (``PoseMaps.position_actuation``).
        iterations: Newton steps.

    Returns:
        Shape (N, f): the trigger readings.
    """
    u = np.array(commands, dtype=float)
    pinv = np.linalg.pinv(actuation)  # (N, f, 3)
    for _ in range(iterations):
        sols = machine.forward_many(u, q)  # type: ignore[attr-defined]
        d, n = probe.surface(sols.translation, sols.rotation, stations, nuisance)
        u = u - (d - probe.radius_m)[:, None] * np.einsum("kfa,ka->kf", pinv, n)
        q = sols.q
    return u
