"""Every user-facing failure of pkmtol, rooted at :class:`PkmtolError`.

Each message says what was wrong and what to do about it. Subclasses carry the data that
identifies the culprit (limb, joint, target, file) as attributes so that callers can react
programmatically.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from pkmtol.warning_types import MissingLimitWarning, MissingMeshWarning, PkmtolWarning  # noqa: F401 - re-exported


class PkmtolError(Exception):
    """Base class of every error raised by pkmtol on bad input or an impossible request.

    Errors pickle with their message and attributes (a worker process or a Dask worker can raise
    them back to the caller), although their constructors take other arguments than the message.
    """

    def __reduce__(self) -> tuple:
        return (_rebuild, (type(self), self.args, self.__dict__))


def _rebuild(cls: type[PkmtolError], args: tuple, state: dict) -> PkmtolError:
    """An error of class ``cls`` with message ``args`` and attributes ``state``, without its constructor."""
    err = cls.__new__(cls)
    Exception.__init__(err, *args)
    err.__dict__.update(state)
    return err


# --- mechanism description -------------------------------------------------------------


class MechanismFormatError(PkmtolError):
    """The mechanism description (TOML) is missing a key, has a mistyped value, or is inconsistent.

    Attributes:
        path: The offending file.
        key: Dotted key of the offending entry (e.g. ``limbs[2].actuated``); ``"-"`` for the
            whole file.
    """

    def __init__(self, path: Path | str, key: str, problem: str) -> None:
        self.path = Path(path)
        self.key = key
        where = "" if key == "-" else f" key '{key}':"
        super().__init__(f"{self.path}:{where} {problem}")


class UnknownKeyError(MechanismFormatError):
    """A key of the mechanism description is not one pkmtol reads (misspelt, or in the wrong table).

    Attributes:
        path: The offending file.
        key: Dotted key of the unknown entry (e.g. ``design.targte``).
        known: The keys that table may hold.
        suggestion: The closest known key (None if nothing is close).
    """

    def __init__(self, path: Path | str, key: str, known: Iterable[str], suggestion: str | None) -> None:
        self.known = tuple(sorted(known))
        self.suggestion = suggestion
        hint = f"did you mean '{suggestion}'? " if suggestion else ""
        super().__init__(
            path,
            key,
            f"unknown key; {hint}this table takes {', '.join(self.known) or 'no keys'} "
            "(docs/mechanism-format.md)",
        )


class URDFError(PkmtolError):
    """A limb URDF is missing, malformed, or does not describe a serial limb pkmtol can use.

    Attributes:
        limb: Name of the limb.
        path: The URDF file (None when the limb came from a ``pin.Model``).
    """

    def __init__(self, limb: str, path: Path | str | None, problem: str) -> None:
        self.limb = limb
        self.path = None if path is None else Path(path)
        where = f" ({self.path})" if self.path is not None else ""
        super().__init__(f"limb '{limb}'{where}: {problem}")


class MissingLimitError(URDFError):
    """A prismatic joint of a URDF has no ``lower``/``upper`` limit, so its stroke is unknown.

    A revolute joint without limits gets ±π and a :class:`MissingLimitWarning`; a prismatic joint
    has no such default (its stroke is a design choice), so it is refused.

    Attributes:
        limb: Name of the limb.
        path: The URDF file.
        joint: The prismatic joint.
    """

    def __init__(self, limb: str, path: Path | str | None, joint: str) -> None:
        self.joint = joint
        super().__init__(
            limb,
            path,
            f"prismatic joint '{joint}' has no lower/upper limit, and a stroke cannot be assumed; "
            f'write its stroke in metres in the URDF: <limit lower="0.4" upper="1.6" effort="1000" '
            'velocity="1" /> inside <joint name="' + joint + '">',
        )


class DHMismatchError(URDFError):
    """A limb URDF disagrees with the D–H table it was generated from (``[limbs.dh]``).

    Attributes:
        limb: Name of the limb.
        path: The URDF file.
        joint: The first joint (or platform attachment) that differs.
        what: What differs (``origin``, ``axis``, ``type``, ``name``, ``limits``).
        difference: Size of the difference (m and rad for an origin, else 0).
        command: The command that regenerates the URDF from the table.
    """

    def __init__(
        self,
        limb: str,
        path: Path | str | None,
        joint: str,
        what: str,
        detail: str,
        command: str,
        difference: float = 0.0,
    ) -> None:
        self.joint = joint
        self.what = what
        self.difference = difference
        self.command = command
        super().__init__(
            limb,
            path,
            f"joint '{joint}': {what} in the URDF and in the [limbs.dh] table of mechanism.toml "
            f"differ ({detail}); regenerate the URDF with `{command}` (or fix the table)",
        )


class UnknownJointError(PkmtolError):
    """A joint named in the description does not exist in the limb.

    Attributes:
        limb: Name of the limb.
        joint: The unknown joint name.
        available: The joint names the limb does have.
    """

    def __init__(self, limb: str, joint: str, available: Sequence[str], source: str = "") -> None:
        self.limb = limb
        self.joint = joint
        self.available = tuple(available)
        src = f" is not in {source}" if source else " does not exist"
        super().__init__(
            f"limb '{limb}': joint '{joint}' listed as actuated{src} "
            f"(joints: {', '.join(self.available)}); fix the name in mechanism.toml"
        )


class PlatformMismatchError(PkmtolError):
    """The limbs' platform frames do not coincide at the nominal (zero) configuration or at closure.

    Attributes:
        limb: The limb whose platform frame disagrees with the first limb's.
        distance_m: Translation mismatch [m].
        angle_rad: Rotation mismatch [rad].
    """

    def __init__(self, limb: str, reference: str, distance_m: float, angle_rad: float) -> None:
        self.limb = limb
        self.distance_m = distance_m
        self.angle_rad = angle_rad
        super().__init__(
            f"limb '{limb}': its platform frame cannot be made to coincide with limb "
            f"'{reference}' (closest mismatch {distance_m * 1e3:.3g} mm, {angle_rad:.3g} rad); "
            "check the limbs' home values in mechanism.toml, and that every limb URDF ends in the "
            "same platform link placed at the same platform frame"
        )


class LoopMismatchError(PlatformMismatchError):
    """An internal loop of a limb cannot be closed near ``home`` (the parent's attributes, and ``loop``)."""

    def __init__(
        self, limb: str, loop: str, frames: tuple[str, str], distance_m: float, angle_rad: float
    ) -> None:
        self.limb, self.loop, self.distance_m, self.angle_rad = limb, loop, distance_m, angle_rad
        PkmtolError.__init__(
            self,
            f"limb '{limb}': its loop '{loop}' ({frames[0]} ↔ {frames[1]}) cannot be closed near home "
            f"(gap {distance_m * 1e3:.3g} mm, {angle_rad:.3g} rad); check the loop's frames and the "
            "limb's home joint values",
        )


# --- kinematics -------------------------------------------------------------------------


class KinematicsError(PkmtolError):
    """Base class of closed-chain kinematics failures."""


class UnreachableTargetError(KinematicsError):
    """No closed-chain configuration reaches the target.

    Attributes:
        target_m: The requested position of the reference point P in frame K [m], shape (3,).
        limb: The limb that could not follow (None if undetermined).
    """

    def __init__(self, target_m: np.ndarray, problem: str, limb: str | None = None) -> None:
        self.target_m = np.asarray(target_m, dtype=float).copy()
        self.limb = limb
        who = f"limb '{limb}': " if limb else ""
        super().__init__(
            f"{who}target P = {_fmt_mm(self.target_m)} is unreachable: {problem}; "
            "move the target (or the task space) inside the workspace, or widen the joint limits"
        )


class JointLimitError(UnreachableTargetError):
    """The closed chain reaches the target only with a joint outside its URDF limits.

    Attributes:
        joint: Name of the joint.
        value: Its value [rad or m].
        lower: Lower limit [rad or m].
        upper: Upper limit [rad or m].
    """

    def __init__(
        self, target_m: np.ndarray, limb: str, joint: str, value: float, lower: float, upper: float
    ) -> None:
        self.joint = joint
        self.value = value
        self.lower = lower
        self.upper = upper
        super().__init__(
            target_m,
            f"joint '{joint}' would be at {value:.6g}, outside its limits [{lower:.6g}, {upper:.6g}]",
            limb=limb,
        )


class ConvergenceError(KinematicsError):
    """Newton's method did not converge.

    Attributes:
        residual: Final residual norm (m, rad mixed).
        iterations: Iterations spent.
    """

    def __init__(self, what: str, residual: float, iterations: int) -> None:
        self.residual = residual
        self.iterations = iterations
        super().__init__(
            f"{what}: Newton's method stopped at residual {residual:.3g} after {iterations} "
            "iterations; try a closer initial guess or a target further from the workspace boundary"
        )


class SingularPoseError(KinematicsError):
    """The configuration is singular (or nearly so): the linear error model is not defined there.

    Attributes:
        target_m: Position of P in K [m] (None if not a task-space solve).
        condition: Condition number of the offending matrix.
        what: Which matrix is singular (``closure Jacobian`` or ``wrench matrix W``).
    """

    def __init__(self, what: str, condition: float, target_m: np.ndarray | None = None) -> None:
        self.what = what
        self.condition = condition
        self.target_m = None if target_m is None else np.asarray(target_m, float).copy()
        at = f" at P = {_fmt_mm(self.target_m)}" if self.target_m is not None else ""
        super().__init__(
            f"singular configuration{at}: {what} has condition number {condition:.3g}; "
            "keep the task space away from this pose or change the dimensions"
        )


class RobotCheckError(KinematicsError):
    """A generated robot does not pass ``pkmtol check`` with the dimensions given (nothing is written).

    Attributes:
        family: The mechanism family.
        problems: What the check found (unreachable points, wrong mobility).
    """

    def __init__(self, family: str, problems: Sequence[str]) -> None:
        self.family = family
        self.problems = tuple(problems)
        super().__init__(
            f"the {family} with these dimensions does not pass `pkmtol check`: {'; '.join(self.problems)}; "
            "change the dimensions, the strokes (--leg-stroke) or the task space (--task-radius, --task-z); "
            "nothing was written"
        )


class MobilityError(KinematicsError):
    """The actuation and constraint wrenches do not span 6 dimensions, or an actuator cannot act.

    The mechanism is not properly actuated at that pose (wrong actuated joints, or an actuation
    singularity).
    """


# --- user requests ----------------------------------------------------------------------


class InvalidRequestError(PkmtolError, ValueError):
    """A numeric request is out of range (non-positive target, beta or sample count, ...)."""


class InvalidArgumentError(InvalidRequestError):
    """An argument of a public function, an option field or a command-line value is wrong.

    Attributes:
        argument: Name of the argument as the caller wrote it (``target_m``,
            ``TaskSpace.radius_m``, ``--samples``).
        value: The value given.
    """

    def __init__(self, argument: str, value: object, problem: str) -> None:
        self.argument = argument
        self.value = value
        self.problem = problem
        super().__init__(_argument_message(argument, value, problem))

    def renamed(self, argument: str) -> InvalidArgumentError:
        """The same error naming the argument as ``argument`` (e.g. the option ``--samples``)."""
        new = type(self).__new__(type(self))
        new.__dict__.update(self.__dict__)
        new.argument = argument
        new.args = (_argument_message(argument, self.value, self.problem),)
        return new


def _argument_message(argument: str, value: object, problem: str) -> str:
    shown = f"{argument} {value}" if argument.startswith("--") else f"{argument} = {_short_repr(value)}"
    return f"{shown}: {problem}"


class ResourceLimitError(InvalidArgumentError):
    """A request would need more memory than the machine has; refused before any work starts.

    Attributes:
        estimate_bytes: Memory the request would need (estimate) [bytes].
        available_bytes: Memory available [bytes].
    """

    def __init__(
        self, argument: str, value: object, estimate_bytes: float, available_bytes: float, hint: str
    ) -> None:
        self.estimate_bytes = float(estimate_bytes)
        self.available_bytes = float(available_bytes)
        super().__init__(
            argument,
            value,
            f"needs about {_gb(estimate_bytes)} of memory, more than the {_gb(available_bytes)} "
            f"available; {hint}",
        )


def _gb(n: float) -> str:
    if n >= 1e12:
        return f"{n / 1e12:,.3g} TB" if n < 1e15 else f"{n / 1e12:,.0f} TB"
    return f"{n / 1e9:.3g} GB" if n >= 1e8 else f"{n / 1e6:.3g} MB"


def _short_repr(value: object, limit: int = 80) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


class OutputError(PkmtolError):
    """An output file or folder cannot be written. Nothing has been written when this is raised."""

    def __init__(self, path: Path | str, problem: str) -> None:
        self.path = Path(path)
        super().__init__(f"cannot write {self.path}: {problem}")


class OutputLockedError(OutputError):
    """Another pkmtol run is writing into the same output folder.

    Attributes:
        path: The output folder.
        pid: Process id of the other run (None if unknown).
    """

    def __init__(self, path: Path | str, pid: int | None) -> None:
        self.pid = pid
        who = f"process {pid}" if pid is not None else "another process"
        super().__init__(
            path,
            f"{who} is writing a run into this folder; wait for it to finish or choose another --out",
        )


def _fmt_mm(p_m: np.ndarray) -> str:
    return "(" + ", ".join(f"{1e3 * x:.3f}" for x in p_m) + ") mm"


# --- closed-loop URDF import --------------------------------------------------------------------


class ClosedLoopError(PkmtolError):
    """A closed-loop URDF tree and its sidecar do not describe a mechanism pkmtol can cut into limbs.

    Attributes:
        path: The file at fault (the URDF or the sidecar).
        culprit: Name of the offending frame, joint, link or key.
    """

    def __init__(self, path: Path | str, culprit: str, problem: str) -> None:
        self.path = Path(path)
        self.culprit = culprit
        super().__init__(f"{self.path}: '{culprit}': {problem}")


class ClosureFrameError(ClosedLoopError):
    """A closure frame is missing, has no partner, or is not listed in the sidecar."""


class UnknownMotorError(ClosedLoopError):
    """A motor joint listed in the sidecar (``name_mot``) is not a joint of the tree.

    Attributes:
        available: The joint names the tree does have.
    """

    def __init__(self, path: Path | str, joint: str, available: Sequence[str]) -> None:
        self.available = tuple(available)
        super().__init__(
            path,
            joint,
            "motor joint listed in name_mot is not a joint of the tree "
            f"(joints: {', '.join(self.available)}); fix the name in the sidecar",
        )


class NoLoopError(ClosedLoopError):
    """The tree has no closure frames and the sidecar lists no loop: nothing to close."""

    def __init__(self, path: Path | str, problem: str) -> None:
        super().__init__(path, "closed_loop", problem)


class PointLoopError(ClosedLoopError):
    """A loop closes on a point only (a URDF ``'3d'`` loop, an MJCF ``<connect>``).

    pkmtol's limbs close on the platform's full pose (6D); write the ball joint at the closure as
    three revolute joints ending in the limb-side frame and close the loop in 6D.
    """


# --- MJCF import ---------------------------------------------------------------------------------


class MJCFError(ClosedLoopError):
    """An MJCF file is missing, malformed, unreadable by Pinocchio, or uses what pkmtol cannot take.

    Attributes:
        path: The MJCF file.
        culprit: The offending element, body, joint, actuator or key.
    """


class LostElementError(MJCFError):
    """Pinocchio's MJCF reader would drop bodies or joints of the file (they would silently vanish).

    Attributes:
        lost: Names of the bodies and joints that would be lost.
    """

    def __init__(self, path: Path | str, culprit: str, lost: Sequence[str], problem: str) -> None:
        self.lost = tuple(lost)
        super().__init__(path, culprit, problem)


class MultiDofJointError(MJCFError):
    """A ``ball`` or ``free`` joint, or a body with several joints (Pinocchio makes them one composite)."""


class UnsupportedEqualityError(MJCFError):
    """An ``<equality>`` element pkmtol cannot turn into a loop (``joint``, ``tendon``, ``distance``, ...)."""


class TendonError(MJCFError):
    """The file has tendons (or an actuator on a tendon): pkmtol's mechanisms have none."""


# --- presentation -------------------------------------------------------------------------------


class ViewerError(PkmtolError):
    """The 3D viewer cannot run: meshcat is missing, or its server did not start."""


class FiguresError(PkmtolError):
    """Figures cannot be made: matplotlib is missing (``pip install 'pkmtol[plots]'``)."""


# --- execution and studies ------------------------------------------------------------------------


class ExecutorError(PkmtolError):
    """The executor cannot run: a bad worker count, Dask missing, or no scheduler at the address.

    Attributes:
        culprit: The offending setting (``workers``, ``dask``, ``n_chunks``).
    """

    def __init__(self, culprit: str, problem: str) -> None:
        self.culprit = culprit
        super().__init__(f"{culprit}: {problem}")


class SweepSpecError(PkmtolError):
    """A ``--vary KEY=START:STOP:N`` specification of ``pkmtol sweep`` cannot be used.

    Attributes:
        spec: The specification as given.
    """

    def __init__(self, spec: str, problem: str) -> None:
        self.spec = spec
        super().__init__(f"--vary {spec!r}: {problem}")


# --- calibration ------------------------------------------------------------------------------


class CalibrationError(PkmtolError):
    """Base class of calibration failures (plan, measurements, identification)."""


class IdentificationError(CalibrationError):
    """The identification cannot proceed: the model cannot be solved at a pose, or no step helps."""


class MeasurementFileError(CalibrationError):
    """A measurement or plan file is malformed: a column, a unit, a value or a row is wrong.

    Attributes:
        path: The file.
        line: 1-based line of the culprit (0 for the header or the whole file).
        column: The column at fault ("" when the whole row or file is).
    """

    def __init__(self, path: Path | str, line: int, column: str, problem: str) -> None:
        self.path = Path(path)
        self.line = line
        self.column = column
        where = f" line {line}" if line else ""
        col = f" column '{column}'" if column else ""
        super().__init__(f"{self.path}:{where}{col}: {problem}".replace("::", ":", 1))


class NoiseFloorError(CalibrationError):
    """The calibration's measurement noise alone exceeds the accuracy target at the design β.

    Attributes:
        noise_m: Tracker noise σ_m per coordinate [m].
        poses: Calibration poses N.
        floor: The smallest target FOSM can meet with this noise (``β √v``) [m or rad].
        target: The target asked for [m or rad].
    """

    def __init__(
        self, noise_m: float, poses: int, floor: float, target: float, beta: float, what: str = "Δλ at P"
    ) -> None:
        self.noise_m, self.poses, self.floor, self.target = noise_m, poses, floor, target
        unit, f = ("µrad", 1e6) if what != "Δλ at P" else ("µm", 1e6)
        super().__init__(
            f"the tracker noise of {1e3 * noise_m:.4g} mm per coordinate over {poses} calibration poses "
            f"alone puts a floor of {f * floor:.4g} {unit} on {what} at β = {beta:g}, above the target "
            f"{f * target:.4g} {unit}: no tolerance can meet it — measure more poses (D-optimal), use a "
            "more precise tracker, or relax the target or β"
        )
