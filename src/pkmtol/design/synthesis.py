"""Dimensional synthesis: the accuracy design over a grid of mechanism.toml numbers and D–H entries.

:func:`synthesize` varies numbers of a robot's ``mechanism.toml`` (``--vary KEY=START:STOP:N``;
several keys make a grid of variants). A key is a dotted path into the TOML document, with list
indices in brackets and a limb given by its index or name: ``reference_point.position_m[2]``,
``task_space.radius_m``, ``limbs[limb1].dh.links[0][2]``. Values are in the file's own units
(metres; degrees for D–H angles). A variant whose D–H table changed gets its limb URDF regenerated
in memory (:func:`pkmtol.model.dh.to_urdf`), exactly as ``scripts/dh_to_urdf.py`` writes it.

Per variant, on the :class:`pkmtol.executor.Executor` (one chunk per variant):

* reachability: the whole task-space grid is solved (else the first failure, e.g. a joint limit);
  the nominal ``home`` is re-closed first when the dimensions moved the limbs' platform frames apart;
* the worst σ[Δλ]: the analytic standard deviation of Δλ with every uncompensatable error
  ``~ N(0, 1)`` (SI units) at the grid's most sensitive pose;
* the design-β tolerances of the uncompensatable errors by the same stages as ``pkmtol allocate``
  (:func:`pkmtol.design.allocation.design_tolerances`: FOSM at that pose, a parameter without
  effect there sensitised at its own most sensitive pose, then the ``exact`` or ``cost`` method);
* σ[Δλ] over the grid (its maximum) when the reference design's tolerances are kept — the
  reference is the robot as its ``mechanism.toml`` gives it;
* the cost of the tolerances under the robot's cost model (:mod:`pkmtol.design.cost`; a free
  tolerance is priced at its process limit ``t_max``).
"""

from __future__ import annotations

import copy
import itertools
import math
import re
import time
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

import pkmtol.values as values
from pkmtol.design.allocation import design_tolerances
from pkmtol.design.cost import cost_model
from pkmtol.design.exact import CRITERIA
from pkmtol.design.modes import grid_model, mode_stage
from pkmtol.design.options import DEFAULT_CRITERION, DEFAULT_METHOD, METHODS
from pkmtol.design.pose_search import analytic_design_pose
from pkmtol.error_model.accuracy import grid_norm_moments
from pkmtol.error_model.parameters import default_set
from pkmtol.error_model.task import machine_parameter_set
from pkmtol.exceptions import (
    JointLimitError,
    KinematicsError,
    MechanismFormatError,
    PkmtolError,
    SweepSpecError,
)
from pkmtol.executor import Executor, imap_chunks
from pkmtol.kinematics.closed_chain import ClosedChain
from pkmtol.model.dh import to_urdf
from pkmtol.model.loader import load_mechanism, read_dh
from pkmtol.model.mechanism import Mechanism
from pkmtol.model.reading import TomlReader

#: Variants at most in one sweep (a guard against a typo such as N = 1e6).
MAX_VARIANTS = 1_000_000

_SPEC = re.compile(r"^\s*([^=\s]+)\s*=\s*([^:]+):([^:]+):([^:]+)\s*$")
_PART = re.compile(r"([^.\[\]]+)|\[([^\]]*)\]")


@dataclass(frozen=True)
class Vary:
    """One varied number: its key and its values.

    Attributes:
        key: Dotted path into ``mechanism.toml`` (``reference_point.position_m[2]``).
        values: The values it takes, in the file's units.
        spec: The specification it was read from (for messages).
    """

    key: str
    values: tuple[float, ...]
    spec: str = ""


def parse_vary(spec: str) -> Vary:
    """``KEY=START:STOP:N`` → :class:`Vary` with ``N`` evenly spaced values from START to STOP.

    >>> parse_vary("reference_point.position_m[2]=0.1:0.5:5").values
    (0.1, 0.2, 0.3, 0.4, 0.5)

    Raises:
        SweepSpecError: not of that form, a bound that is not a number, or N not an integer ≥ 1.
    """
    m = _SPEC.match(spec)
    if not m:
        raise SweepSpecError(spec, "expected KEY=START:STOP:N, e.g. reference_point.position_m[2]=0.1:0.5:5")
    key, start, stop, count = m.groups()
    try:
        lo, hi = float(start), float(stop)
    except ValueError:
        raise SweepSpecError(spec, f"START and STOP must be numbers, got {start!r} and {stop!r}") from None
    try:
        n = int(count)
    except ValueError:
        n = 0
    if n < 1 or not np.isfinite([lo, hi]).all():
        raise SweepSpecError(spec, f"N must be an integer ≥ 1 and START, STOP finite, got N = {count!r}")
    return Vary(key=key, values=tuple(float(v) for v in np.round(np.linspace(lo, hi, n), 12)), spec=spec)


