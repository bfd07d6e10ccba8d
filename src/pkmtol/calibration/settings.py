"""The calibration plan's settings: targets, tracker noise, pose count and selection, controller model, prior.

They come from the optional ``[calibration]`` table of ``mechanism.toml`` (docs/calibration.md),
overridable on the command line. Every length and angle in the table carries its unit.

Defaults and why:

* **noise 0.01 mm per axis**: a laser tracker's maximum permissible error is about
  ±(15 µm + 6 µm/m) (manufacturers' ISO 10360-10 figures for the Leica AT960 / FARO Vantage class);
  at the 1–2 m range of a machining PKM that is 25–30 µm at 2σ–3σ, i.e. a σ of about 10 µm per
  coordinate;
* **40 poses, D-optimal**: enough to reach the noise floor on the bundled robots (docs/calibration.md
  shows the p99 against the pose count);
* **targets**: P only (position of P is what the task needs; give three or more non-collinear
  targets to observe the platform's orientation);
* **controller ``compensatable``**: the paper's premise — the controller's model holds the errors
  that the actuators can compensate; ``full`` holds every non-absorbed parameter (a controller
  running inverse kinematics on calibrated URDFs);
* **manufacturing σ 0.1 mm and 0.5 mrad**: the size of the compensatable errors before calibration
  (they also scale the identification's columns and the MAP prior).
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.tool_sweep import TRACKER_POINTS, tracker_on
from pkmtol.exceptions import InvalidRequestError, MechanismFormatError
from pkmtol.model.mechanism import Mechanism
from pkmtol.units import parse_angle, parse_length

CONTROLLERS = ("compensatable", "full")
SELECTIONS = ("d-optimal", "random")
#: The measurement models (docs/instruments.md).
INSTRUMENTS = ("tracker", "tracker-multi", "tracker-6d", "ballbar", "probe")
#: The probe's artifacts: a set of spheres, or the flat faces of a block (docs/instruments.md).
ARTIFACTS = ("sphere", "plane")
#: The plane artifact's faces by outward normal (``+z``: the top; the block stands on ``-z``).
ARTIFACT_FACES = ("+z", "+x", "-x", "+y", "-y")
#: Default effective radius of a probed sphere (12.7 mm sphere + 1 mm tip) and of the tip on a plane [m].
ARTIFACT_RADIUS = {"sphere": 0.0137, "plane": 0.001}
#: Default candidate approach directions per sphere, touch points per face of a plane artifact.
ARTIFACT_TOUCHES = {"sphere": 24, "plane": 100}
#: How a tracker's frame is known: registered to K before the session, or identified with the machine.
TRACKER_FRAMES = ("registered", "identify")
#: Per instrument: the default noise σ of its (first) value [m] and the default plan size (poses;
#: circles for the ballbar).
INSTRUMENT_DEFAULTS: dict[str, tuple[float, int]] = {
    "tracker": (1e-5, 40),
    "tracker-multi": (1e-5, 40),
    "tracker-6d": (1e-5, 40),
    "ballbar": (1e-6, 6),
    "probe": (1e-6, 120),
}
#: Reflectors of ``tracker-multi`` when ``targets_m`` is not given: P and 0.1 m from it along the
#: platform's x and y axes.
MULTI_OFFSETS_M = ((0.0, 0.0, 0.0), (0.1, 0.0, 0.0), (0.0, 0.1, 0.0))
#: Keys of the ``[calibration]`` table.
TABLE_KEYS = (
    "targets_m",
    "noise",
    "poses",
    "selection",
    "controller",
    "prior",
    "rank_tolerance",
    "candidates",
    "manufacturing_length",
    "manufacturing_angle",
    "instrument",
    "orientation_noise",
    "tracker_frame",
    "stations_m",
    "ballbar_length",
    "circle_planes",
    "circle_points",
    "artifact",
    "artifact_faces",
    "artifact_radius",
    "approach_directions",
    "tracker_on",
)


@dataclass(frozen=True)
class CalibrationSettings:
    """How the machine will be calibrated.

    Attributes:
        targets_m: Tracker targets in the platform frame, ``((x, y, z), ...)`` [m]; empty: P only
            (``tracker-multi``: P and two points 0.1 m from it).
        noise_m: Noise σ_m of the instrument's reading [m]: per tracker coordinate, per ballbar
            reading, per probe touch (NaN: the instrument's default, 10 µm for a tracker, 1 µm for
            the ballbar and the probe). Tables name it the reference σ.
        poses: Number of calibration poses N (the ballbar: circles; 0: the instrument's default).
        selection: ``d-optimal`` or ``random`` (from the candidate pool).
        controller: ``compensatable``, ``full``, or an explicit tuple of parameter names.
        prior: Identify every controller parameter with a Gaussian prior (MAP) instead of least
            squares on the base parameters.
        rank_tolerance: Relative pivot below which a direction is unidentifiable.
        candidates: Random reachable poses added to the task-space grid to form the pool.
        manufacturing_length_m: σ of the compensatable length errors before calibration [m].
        manufacturing_angle_rad: σ of the compensatable angle errors [rad].
        seed: Random seed (candidate pool, random plans).
        instrument: The measurement model, one of :data:`INSTRUMENTS`.
        orientation_noise_rad: σ per rotation component of ``tracker-6d`` [rad].
        tracker_frame: ``registered`` (the tracker reads in K) or ``identify`` (its transform to
            K is identified with the machine: 6 nuisance parameters).
        stations_m: Ballbar table-ball centres or probed sphere centres in K [m] (empty: 5 per
            height around the task space's axis, :func:`~pkmtol.calibration.instruments.default_centres`).
        ballbar_length_m: The ballbar's length = the circles' radius [m] (0: a quarter of the
            task space's radius).
        circle_planes: The planes of the ballbar circles about every centre (xy, yz, zx).
        circle_points: Readings per ballbar circle.
        artifact: The probe's artifact, ``sphere`` (spheres at ``stations_m``) or ``plane`` (the
            flat faces of a block).
        artifact_faces: The plane artifact's faces touched, by outward normal (:data:`ARTIFACT_FACES`).
        artifact_radius_m: The probed sphere's effective radius (sphere + stylus tip), or on a
            plane the stylus tip's radius [m] (NaN: 13.7 mm, 1 mm).
        approach_directions: Candidate approach directions per probed sphere, or touch points
            per face of a plane artifact (0: 24 per sphere, 100 per face).
    """

    targets_m: tuple[tuple[float, float, float], ...] = ()
    noise_m: float = float("nan")
    poses: int = 0
    selection: str = "d-optimal"
    controller: str | tuple[str, ...] = "compensatable"
    prior: bool = False
    rank_tolerance: float = 1e-6
    candidates: int = 300
    manufacturing_length_m: float = 1e-4
    manufacturing_angle_rad: float = 5e-4
    seed: int = 0
    instrument: str = "tracker"
    orientation_noise_rad: float = 1e-4
    tracker_frame: str = "registered"
    stations_m: tuple[tuple[float, float, float], ...] = ()
    ballbar_length_m: float = 0.0
    circle_planes: tuple[str, ...] = ("xy", "yz", "zx")
    circle_points: int = 36
    artifact: str = "sphere"
    artifact_faces: tuple[str, ...] = ARTIFACT_FACES
    artifact_radius_m: float = float("nan")
    approach_directions: int = 0
    extra: dict[str, Any] = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        if self.instrument not in INSTRUMENTS:
            close = difflib.get_close_matches(str(self.instrument), INSTRUMENTS, n=1)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            raise InvalidRequestError(
                f"unknown instrument {self.instrument!r}{hint}; use one of {', '.join(INSTRUMENTS)}"
            )
        if self.tracker_frame not in TRACKER_FRAMES:
            raise InvalidRequestError(
                f"unknown tracker_frame {self.tracker_frame!r}; use one of {', '.join(TRACKER_FRAMES)}"
            )
        if self.artifact not in ARTIFACTS:
            raise InvalidRequestError(
                f"unknown artifact {self.artifact!r}; use one of {', '.join(ARTIFACTS)}"
            )
        faces = [f for f in self.artifact_faces if f not in ARTIFACT_FACES]
        if faces or not self.artifact_faces or len(set(self.artifact_faces)) != len(self.artifact_faces):
            raise InvalidRequestError(
                f"artifact_faces must be distinct faces of {', '.join(ARTIFACT_FACES)}; "
                f"got {list(self.artifact_faces)!r}"
            )
        if isinstance(self.artifact_radius_m, float) and np.isnan(self.artifact_radius_m):
            object.__setattr__(self, "artifact_radius_m", ARTIFACT_RADIUS[self.artifact])
        if self.approach_directions == 0 and not isinstance(self.approach_directions, bool):
            object.__setattr__(self, "approach_directions", ARTIFACT_TOUCHES[self.artifact])
        noise, poses = INSTRUMENT_DEFAULTS[self.instrument]
        if isinstance(self.noise_m, float) and np.isnan(self.noise_m):
            object.__setattr__(self, "noise_m", noise)
        if self.poses == 0 and not isinstance(self.poses, bool):
            object.__setattr__(self, "poses", poses)
        for name, value in (
            ("orientation_noise_rad", self.orientation_noise_rad),
            ("ballbar_length_m", self.ballbar_length_m),
            ("artifact_radius_m", self.artifact_radius_m),
        ):
            if (
                isinstance(value, bool)
                or not isinstance(value, int | float)
                or not np.isfinite(value)
                or value < 0
            ):
                raise InvalidRequestError(f"calibration {name} must be a finite number ≥ 0, got {value!r}")
        for name, value, low in (
            ("circle_points", self.circle_points, 4),
            ("approach_directions", self.approach_directions, 4),
        ):
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise InvalidRequestError(f"calibration {name} must be an integer ≥ {low}, got {value!r}")
        bad = [p for p in self.circle_planes if p not in ("xy", "yz", "zx")]
        if bad or not self.circle_planes:
            raise InvalidRequestError(
                f"circle_planes must be a list of xy, yz, zx; got {list(self.circle_planes)!r}"
            )
        st = (
            np.asarray(self.stations_m, dtype=float).reshape(-1, 3)
            if len(self.stations_m)
            else np.zeros((0, 3))
        )
        if not np.all(np.isfinite(st)):
            raise InvalidRequestError("calibration stations_m must be finite [x, y, z] points in metres")
        for name, value in (
            ("noise_m", self.noise_m),
            ("manufacturing_length_m", self.manufacturing_length_m),
            ("manufacturing_angle_rad", self.manufacturing_angle_rad),
        ):
            if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
                raise InvalidRequestError(f"calibration {name} must be a finite number, got {value!r}")
        if self.noise_m < 0 or self.manufacturing_length_m <= 0 or self.manufacturing_angle_rad <= 0:
            raise InvalidRequestError(
                "calibration noise must be ≥ 0 and the manufacturing σ > 0; give e.g. noise '0.01 mm'"
            )
        if max(self.noise_m, self.manufacturing_length_m, self.orientation_noise_rad) > 1.0 or (
            self.manufacturing_angle_rad > 1.0
        ):  # squares of larger ones overflow nowhere, but no instrument or machine is that far off
            raise InvalidRequestError(
                "calibration noise and manufacturing σ must be at most 1 m (1 rad); give e.g. noise "
                "'0.01 mm', manufacturing_length '0.1 mm'"
            )
        for name, value, low in (
            ("poses", self.poses, 1),
            ("candidates", self.candidates, 0),
            ("seed", self.seed, 0),
        ):
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise InvalidRequestError(f"calibration {name} must be an integer ≥ {low}, got {value!r}")
        if self.selection not in SELECTIONS:
            raise InvalidRequestError(
                f"unknown pose selection {self.selection!r}; use one of {', '.join(SELECTIONS)}"
            )
        if isinstance(self.controller, str) and self.controller not in CONTROLLERS:
            raise InvalidRequestError(
                f"unknown controller model {self.controller!r}; use {', '.join(CONTROLLERS)} or a list "
                "of parameter names"
            )
        if not 0 < self.rank_tolerance < 1:
            raise InvalidRequestError(f"rank_tolerance must be in (0, 1), got {self.rank_tolerance!r}")
        pts = (
            np.asarray(self.targets_m, dtype=float).reshape(-1, 3)
            if len(self.targets_m)
            else np.zeros((0, 3))
        )
        if not np.all(np.isfinite(pts)):
            raise InvalidRequestError("calibration targets_m must be finite [x, y, z] in metres")

    def targets(self, mechanism: Mechanism) -> np.ndarray:
        """The tracker targets (t, 3) in the platform frame [m]: ``targets_m``, or P alone.

        ``tracker-multi`` without ``targets_m``: P and :data:`MULTI_OFFSETS_M` from it. A hybrid
        machine (a ``[tool]`` chain): the frame is the TCP frame, and the default target the TCP,
        or with ``tracker_on = "nose"`` the spindle nose ``(0, 0, −L)``.
        """
        if len(self.targets_m):
            return np.asarray(self.targets_m, dtype=float).reshape(-1, 3)
        p = np.asarray(mechanism.reference_point_m, dtype=float)
        if mechanism.tool is not None:
            on_nose = tracker_on(mechanism) == "nose"
            p = np.array([0.0, 0.0, -mechanism.tool.length_m if on_nose else 0.0])
        if self.instrument == "tracker-multi":
            return p[None, :] + np.asarray(MULTI_OFFSETS_M)
        return p[None, :]

    def controller_columns(self, pset: ParameterSet, classes: list[str]) -> np.ndarray:
        """Indices of the controller model's parameters in ``pset``.

        Raises:
            InvalidRequestError: an explicit name is not a parameter, or names an absorbed one.
        """
        if self.controller == "compensatable":
            return np.array([i for i, c in enumerate(classes) if c == "compensatable"], dtype=int)
        if self.controller == "full":
            return np.array([i for i, c in enumerate(classes) if c != "absorbed"], dtype=int)
        names = pset.names
        out = []
        for name in self.controller:
            if name not in names:
                close = difflib.get_close_matches(name, names, n=1)
                hint = f"; did you mean '{close[0]}'?" if close else "; see `pkmtol errors` for the names"
                raise InvalidRequestError(
                    f"controller parameter '{name}' is not in the {pset.kind} set{hint}"
                )
            out.append(names.index(name))
        return np.array(sorted(set(out)), dtype=int)

    @property
    def controller_label(self) -> str:
        """``compensatable``, ``full`` or ``explicit (k)``."""
        return self.controller if isinstance(self.controller, str) else f"explicit ({len(self.controller)})"

    def manufacturing_sigma(self, pset: ParameterSet) -> np.ndarray:
        """σ per parameter before calibration (n,) [m or rad], by unit."""
        return np.array(
            [self.manufacturing_length_m if u == "m" else self.manufacturing_angle_rad for u in pset.units]
        )


def settings_from_table(table: dict[str, Any], path: Path | str, **overrides: Any) -> CalibrationSettings:
    """Settings from a ``[calibration]`` table (``mechanism.toml``), then ``overrides`` (non-None only).

    Raises:
        MechanismFormatError: an unknown key (with a "did you mean"), or a mistyped value.
    """
    kw: dict[str, Any] = {}
    for key, value in table.items():
        if key not in TABLE_KEYS:
            close = difflib.get_close_matches(key, TABLE_KEYS, n=1)
            hint = f"; did you mean '{close[0]}'?" if close else f"; known keys: {', '.join(TABLE_KEYS)}"
            raise MechanismFormatError(path, f"calibration.{key}", f"unknown key{hint}")
        try:
            kw.update(_read(key, value))
        except (InvalidRequestError, TypeError, ValueError) as err:
            raise MechanismFormatError(path, f"calibration.{key}", str(err)) from err
    kw.update({k: v for k, v in overrides.items() if v is not None})
    try:
        return CalibrationSettings(**kw)
    except InvalidRequestError as err:
        raise MechanismFormatError(path, "calibration", str(err)) from err


def _read(key: str, value: Any) -> dict[str, Any]:
    if key == "targets_m":
        pts = np.asarray(value, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
            raise InvalidRequestError(f"expected a list of [x, y, z] points in metres, got {value!r}")
        return {"targets_m": tuple(tuple(float(c) for c in p) for p in pts)}
    if key == "noise":
        return {"noise_m": parse_length(_with_unit(value, key), "calibration.noise")}
    if key == "manufacturing_length":
        return {"manufacturing_length_m": parse_length(_with_unit(value, key), key)}
    if key == "manufacturing_angle":
        return {"manufacturing_angle_rad": parse_angle(value, key)}
    if key == "orientation_noise":
        return {"orientation_noise_rad": parse_angle(value, key)}
    if key == "ballbar_length":
        return {"ballbar_length_m": parse_length(_with_unit(value, key), key)}
    if key == "artifact_radius":
        return {"artifact_radius_m": parse_length(_with_unit(value, key), key)}
    if key == "stations_m":
        pts = np.asarray(value, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
            raise InvalidRequestError(f"expected a list of [x, y, z] points in metres, got {value!r}")
        return {"stations_m": tuple(tuple(float(c) for c in p) for p in pts)}
    if key == "artifact_faces":
        if not isinstance(value, list) or not all(isinstance(x, str) for x in value):
            raise InvalidRequestError(
                f"expected a list of faces ({', '.join(ARTIFACT_FACES)}), got {value!r}"
            )
        return {"artifact_faces": tuple(value)}
    if key == "circle_planes":
        if not isinstance(value, list) or not all(isinstance(x, str) for x in value):
            raise InvalidRequestError(f"expected a list of planes (xy, yz, zx), got {value!r}")
        return {"circle_planes": tuple(value)}
    if key in ("instrument", "tracker_frame", "tracker_on", "artifact") and not isinstance(value, str):
        raise InvalidRequestError(f"expected a name, got {value!r}")
    if key == "tracker_on":  # a hybrid's: read from the mechanism's table (error_model.tool_sweep.tracker_on)
        if value not in TRACKER_POINTS:
            raise InvalidRequestError(f"expected one of {', '.join(TRACKER_POINTS)}, got {value!r}")
        return {}
    if key == "controller":
        if isinstance(value, list):
            if not all(isinstance(x, str) for x in value):
                raise InvalidRequestError(f"expected a list of parameter names, got {value!r}")
            return {"controller": tuple(value)}
        return {"controller": value}
    if key == "prior":
        if not isinstance(value, bool):
            raise InvalidRequestError(f"expected true or false, got {value!r}")
        return {"prior": value}
    if key == "rank_tolerance":
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise InvalidRequestError(f"expected a number, got {value!r}")
        return {"rank_tolerance": float(value)}
    return {key: value}


def _with_unit(value: Any, key: str) -> str:
    if not isinstance(value, str):
        raise InvalidRequestError(f"give {key} with its unit, e.g. '0.01 mm', got {value!r}")
    return value
