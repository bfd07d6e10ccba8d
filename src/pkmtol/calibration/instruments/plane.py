"""``probe`` on a plane artifact: a touch probe at the tool point touching the flat faces of a block.

The artifact is a rigid block of known size (a granite square, a gauge block, a surface plate):
its flat faces ``j`` pass through points ``s_j`` with outward unit normals ``m_j`` (artifact
frame), known from its certificate. It is set up at an unknown pose ``A = A_ref · exp6(α)`` in K;
the 6 parameters ``α`` are identified with the machine. At a touch the probe triggers where the
stylus tip centre P lies at the tip radius ``r`` from the face: with ``p = A⁻¹ P`` (P in the
artifact frame) the value of a pose is the signed distance ``d = m_jᵀ (p − s_j)``, and the
residual of a real touch is ``r − d`` (a point-to-plane residual). Per unit platform twist
``dd = (R_A m_j)ᵀ [I, −[R b]×] $``; per unit ``α``, ``dd = −[m_jᵀ, (p × m_j)ᵀ] J_r(α) dα``.

**What a plane cannot see.** A face is unchanged by a translation in its plane and by a rotation
about its normal: of its pose, the data fix the normal (2 tilts) and the offset (1). A block's
pose is fixed once three faces with independent normals are touched; with the top face alone (a
surface plate) the artifact's in-plane translation and its rotation about the normal stay
unknown, and so do the machine's
(:func:`~.base.unseen_nuisance` names them; the plan and the calibration print them).

The plan chooses touches among ``touch_points`` points spread over every face (the stylus
approaches along the face's normal; where it touches is what the plan chooses), P at
``A_ref (s_j + r m_j + a u + b v)``. Default artifact (:func:`default_block`): a block on the
task axis, half as wide as the task space, its top face at the top of the task space and its
four side faces over the whole height, tip radius 1 mm. Noise: σ per touch along the normal
(default 1 µm, as the sphere probe).

CSV: as the sphere probe, ``pose,<actuated joints>…,station`` (the readings at the trigger, the
face's index), one row per touch (:mod:`pkmtol.calibration.instrument_files`).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from pkmtol.calibration.instruments.base import Candidates, Instrument
from pkmtol.calibration.instruments.probe import POSE_NAMES, SETUP_DRAW, touch_rows
from pkmtol.exceptions import InvalidRequestError

#: The faces of a block by their outward normal in K (the face it stands on, ``-z``, is not touched).
FACES: dict[str, tuple[float, float, float]] = {
    "+z": (0.0, 0.0, 1.0),
    "+x": (1.0, 0.0, 0.0),
    "-x": (-1.0, 0.0, 0.0),
    "+y": (0.0, 1.0, 0.0),
    "-y": (0.0, -1.0, 0.0),
}
#: What each artifact pose parameter is, for the names of what the data cannot fix.
POSE_MEANING = (
    "translation along the artifact's x",
    "translation along the artifact's y",
    "translation along the artifact's z",
    "rotation about the artifact's x",
    "rotation about the artifact's y",
    "rotation about the artifact's z",
)


def face_grid(count: int) -> np.ndarray:
    """``count`` points (a, b) spread over the square [−0.9, 0.9]² (a Fibonacci lattice), (count, 2)."""
    i = np.arange(count)
    a = np.mod(i * (np.sqrt(5.0) - 1.0) / 2.0 + 0.5, 1.0)
    b = (i + 0.5) / count
    return 1.8 * np.column_stack([a, b]) - 0.9


class PlaneProbe(Instrument):
    """Touches on the flat faces of a block artifact, tip radius ``radius_m``.

    Args:
        point_m: Shape (3,): the stylus tip centre in the platform frame (P) [m].
        centres_m: Shape (F, 3): each face's centre at the artifact's nominal pose, in K [m].
        normals: Shape (F, 3): each face's outward normal in K (normalised here).
        extents_m: Shape (F, 2, 3): each face's two in-plane half-extent vectors in K [m].
        radius_m: The stylus tip's radius [m] (P is this far from the face at the trigger).
        touch_points: Candidate touch points per face.
        noise_m: σ per touch [m].
        reference: The artifact pose ``A_ref`` the nuisance is relative to (default identity).
        face_names: A name per face (default ``face0``, …).

    Raises:
        InvalidRequestError: no face, a normal of zero length, a radius ≤ 0, or fewer than 4 points.
    """

    name = "probe"
    value_names = ("d",)
    value_units = ("m",)
    refresh_rows = True
    nuisance_names = POSE_NAMES
    nuisance_units = ("m", "m", "m", "rad", "rad", "rad")
    nuisance_meanings = POSE_MEANING

    def __init__(
        self,
        point_m: np.ndarray,
        centres_m: np.ndarray,
        normals: np.ndarray,
        extents_m: np.ndarray,
        radius_m: float,
        touch_points: int,
        noise_m: float,
        reference: pin.SE3 | None = None,
        face_names: tuple[str, ...] | None = None,
    ) -> None:
        if not radius_m > 0 or not np.isfinite(radius_m):
            raise InvalidRequestError(f"the stylus tip's radius must be > 0, got {radius_m!r} m")
        if touch_points < 4:
            raise InvalidRequestError(f"a face needs ≥ 4 touch points, got {touch_points}")
        self.point_m = np.asarray(point_m, dtype=float).reshape(3)
        self.centres_m = np.asarray(centres_m, dtype=float).reshape(-1, 3)
        normals = np.asarray(normals, dtype=float).reshape(-1, 3)
        length = np.linalg.norm(normals, axis=1)
        if not len(self.centres_m) or normals.shape != self.centres_m.shape or not np.all(length > 1e-12):
            raise InvalidRequestError(
                "the plane artifact needs at least one face, each with a centre [x, y, z] in metres "
                "and an outward normal of non-zero length; use [calibration] artifact_faces"
            )
        self.normals = normals / length[:, None]
        self.extents_m = np.asarray(extents_m, dtype=float).reshape(-1, 2, 3)
        self.radius_m = float(radius_m)
        self.touch_points = int(touch_points)
        self.noise = np.array([float(noise_m)])
        self.nuisance_scale = np.array([SETUP_DRAW[0]] * 3 + [SETUP_DRAW[1]] * 3)
        self.reference = pin.SE3.Identity() if reference is None else reference
        self.face_names = face_names or tuple(f"face{j}" for j in range(len(self.centres_m)))

    def describe(self) -> str:
        """One line: the faces, the noise, the artifact's pose."""
        return (
            f"probe on a plane artifact: faces {', '.join(self.face_names)}, tip radius "
            f"{1e3 * self.radius_m:.3g} mm, σ {1e6 * self.noise[0]:.3g} µm per touch; the artifact's pose "
            "(6 nuisance parameters) identified with the machine where its faces fix it"
        )

    def pose(self, alpha: np.ndarray) -> pin.SE3:
        """The artifact's pose ``A = A_ref · exp6(α)`` (artifact → K)."""
        return self.reference * pin.exp6(pin.Motion(np.asarray(alpha, dtype=float)))

    def _local(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, alpha: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, pin.SE3]:
        """``(p − s_j, p, m_j, A)``: P in the artifact frame, and each pose's face, (N, 3) each."""
        st = np.asarray(stations, dtype=int)
        if st.size and (st.min() < 0 or st.max() >= len(self.centres_m)):
            raise InvalidRequestError(
                f"face {int(st.max())} does not exist: the artifact has {len(self.centres_m)} "
                "([calibration] artifact_faces)"
            )
        R0, t0 = self.reference.rotation, self.reference.translation
        s = (self.centres_m - t0) @ R0  # s_j, artifact frame
        m = self.normals @ R0  # m_j
        A = self.pose(alpha)
        point = origin + np.einsum("kab,b->ka", rotation, self.point_m)
        p = (point - A.translation) @ A.rotation
        return p - s[st], p, m[st], A

    def measure(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> np.ndarray:
        """``m_jᵀ (A⁻¹ P − s_j)`` per pose, (N, 1) [m]."""
        r, _, m, _ = self._local(origin, rotation, stations, nuisance)
        return np.einsum("ka,ka->k", m, r)[:, None]

    def surface(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(d (N,), its gradient in P (N, 3))``: the distance and the face's normal in K."""
        r, _, m, A = self._local(origin, rotation, stations, nuisance)
        return np.einsum("ka,ka->k", m, r), m @ A.rotation.T

    def twist_rows(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> np.ndarray:
        """``(R_A m_j)ᵀ [I, −[R b]×]`` per pose, (N, 1, 6)."""
        return touch_rows(self.surface(origin, rotation, stations, nuisance)[1], rotation, self.point_m)

    def nuisance_rows(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> np.ndarray:
        """``−[m_jᵀ, (p × m_j)ᵀ] J_r(α)`` per pose, (N, 1, 6)."""
        _, p, m, _ = self._local(origin, rotation, stations, nuisance)
        local = -np.concatenate([m, np.cross(p, m)], axis=1)
        jr = np.asarray(pin.Jexp6(pin.Motion(np.asarray(nuisance, dtype=float))))
        return (local @ jr)[:, None, :]

    def draw_nuisance(self, rng: np.random.Generator) -> np.ndarray:
        """A set-up error of the artifact: σ 0.5 mm per axis, 1 mrad per rotation."""
        return rng.standard_normal(6) * self.nuisance_scale

    def required(self, points_m: np.ndarray, stations: np.ndarray) -> np.ndarray:
        """Three touches per face, far apart: they fix its normal and offset (the plan starts from them).

        Per face: the touch farthest from the face's mean, the one farthest from it, then the one
        farthest from the line through both.
        """
        pts = np.asarray(points_m, dtype=float)
        out: list[int] = []
        for s in np.unique(stations):
            idx = np.flatnonzero(stations == s)
            if idx.size < 3:
                continue
            p = pts[idx]
            a = int(np.argmax(np.linalg.norm(p - p.mean(axis=0), axis=1)))
            b = int(np.argmax(np.linalg.norm(p - p[a], axis=1)))
            line = (p[b] - p[a]) / max(float(np.linalg.norm(p[b] - p[a])), 1e-300)
            off = (p - p[a]) - np.outer((p - p[a]) @ line, line)
            c = int(np.argmax(np.linalg.norm(off, axis=1)))
            out += [int(idx[a]), int(idx[b]), int(idx[c])]
        return np.array(sorted(set(out)), dtype=int)

    def candidates(self, task_points: np.ndarray, rng: np.random.Generator) -> Candidates:
        """Every face's touch points: P at ``c_j + r n_j + a e₁ + b e₂`` over the face."""
        ab = face_grid(self.touch_points)
        pts = (
            self.centres_m[:, None, :]
            + self.radius_m * self.normals[:, None, :]
            + np.einsum("kc,fca->fka", ab, self.extents_m)
        ).reshape(-1, 3)
        F, D = len(self.centres_m), len(ab)
        return Candidates(points_m=pts, stations=np.repeat(np.arange(F), D), groups=np.arange(F * D))


def default_block(
    geometry: tuple[float, float, float, float, float], faces: tuple[str, ...], tip_m: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The default block's faces ``(centres (F, 3), normals (F, 3), extents (F, 2, 3))`` [m].

    ``geometry`` is the task space's ``(cx, cy, radius, z_min, z_max)``: the block stands on the
    task axis, half-width half the task radius, its top face ``tip_m`` below the task space's top
    (P touches it at ``z_max``), its side faces from ``z_min`` to the top.

    Raises:
        InvalidRequestError: an unknown face name.
    """
    bad = [f for f in faces if f not in FACES]
    if bad or not faces:
        raise InvalidRequestError(
            f"unknown artifact face(s) {bad or list(faces)!r}; use some of {', '.join(FACES)}"
        )
    cx, cy, radius, z0, z1 = geometry
    a = 0.5 * radius
    top = z1 - tip_m
    half_h = 0.5 * max(top - z0, 1e-3)
    zc = top - half_h
    centres, normals, extents = [], [], []
    for f in faces:
        n = np.array(FACES[f])
        if f == "+z":
            centres.append((cx, cy, top))
            extents.append(((a, 0.0, 0.0), (0.0, a, 0.0)))
        else:
            side = np.array([-n[1], n[0], 0.0])
            centres.append((cx + a * n[0], cy + a * n[1], zc))
            extents.append((tuple(a * side), (0.0, 0.0, half_h)))
        normals.append(n)
    return np.array(centres, dtype=float), np.array(normals, dtype=float), np.array(extents, dtype=float)