def set_number(doc: dict[str, Any], key: str, value: float, spec: str | None = None) -> str | None:
    """Set the number at ``key`` of a TOML document to ``value``; the limb name if it is a D–H entry.

    Raises:
        SweepSpecError: the key does not exist or does not hold a number.
    """
    what = spec or key
    parts = [(a or None, b) for a, b in _PART.findall(key)]
    if not parts or "".join(f".{a}" if a else f"[{b}]" for a, b in parts).lstrip(".") != key:
        raise SweepSpecError(what, f"cannot read the key {key!r}; write it as a.b[2].c (see docs/cli.md)")
    node: Any = doc
    path: list[str] = []
    limb = None
    for pos, (name, index) in enumerate(parts):
        last = pos == len(parts) - 1
        if name is not None:
            if not isinstance(node, dict) or name not in node:
                have = ", ".join(sorted(node)) if isinstance(node, dict) else type(node).__name__
                raise SweepSpecError(
                    what, f"mechanism.toml has no key {'.'.join(path + [name])!r} (there: {have})"
                )
            step: Any = name
        else:
            if not isinstance(node, list):
                raise SweepSpecError(
                    what, f"{'.'.join(path) or 'the document'} is not a list; drop [{index}]"
                )
            step = _index(node, index, what, path)
            if path == ["limbs"]:
                limb = node[step].get("name", str(step))
        path.append(str(step))
        if last:
            unit = _unit_of(node[step])  # a quantity written with its unit ("150 mm"): kept in it
            if unit is not None:
                node[step] = f"{float(value):.12g} {unit}"
            elif isinstance(node[step], bool) or not isinstance(node[step], int | float):
                raise SweepSpecError(what, f"{key!r} holds {node[step]!r}, not a number")
            else:
                node[step] = float(value)
        else:
            node = node[step]
    return limb if limb is not None and len(parts) > 2 and parts[2][0] == "dh" else None


def _unit_of(value: Any) -> str | None:
    """The unit of a TOML string ``"<number> <unit>"`` (e.g. ``[tool] length = "150 mm"``), else None."""
    if not isinstance(value, str):
        return None
    number, _, unit = value.strip().partition(" ")
    try:
        float(number)
    except ValueError:
        return None
    return unit.strip() or None


def _index(node: list[Any], index: str, what: str, path: list[str]) -> int:
    if index.lstrip("-").isdigit():
        k = int(index)
        if -len(node) <= k < len(node):
            return k % len(node)
        raise SweepSpecError(what, f"{'.'.join(path)}[{index}] is out of range (length {len(node)})")
    names = [n.get("name") for n in node if isinstance(n, dict)]
    if index in names:
        return names.index(index)
    raise SweepSpecError(
        what, f"no entry {index!r} in {'.'.join(path)} (names: {', '.join(map(str, names))})"
    )


@dataclass(frozen=True, eq=False)
class Variant:
    """The accuracy design of one variant (SI units).

    Attributes:
        values: The varied numbers, key → value (the file's units).
        reachable: Whether the whole task-space grid was solved and separated.
        reason: Why not (empty when reachable).
        worst_point_m: Shape (3,): the most sensitive grid point (nan if unreachable) [m].
        sigma_unit_m: σ[Δλ] there with every η_c ~ N(0, 1) [m per unit error].
        sigma_reference_m: max over the grid of σ[Δλ] with the reference design's tolerances [m]
            (nan if the variant's η_c differ from the reference's).
        names: The uncompensatable parameters.
        units: Their units (``m`` or ``rad``).
        tolerances: Shape (len(names),): the design-β tolerances of ``allocate`` with the sweep's
            method and criterion [m or rad] (inf: free).
        cost: Cost of the tolerances under the cost model.
        seconds: Wall time of the evaluation [s].
    """

    values: dict[str, float]
    reachable: bool
    reason: str = ""
    worst_point_m: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    sigma_unit_m: float = float("nan")
    sigma_reference_m: float = float("nan")
    names: tuple[str, ...] = ()
    units: tuple[str, ...] = ()
    tolerances: np.ndarray = field(default_factory=lambda: np.zeros(0))
    cost: float = float("nan")
    seconds: float = 0.0


