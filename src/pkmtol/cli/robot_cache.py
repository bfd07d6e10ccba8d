"""Per-robot work that ``pkmtol calibrate`` computes once: the loaded mechanism and its grid sweep.

A ``calibrate --measurements`` run needs the task-space grid sweep twice (the class of every
parameter, then the nominal solutions and the pool's identifiability), and every run loads the
robot. Both are kept here, so that one run sweeps the grid once, and a process that runs the
command line many times (a notebook, the tests, ``scripts/fuzz_calibrate.py``) loads and sweeps
each robot once.

A loaded robot is reused only while its files are unchanged: the key is the size and modification
time of every file in the robot folder and of every limb URDF the mechanism was read from (a
file outside the folder included), checked again at every use.
"""

from __future__ import annotations

import weakref
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

from pkmtol.error_model.parameters import ParameterSet
from pkmtol.error_model.sweep import Sweep
from pkmtol.error_model.task import grid_sweep
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.loader import load_mechanism
from pkmtol.model.mechanism import Mechanism

#: Robots kept at once (the least recently used goes first).
KEPT_ROBOTS = 4
#: A robot folder with more files than this is not kept (its key would cost a walk of them all).
MAX_FOLDER_FILES = 2000

_Stamp = tuple[tuple[str, int, int], ...]


@dataclass(frozen=True, eq=False)
class RobotGrid:
    """A mechanism's grid sweep for one parameter set.

    Attributes:
        chain: The solver workspace the sweep used (for later solves of the same mechanism).
        sweep: The error model over the task-space grid (:func:`grid_sweep`).
        classes: The class of every parameter over the grid (:meth:`Sweep.classify`).
    """

    chain: ClosedChain
    sweep: Sweep
    classes: list[str]


_robots: OrderedDict[str, tuple[_Stamp, Mechanism]] = OrderedDict()
_grids: weakref.WeakKeyDictionary[Mechanism, dict[tuple[str, ...], RobotGrid]] = weakref.WeakKeyDictionary()


def _stamp(paths: list[Path]) -> _Stamp:
    out = []
    for p in sorted(set(paths)):
        try:
            st = p.stat()
        except OSError:
            out.append((str(p), -1, -1))
            continue
        out.append((str(p), st.st_size, st.st_mtime_ns))
    return tuple(out)


def _folder_files(folder: Path) -> list[Path] | None:
    files: list[Path] = []
    try:
        for p in folder.rglob("*"):
            if p.is_file():
                files.append(p)
                if len(files) > MAX_FOLDER_FILES:
                    return None
    except OSError:
        return None
    return files


def _sources(mechanism: Mechanism) -> list[Path]:
    return [limb.urdf_path.resolve() for limb in mechanism.limbs if limb.urdf_path is not None]


def mechanism(folder: Path) -> Mechanism:
    """:func:`load_mechanism` of ``folder``, or the same mechanism again while its files are unchanged.

    Raises:
        The errors of :func:`load_mechanism` (nothing is kept then).
    """
    try:
        key = str(Path(folder).resolve())
    except (OSError, RuntimeError, ValueError, TypeError):
        return load_mechanism(folder)
    files = _folder_files(Path(key))
    kept = _robots.get(key)
    if kept is not None and files is not None:
        stamp, mech = kept
        if _stamp(files + _sources(mech)) == stamp:
            _robots.move_to_end(key)
            return mech
    mech = load_mechanism(folder)
    if files is not None:
        _robots[key] = (_stamp(files + _sources(mech)), mech)
        _robots.move_to_end(key)
        while len(_robots) > KEPT_ROBOTS:
            _robots.popitem(last=False)
    return mech


def robot_grid(mech: Mechanism, pset: ParameterSet) -> RobotGrid:
    """The grid sweep of ``mech`` for ``pset``, computed on the first call for this mechanism object."""
    per_set = _grids.setdefault(mech, {})
    key = (pset.kind, *pset.names)
    got = per_set.get(key)
    if got is None:
        chain = ClosedChain(mech)
        sw = grid_sweep(mech, pset, chain)  # a hybrid's: TCP × tool axis
        got = per_set[key] = RobotGrid(chain, sw, sw.classify())
    return got


def clear() -> None:
    """Forget every kept robot and grid sweep."""
    _robots.clear()
    _grids.clear()
