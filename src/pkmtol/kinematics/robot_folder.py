"""A generated robot folder that passes ``pkmtol check``: written beside its destination, then moved in.

:func:`new_robot` is what ``pkmtol new <family>`` runs: the family's robot with the given
dimensions (:mod:`pkmtol.model.families`) is written as ``mechanism.toml`` and limb URDFs
(generated from the D–H tables, :mod:`pkmtol.model.robot_files`) into a temporary folder next to
the destination, loaded (every check of loading, the D–H tables against the URDFs included) and
checked over its task space (:func:`~pkmtol.kinematics.check.check_mechanism`). Only a robot with
no problem is renamed into place; otherwise nothing is left behind.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pkmtol.exceptions import OutputError, RobotCheckError
from pkmtol.kinematics.check import CheckReport, check_mechanism
from pkmtol.model.families import draft
from pkmtol.model.loader import load_mechanism
from pkmtol.model.robot_files import command_line, render_toml, urdfs_from_toml


@dataclass(frozen=True)
class NewRobot:
    """A robot folder written by :func:`new_robot`.

    Attributes:
        folder: The folder.
        files: The files written (mechanism.toml first).
        command: The ``pkmtol new`` command line that writes it again (every dimension spelled out).
        report: Its check (mobility, constraints, reachability).
    """

    folder: Path
    files: tuple[Path, ...]
    command: str
    report: CheckReport


def new_robot(
    family: str, out: Path | str, name: str | None = None, progress: bool = False, **dimensions: Any
) -> NewRobot:
    """Write a checked robot folder of ``family`` with ``dimensions`` into ``out`` (new or empty).

    Args:
        family: One of :data:`pkmtol.model.families.FAMILIES`.
        out: The robot folder to create.
        name: The mechanism's name (default: the folder's name).
        progress: Show a progress bar while checking the task space.
        **dimensions: Dimensions by name [m] (see the family function); the rest keep their defaults.

    Raises:
        InvalidArgumentError: an unknown family or dimension, or dimensions that cannot make it.
        OutputError: ``out`` exists and is not an empty folder, or cannot be written.
        RobotCheckError: the robot does not pass the check (nothing is written).
    """
    robot = draft(family, **dimensions)
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise OutputError(out, "exists and is not an empty folder; choose a new folder (nothing was written)")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o777 & ~umask)  # mkdtemp makes it 0700; the robot folder is an ordinary one
    except OSError as err:
        raise OutputError(out, f"{err.strerror or err}; choose another folder") from err
    try:
        command = command_line(robot, str(out))
        (tmp / "mechanism.toml").write_text(render_toml(robot, name or out.name, command), encoding="utf-8")
        urdfs = urdfs_from_toml(tmp)
        for path, text in urdfs.items():
            path.write_text(text, encoding="utf-8")
        report = check_mechanism(load_mechanism(tmp), progress=progress)
        if report.problems:
            raise RobotCheckError(family, report.problems)
        with contextlib.suppress(FileNotFoundError):
            out.rmdir()  # an empty folder given as the destination
        os.replace(tmp, out)
    except OSError as err:
        raise OutputError(out, f"{err.strerror or err}; choose another folder") from err
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    files = (out / "mechanism.toml", *(out / p.name for p in urdfs))
    return NewRobot(folder=out, files=files, command=command, report=report)
