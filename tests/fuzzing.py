"""A seeded, bounded fuzzer of robot folders: mutated mechanism.toml and URDF bytes and values.

Each case copies a bundled robot, applies one to three mutations chosen by a seeded generator
(:func:`mutate`) — byte flips, non-UTF-8 bytes, insertions, deletions, truncations; numbers
replaced by ``nan``/``inf``/huge/negative/strings; keys misspelt; lines dropped or repeated; URDF
attributes (origins, axes, limits, types, link names) replaced; elements dropped, repeated, or a
``<mimic>`` added — then loads it and, when it loads, closes it at home and solves the inverse
kinematics and the error model at two grid points (:func:`exercise`). The outcome is ``ok``, the
name of the :class:`~pkmtol.exceptions.PkmtolError` subclass raised, or ``BUG`` for any other
exception; each case is timed (a case over :data:`HANG_S` counts as a hang).

Used by ``tests/test_fuzz.py`` (2,000 cases in CI) and ``scripts/fuzz_inputs.py`` (any number).
"""

from __future__ import annotations

import re
import shutil
import signal
import time
import traceback
import warnings
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pkmtol.error_model.parameters import default_set, parameter_set
from pkmtol.error_model.sweep import sweep
from pkmtol.exceptions import PkmtolError, PkmtolWarning
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.loader import load_mechanism

REPO = Path(__file__).resolve().parents[1]
ROBOTS = ("r2rps_ups", "sprint_z3", "exechon", "tricept")
#: A case taking longer than this [s] is a hang.
HANG_S = 10.0

NUMBER = re.compile(rb"(?<![\w.])-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")
TOML_VALUES = [b"nan", b"inf", b"-inf", b"0", b"-1", b"1e308", b"-1e308", b"1e-320", b"2.5",
               b"100000000000", b'"x"', b"true", b"[]", b"[1, 2]", b"{}", b"0.0", b"-0.0", b"1e6",
               b'"50"', b'"1 um"', b"3"]  # fmt: skip
XML_VALUES = [b"nan", b"inf", b"-inf", b"0 0 0", b"0 0 5", b"1 2", b"a b c", b"", b"-1e308", b"1e308 0 0",
              b"0 0 1", b"1 0 0", b"0.7 0.7 0", b"-1", b"3.5", b"base", b"platform", b"revolute",
              b"prismatic", b"continuous", b"fixed", b"floating", b"\xff\xfe", b"&amp;",
              b"1 0 0 0"]  # fmt: skip
XML_ATTR = re.compile(rb'(\w+)="([^"]*)"')
XML_ELEMENT = re.compile(
    rb"<(joint|link|limit|axis|origin|parent|child|visual|geometry)\b[^>]*?(/>|>.*?</\1>)", re.S
)
TOML_KEY = re.compile(rb"^([A-Za-z_]+)\s*=", re.M)


@dataclass
class Report:
    """What a fuzzing run found.

    Attributes:
        cases: Cases run.
        outcomes: Count per outcome (``ok``, an exception class name, ``BUG``).
        bugs: ``(case, traceback)`` of every non-pkmtol exception.
        slowest_s: Longest case [s].
        hangs: Cases over :data:`HANG_S`.
    """

    cases: int = 0
    outcomes: Counter[str] = field(default_factory=Counter)
    bugs: list[tuple[int, str]] = field(default_factory=list)
    slowest_s: float = 0.0
    hangs: list[int] = field(default_factory=list)


class Hang(Exception):
    """Raised by the alarm when a case runs past :data:`HANG_S`."""


def _alarm(signum: int, frame: object) -> None:
    raise Hang


def mutate_bytes(data: bytes, rng: np.random.Generator) -> bytes:
    """One byte-level mutation: flip, insert (often non-UTF-8), delete, duplicate or truncate."""
    n = len(data)
    if n == 0:
        return bytes(rng.integers(0, 256, 4, dtype=np.uint8))
    i = int(rng.integers(0, n))
    op = int(rng.integers(0, 5))
    if op == 0:
        return data[:i] + bytes([int(rng.integers(0, 256))]) + data[i + 1 :]
    if op == 1:
        junk = bytes(rng.integers(0x80, 0x100, int(rng.integers(1, 4)), dtype=np.uint8))
        return data[:i] + junk + data[i:]
    j = min(n, i + int(rng.integers(1, 40)))
    if op == 2:
        return data[:i] + data[j:]
    if op == 3:
        return data[:j] + data[i:j] + data[j:]
    return data[:i]


