"""What every measurement model of a calibration provides: values, their Jacobians, noise, nuisance.

An instrument measures ``r`` values per pose of the platform (frame K, SI units). Its model is a
function of the platform pose (O' at ``origin``, orientation ``rotation``), of the *station* the
pose belongs to (a ballbar circle, a probed sphere; 0 for a tracker), and of the instrument's own
unknowns, its **nuisance parameters** ``π`` (the tracker-to-base transform, a ballbar's table
ball, a probed artifact's position), identified together with the machine and then dropped.

The identification needs, at each pose:

* :meth:`Instrument.measure`: the exact values;
* :meth:`Instrument.residual`: measured − model (a rotation's difference is ``log3``);
* :meth:`Instrument.twist_rows`: the values' change per unit platform twist at O' (``[v; ω]`` in
  K', DESIGN.md), shape (N, r, 6); times ``Separation.twist_map`` it is the machine Jacobian;
* :meth:`Instrument.nuisance_rows`: their change per unit nuisance parameter, (N, r, q);
* :attr:`Instrument.noise`: σ of each value (r,) [m or rad], independent Gaussian.

Each Jacobian is checked against finite differences of :meth:`measure` in
``tests/test_instruments.py``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Candidates:
    """Where an instrument can measure: candidate positions of P and what each belongs to.

    Attributes:
        points_m: Shape (m, 3): target positions of P in K [m].
        stations: Shape (m,): the station of each (index into the instrument's stations).
        groups: Shape (m,): poses measured together (a ballbar circle); a plan chooses whole groups.
    """

    points_m: np.ndarray
    stations: np.ndarray
    groups: np.ndarray


class Instrument(ABC):
    """A measurement model (abstract): see the module docstring.

    Attributes:
        name: The instrument's name (``[calibration] instrument``).
        value_names: Name of each of the ``r`` values of a pose (e.g. ``x``, ``y``, ``z``).
        value_units: ``m`` or ``rad`` per value.
        noise: Shape (r,): σ of each value [m or rad].
        nuisance_names: Names of the ``q`` nuisance parameters.
        nuisance_units: ``m`` or ``rad`` per nuisance parameter.
        nuisance_scale: Shape (q,): their expected size [m or rad] (column scaling, simulated draws).
    """

    name: str = ""
    value_names: tuple[str, ...] = ()
    value_units: tuple[str, ...] = ()
    noise: np.ndarray
    nuisance_names: tuple[str, ...] = ()
    nuisance_units: tuple[str, ...] = ()
    nuisance_scale: np.ndarray
    #: What each nuisance parameter is, in words (for what the data cannot fix; empty: its name).
    nuisance_meanings: tuple[str, ...] = ()
    #: Re-evaluate :meth:`twist_rows` and :meth:`nuisance_rows` at every Gauss–Newton iterate (the
    #: values are strongly curved in the platform pose: a distance to a centre a few cm away);
    #: the machine's twist maps stay the nominal ones.
    refresh_rows: bool = False

    @property
    def values_per_pose(self) -> int:
        """``r``: values measured at each pose."""
        return len(self.value_names)

    @property
    def nuisance_count(self) -> int:
        """``q``: nuisance parameters."""
        return len(self.nuisance_names)

    @abstractmethod
    def measure(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> np.ndarray:
        """The exact values (N, r) at platform poses ``origin`` (N, 3) [m], ``rotation`` (N, 3, 3).

        ``stations`` (N,) are the poses' stations, ``nuisance`` (q,) the nuisance parameters.
        """

    def residual(self, measured: np.ndarray, model: np.ndarray) -> np.ndarray:
        """``measured − model`` (N, r), to first order the values' change (default: the difference)."""
        return np.asarray(measured, dtype=float) - np.asarray(model, dtype=float)

    def perturb(self, values: np.ndarray, noise: np.ndarray) -> np.ndarray:
        """Values (N, r) read with ``noise`` (N, r) [m or rad] (default: added)."""
        return np.asarray(values, dtype=float) + np.asarray(noise, dtype=float)

    @abstractmethod
    def twist_rows(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> np.ndarray:
        """Change of the values per unit platform twist at O' (in K'), shape (N, r, 6)."""

    def nuisance_rows(
        self, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray, nuisance: np.ndarray
    ) -> np.ndarray:
        """Change of the values per unit nuisance parameter, shape (N, r, q) (default: none)."""
        return np.zeros((len(origin), self.values_per_pose, self.nuisance_count))

    def start(
        self, measured: np.ndarray, origin: np.ndarray, rotation: np.ndarray, stations: np.ndarray
    ) -> tuple[Instrument, np.ndarray]:
        """The instrument to linearise at and its starting nuisance, from the data and the nominal poses.

        The default: this instrument, nuisance zero (its nominal). A tracker whose frame is
        identified first registers the frame in closed form (:mod:`.frame`).
        """
        return self, np.zeros(self.nuisance_count)

    def draw_nuisance(self, rng: np.random.Generator) -> np.ndarray:
        """A simulated true nuisance vector (q,): Gaussian at :attr:`nuisance_scale` (default)."""
        return rng.standard_normal(self.nuisance_count) * self.nuisance_scale

    def candidates(self, task_points: np.ndarray, rng: np.random.Generator) -> Candidates | None:
        """Candidate poses of the plan, or None: the task-space grid and random poses (a tracker)."""
        return None

    def required(self, points_m: np.ndarray, stations: np.ndarray) -> np.ndarray:
        """Candidates (indices into ``points_m`` (m, 3), ``stations`` (m,)) every D-optimal plan holds.

        Default none. A plane artifact needs three touches of a face before any further touch of
        it tells the machine anything (they fix the face's normal and offset), which a greedy,
        one-touch-at-a-time choice cannot see.
        """
        return np.zeros(0, dtype=int)

    def nuisance_report(self, nuisance: np.ndarray, std: np.ndarray) -> list[dict[str, object]]:
        """The identified nuisance parameters for the output, one dict per parameter (SI)."""
        return [
            {"name": n, "unit": u, "value": float(v), "std": float(s)}
            for n, u, v, s in zip(self.nuisance_names, self.nuisance_units, nuisance, std, strict=True)
        ]

    def describe(self) -> str:
        """One line: what is measured, the noise, the nuisance parameters."""
        noise = ", ".join(_fmt_noise(s, u) for s, u in zip(self.noise, self.value_units, strict=True))
        return (
            f"{self.name}: {self.values_per_pose} value(s) per pose ({', '.join(self.value_names)}), "
            f"σ {noise}; {self.nuisance_count} nuisance parameter(s) identified with the machine"
        )


def unseen_nuisance(instrument: Instrument, rows: np.ndarray, tolerance: float = 1e-8) -> list[str]:
    """The instrument's nuisance directions that no value changes with (its data cannot fix them).

    Args:
        instrument: The measurement model.
        rows: Shape (M, q): the values' change per unit nuisance parameter at the data.
        tolerance: Relative singular value below which a direction is unseen.

    Returns:
        One name per unseen direction: a parameter's name when the direction is one parameter
        (to 1e-6), else its combination (largest terms first).
    """
    rows = np.asarray(rows, dtype=float).reshape(-1, instrument.nuisance_count)
    if not rows.size:
        return []
    scaled = rows * np.asarray(instrument.nuisance_scale, dtype=float)[None, :]
    _, s, vt = np.linalg.svd(scaled, full_matrices=True)
    full = np.zeros(vt.shape[0])
    full[: s.size] = s
    null = vt[full <= tolerance * max(float(full[0]), 1e-300)]
    if not len(null):
        return []
    # a clean basis: reduce the null space to the fewest parameters (rref of its rows)
    basis = _rref(null)
    out = []
    names = instrument.nuisance_names
    meaning = instrument.nuisance_meanings or names
    for v in basis:
        big = np.flatnonzero(np.abs(v) > 1e-6 * np.abs(v).max())
        if big.size == 1:
            out.append(names[big[0]] + (f" ({meaning[big[0]]})" if meaning is not names else ""))
        else:
            order = big[np.argsort(-np.abs(v[big]))]
            out.append(" ".join(f"{v[i] / v[order[0]]:+.3g}·{names[i]}" for i in order))
    return out


def _rref(rows: np.ndarray) -> np.ndarray:
    """Reduced row echelon form of ``rows`` (k, q) with partial pivoting (a basis of the same span)."""
    a = np.array(rows, dtype=float)
    k, q = a.shape
    r = 0
    for c in range(q):
        if r >= k:
            break
        p = r + int(np.argmax(np.abs(a[r:, c])))
        if abs(a[p, c]) < 1e-9:
            continue
        a[[r, p]] = a[[p, r]]
        a[r] /= a[r, c]
        for i in range(k):
            if i != r:
                a[i] -= a[i, c] * a[r]
        r += 1
    a[np.abs(a) < 1e-12] = 0.0
    return a[:r]


def _fmt_noise(sigma: float, unit: str) -> str:
    return f"{sigma * 1e6:.3g} µm" if unit == "m" else f"{sigma * 1e6:.3g} µrad"


def lever_rows(rotation: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """``[I, −[R b]×]`` per pose (N, 3, 6): a point at ``offset`` b (platform frame) per unit twist at O'."""
    lever = np.einsum("kab,b->ka", rotation, np.asarray(offset, dtype=float))
    out = np.zeros((len(rotation), 3, 6))
    out[:, :, :3] = np.eye(3)
    out[:, :, 3:] = -skew(lever)
    return out


def skew(v: np.ndarray) -> np.ndarray:
    """``[v]×`` of vectors (…, 3), shape (…, 3, 3)."""
    v = np.asarray(v, dtype=float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out