@dataclass(frozen=True, eq=False)
class Synthesis:
    """A sweep over design variants.

    Attributes:
        robot: The robot's name.
        varies: The varied keys and their values.
        parameter_set: ``dh`` or ``urdf``.
        design_beta: β of the tolerances (the robot's design β unless one was given; a variant
            of ``design.design_beta`` uses its own).
        reference: The robot as given (its tolerances feed ``sigma_reference_m``).
        variants: One per combination of the values, the last key varying fastest.
        executor: Where the variants ran.
        method: The design method of the tolerances (as ``allocate --method``).
        criterion: Its criterion (``exact``).
    """

    robot: str
    varies: tuple[Vary, ...]
    parameter_set: str
    design_beta: float
    reference: Variant
    variants: tuple[Variant, ...]
    executor: str
    method: str = DEFAULT_METHOD
    criterion: str = DEFAULT_CRITERION


@dataclass(frozen=True, eq=False)
class _Task:
    """One variant to evaluate: the robot's TOML and URDF texts, and the numbers to change in it."""

    folder: Path
    doc: dict[str, Any]
    urdf_texts: dict[str, str]
    values: dict[str, float]
    kind: str
    beta: float | None
    reference_names: tuple[str, ...]
    reference_tolerances: np.ndarray
    method: str = DEFAULT_METHOD
    criterion: str = DEFAULT_CRITERION


def synthesize(
    folder: Path | str,
    varies: Sequence[Vary],
    kind: str | None = None,
    beta: float | None = None,
    executor: Executor | None = None,
    progress: Any = None,
    tool_scope: str | None = None,
    method: str = DEFAULT_METHOD,
    criterion: str = DEFAULT_CRITERION,
) -> Synthesis:
    """Evaluate every variant of ``varies`` (their Cartesian product) and the reference design.

    Args:
        folder: The robot folder.
        varies: The varied keys (see :func:`parse_vary`).
        kind: Parameter set (default: ``dh`` when every limb has a D–H table).
        beta: β of the tolerances (default: each variant's design β, ``design.design_beta``).
        executor: Where the variants run (None: serial).
        progress: Called with the number of variants done after each one (e.g. a progress bar).
        tool_scope: A hybrid's compensation scope (``[tool] compensation``; default the file's).
        method: The design method, as ``allocate --method`` (default ``DEFAULT_METHOD``).
        criterion: Where ``exact`` meets R*, as ``allocate --criterion`` (default ``every``).

    Raises:
        SweepSpecError: a key does not exist or holds no number, or too many variants.
        PkmtolError: the robot as given cannot be loaded or its design fails.
    """
    values.choice("method", method, METHODS)
    values.choice("criterion", criterion, CRITERIA)
    folder = Path(folder)
    nominal = load_mechanism(folder)
    doc = read_doc(folder)
    if tool_scope is not None and isinstance(doc.get("tool"), dict):
        doc["tool"]["compensation"] = tool_scope  # --compensate-with
    kind = kind or default_set(nominal)
    texts = {lb.name: lb.urdf_path.read_text(encoding="utf-8") for lb in nominal.limbs if lb.urdf_path}
    count = math.prod(len(v.values) for v in varies) if varies else 0  # Python ints: no overflow
    if count > MAX_VARIANTS:
        raise SweepSpecError(
            " ".join(v.key for v in varies), f"{count} variants > {MAX_VARIANTS}; use fewer values"
        )
    check_keys(doc, varies)
    base = _Task(folder, doc, texts, {}, kind, beta, (), np.zeros(0), method, criterion)
    reference = evaluate_variant(base)
    if not reference.reachable:
        raise KinematicsError(f"the robot as given fails: {reference.reason}")
    ref = replace(base, reference_names=reference.names, reference_tolerances=reference.tolerances)
    keys = [v.key for v in varies]
    tasks = [
        replace(ref, values=dict(zip(keys, combo, strict=True)))
        for combo in itertools.product(*(v.values for v in varies))
    ]
    variants = []
    for done, result in enumerate(imap_chunks(evaluate_variant, tasks, executor), start=1):
        variants.append(result)
        if progress is not None:
            progress(done)
    return Synthesis(
        robot=nominal.name,
        varies=tuple(varies),
        parameter_set=kind,
        design_beta=nominal.design_beta if beta is None else float(beta),
        reference=reference,
        variants=tuple(variants),
        executor=(executor or Executor()).describe(),
        method=method,
        criterion=criterion,
    )


def check_keys(doc: dict[str, Any], varies: Sequence[Vary]) -> None:
    """Raise :class:`SweepSpecError` unless every key of ``varies`` holds a number of ``doc`` (once)."""
    keys = [v.key for v in varies]
    if len(set(keys)) != len(keys):
        raise SweepSpecError(
            " ".join(v.spec or v.key for v in varies), "a key is varied twice; give each key once"
        )
    for v in varies:
        set_number(copy.deepcopy(doc), v.key, v.values[0], v.spec or None)