def mutate_toml(data: bytes, rng: np.random.Generator) -> bytes:
    """One value-level mutation of a TOML text: a number, a key, or a line."""
    op = int(rng.integers(0, 6))
    if op <= 1 or op == 5:
        nums = list(NUMBER.finditer(data))
        if nums:
            m = nums[int(rng.integers(0, len(nums)))]
            if op == 5:  # a plausible value: the number scaled (the file stays valid, the robot changes)
                value = repr(float(m.group(0)) * float(rng.uniform(0.3, 3.0))).encode()
            else:
                value = TOML_VALUES[int(rng.integers(0, len(TOML_VALUES)))]
            return data[: m.start()] + value + data[m.end() :]
    if op == 2:
        keys = list(TOML_KEY.finditer(data))
        if keys:
            m = keys[int(rng.integers(0, len(keys)))]
            key = bytearray(m.group(1))
            k = int(rng.integers(0, len(key)))
            key = key[:k] + key[k + 1 :] if rng.random() < 0.5 else key[:k] + b"x" + key[k:]
            return data[: m.start(1)] + bytes(key) + data[m.end(1) :]
    lines = data.split(b"\n")
    k = int(rng.integers(0, len(lines)))
    if op == 3:
        del lines[k]
    else:
        lines.insert(k, lines[int(rng.integers(0, len(lines)))])
    return b"\n".join(lines)


def mutate_urdf(data: bytes, rng: np.random.Generator) -> bytes:
    """One value-level mutation of a URDF: an attribute value, an element dropped or repeated, a mimic."""
    op = int(rng.integers(0, 4))
    if op <= 1:
        attrs = list(XML_ATTR.finditer(data))
        if attrs:
            m = attrs[int(rng.integers(0, len(attrs)))]
            value = XML_VALUES[int(rng.integers(0, len(XML_VALUES)))]
            return data[: m.start(2)] + value + data[m.end(2) :]
    elements = list(XML_ELEMENT.finditer(data))
    if not elements:
        return data
    m = elements[int(rng.integers(0, len(elements)))]
    if op == 2:
        return (
            data[: m.start()] + data[m.end() :]
            if rng.random() < 0.5
            else data[: m.end()] + m.group(0) + data[m.end() :]
        )
    joints = [e for e in elements if e.group(1) == b"joint" and e.group(2) != b"/>"]
    if joints:
        j = joints[int(rng.integers(0, len(joints)))]
        end = data.index(b"</joint>", j.start())
        return data[:end] + b'<mimic joint="x"/>' + data[end:]
    return data


def mutate(folder: Path, rng: np.random.Generator) -> list[str]:
    """Apply one to three mutations to the robot in ``folder``; returns what was done (for reports)."""
    files = sorted(folder.glob("*.urdf"))
    done = []
    for _ in range(int(rng.integers(1, 4))):
        if rng.random() < 0.5:
            path = folder / "mechanism.toml"
            kind = "toml"
        else:
            path = files[int(rng.integers(0, len(files)))]
            kind = "urdf"
        data = path.read_bytes()
        if rng.random() < 0.35:
            data, how = mutate_bytes(data, rng), "bytes"
        else:
            data, how = (mutate_toml(data, rng) if kind == "toml" else mutate_urdf(data, rng)), "value"
        path.write_bytes(data)
        done.append(f"{path.name}:{how}")
    return done


def exercise(folder: Path) -> None:
    """Load the robot; if it loads, close it at home and run the error model at two grid points."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PkmtolWarning)  # a warning is an accepted input
        mech = load_mechanism(folder)
    chain = ClosedChain(mech)
    chain.home()
    grid = mech.task_space.grid()
    sweep(mech, parameter_set(mech, default_set(mech)), grid[[0, len(grid) - 1]], chain)


def run_case(index: int, seed: int, workdir: Path) -> tuple[str, float, str | None]:
    """Case ``index`` of the run seeded ``seed``: ``(outcome, seconds, traceback or None)``."""
    rng = np.random.default_rng([seed, index])
    robot = ROBOTS[int(rng.integers(0, len(ROBOTS)))]
    folder = workdir / f"case{index}"
    shutil.copytree(REPO / "robots" / robot, folder)
    what = mutate(folder, rng)
    t0 = time.perf_counter()
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, HANG_S)
    try:
        exercise(folder)
        outcome, tb = "ok", None
    except Hang:
        outcome, tb = "HANG", f"{robot} {what}"
    except PkmtolError as err:
        outcome, tb = type(err).__name__, None
    except Exception:  # noqa: BLE001 - the fuzzer's job: every other exception is a bug to report
        outcome, tb = "BUG", f"{robot} {what}\n{traceback.format_exc()}"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
        shutil.rmtree(folder, ignore_errors=True)
    return outcome, time.perf_counter() - t0, tb


def fuzz(cases: int, seed: int, workdir: Path, start: int = 0) -> Report:
    """Run cases ``start .. start + cases - 1`` of the run seeded ``seed`` in ``workdir``."""
    report = Report()
    for i in range(start, start + cases):
        outcome, seconds, tb = run_case(i, seed, workdir)
        report.cases += 1
        report.outcomes[outcome] += 1
        report.slowest_s = max(report.slowest_s, seconds)
        if outcome == "BUG" and tb:
            report.bugs.append((i, tb))
        if outcome == "HANG" or seconds > HANG_S:
            report.hangs.append(i)
    return report