def read_doc(folder: Path | str) -> dict[str, Any]:
    """The parsed ``mechanism.toml`` of a robot folder (MechanismFormatError if unreadable)."""
    path = Path(folder) / "mechanism.toml"
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise MechanismFormatError(path, "-", f"cannot read it: {err}") from err


def variant_mechanism(
    folder: Path, doc: dict[str, Any], urdf_texts: dict[str, str], values: dict[str, float] | None = None
) -> Mechanism:
    """The mechanism of a TOML document with ``values`` set, closed at home.

    A limb whose D–H table changed gets its URDF made from the table in memory. When the nominal
    ``home`` no longer closes (changed dimensions), it is re-closed: the passive joints with the
    actuators held, or, failing that, every joint to put P at the first grid point.

    Raises:
        PkmtolError: the document or a regenerated URDF is unusable, or no closed configuration
            is found near the nominal ``home``.
    """
    doc = copy.deepcopy(doc)
    changed = {set_number(doc, key, x) for key, x in (values or {}).items()} - {None}
    texts = dict(urdf_texts)
    path = folder / "mechanism.toml"
    for i, ld in enumerate(doc.get("limbs", [])):
        if isinstance(ld, dict) and "dh" in ld and ld.get("name") in changed:
            table = read_dh(TomlReader(path, ld, prefix=f"limbs[{i}]."))
            base, platform = doc.get("base_link", "base"), doc.get("platform_link", "platform")
            texts[ld["name"]] = to_urdf(table, ld["name"], base, platform, ld["name"])
    mech = load_mechanism(folder, doc=doc, urdf_texts=texts, check_home_closure=False)
    chain = ClosedChain(mech)
    try:
        q = chain.home()
    except KinematicsError:
        raw = np.concatenate([lb.home for lb in mech.limbs])
        q = chain.inverse(mech.task_space.grid()[0], raw).q_all
    split = np.split(q, chain.offsets[1:-1])
    limbs = [replace(lb, home=qi) for lb, qi in zip(mech.limbs, split, strict=True)]
    closed = Mechanism.from_limbs(
        mech.name,
        limbs,
        mech.reference_point_m,
        mech.task_space,
        mech.target_m,
        mech.betas,
        mech.design_beta,
        root=mech.root,
        description=mech.description,
        extra=mech.extra,
    )
    return replace(closed, tool=mech.tool, tool_directions=mech.tool_directions)  # a hybrid's tool chain


def evaluate_variant(task: _Task) -> Variant:
    """The accuracy design of one variant (a chunk of :func:`synthesize`)."""
    t0 = time.perf_counter()
    try:
        mech = variant_mechanism(task.folder, task.doc, task.urdf_texts, task.values)
        pset = machine_parameter_set(mech, task.kind)  # a hybrid: with its tool's, at the TCP
        model = grid_model(mech, pset)
    except PkmtolError as err:
        return Variant(
            values=task.values, reachable=False, reason=_reason(err), seconds=time.perf_counter() - t0
        )
    beta = mech.design_beta if task.beta is None else task.beta
    betas = tuple(sorted(set(mech.betas) | {beta}))
    setup = mode_stage(mech, pset, model, "ideal", None, mech.target_m, beta)  # the sweep's mode
    unc = setup.columns
    J = setup.grid_maps.position[:, :, unc]
    sigma = grid_norm_moments(J)[:, 1]
    worst = analytic_design_pose(J)
    grid = model.grid
    try:  # the tolerances stage of `pkmtol allocate`
        tol = design_tolerances(
            mech, pset, grid, setup.grid_maps, unc, worst, mech.target_m, betas, beta, task
        ).sigma
    except PkmtolError as err:
        return Variant(
            values=task.values, reachable=False, reason=_reason(err), seconds=time.perf_counter() - t0
        )
    names = tuple(pset.names[i] for i in unc)
    sigma_ref = float("nan")
    if task.reference_names == names and names:
        ref = np.where(np.isfinite(task.reference_tolerances), task.reference_tolerances, 0.0)
        sigma_ref = float(grid_norm_moments(J, ref)[:, 1].max())
    cost = cost_model([pset.parameters[i] for i in unc], mech.extra.get("cost"))
    return Variant(
        values=task.values,
        reachable=True,
        worst_point_m=grid.points_m[worst].copy(),
        sigma_unit_m=float(sigma[worst]),
        sigma_reference_m=sigma_ref,
        names=names,
        units=tuple(pset.units[i] for i in unc),
        tolerances=tol,
        cost=cost.cost(np.where(np.isfinite(tol), tol, cost.t_max_si)) if unc.size else 0.0,
        seconds=time.perf_counter() - t0,
    )


def _reason(err: PkmtolError) -> str:
    if isinstance(err, JointLimitError):
        return f"joint {err.joint} out of its limits"
    return f"{type(err).__name__}: {err}"
