"""``load_mechanism``: a robot folder (``mechanism.toml`` and its limbs) to a :class:`Mechanism`."""

from __future__ import annotations

import dataclasses
import math
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

import pkmtol.values as values
from pkmtol.exceptions import InvalidRequestError, MechanismFormatError
from pkmtol.model import closed_loop, mjcf
from pkmtol.model.dh import DHTable, check_dh_matches
from pkmtol.model.drawing import read_drawing
from pkmtol.model.keys import check_keys
from pkmtol.model.limb import make_limb
from pkmtol.model.mechanism import DEFAULT_BETAS, Mechanism
from pkmtol.model.reading import TomlReader, check_finite, load_urdf, read_text
from pkmtol.model.taskspace import MAX_GRID_POINTS, TaskSpace
from pkmtol.model.tool_reading import TOOL_TASK_KEYS, read_tool, read_tool_directions
from pkmtol.units import parse_angle, parse_length
from pkmtol.values import MAX_LENGTH_M


def load_mechanism(
    folder: Path | str,
    doc: Mapping[str, Any] | None = None,
    urdf_texts: Mapping[str, str] | None = None,
    check_home_closure: bool = True,
) -> Mechanism:
    """Load ``<folder>/mechanism.toml`` and its limbs.

    The limbs come from one of: ``[[limbs]]`` tables (one URDF each), a ``[closed_loop]`` table
    (one URDF tree with closure frames, docs/closed-loop.md) or an ``[mjcf]`` table (one MJCF file
    whose loops are ``<weld>`` equalities, docs/closed-loop.md, "MJCF").

    Args:
        folder: The robot folder.
        doc: The parsed TOML to use instead of the file's (a design variant); paths in it are
            relative to ``folder``.
        urdf_texts: Per limb name, URDF text to use instead of the limb's file.
        check_home_closure: Check that the platform frames coincide at ``home`` (see
            :meth:`Mechanism.from_limbs`).

    Raises:
        InvalidArgumentError: ``folder`` is not a path.
        MechanismFormatError: the folder has no mechanism.toml, or a key is missing, mistyped,
            not finite (``nan``, ``inf``) or unknown (:class:`UnknownKeyError`, with a "did you
            mean"; the known keys are in :mod:`pkmtol.model.keys`).
        URDFError: a limb URDF is missing, malformed or unusable; :class:`DHMismatchError` when it
            disagrees with the limb's ``[limbs.dh]`` table.
        UnknownJointError: an actuated joint is not in its limb.
        PlatformMismatchError: the limbs' platform frames do not coincide at ``home``.
        ClosedLoopError, MJCFError (and subclasses): a tree or MJCF file pkmtol cannot cut into limbs.
    """
    folder = values.path("folder", folder, "the path of a robot folder, e.g. 'robots/r2rps_ups'")
    path = folder / "mechanism.toml"
    values.optional(values.instance, "doc", doc, Mapping, "a mapping (the parsed mechanism.toml) or None")
    if urdf_texts is not None:
        values.instance("urdf_texts", urdf_texts, Mapping, "a mapping of limb names to URDF texts, or None")
        for key, text in urdf_texts.items():
            values.text(f"urdf_texts[{key!r}]", text)
    values.flag("check_home_closure", check_home_closure)
    if doc is not None:
        return _from_doc(folder, path, dict(doc), urdf_texts or {}, check_home_closure)
    if not folder.is_dir():
        raise MechanismFormatError(
            path, "-", f"'{folder}' is not a folder; give a robot folder such as robots/r2rps_ups"
        )
    if not path.is_file():
        raise MechanismFormatError(
            path, "-", "file not found; a robot folder needs a mechanism.toml (see docs/mechanism-format.md)"
        )
    text = read_text(path, lambda problem: MechanismFormatError(path, "-", problem))
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise MechanismFormatError(path, "-", f"not valid TOML: {err}") from err
    return _from_doc(folder, path, doc, urdf_texts or {}, check_home_closure)


def _from_doc(
    folder: Path, path: Path, doc: dict[str, Any], urdf_texts: Mapping[str, str], check_home_closure: bool
) -> Mechanism:
    check_keys(path, doc)
    check_finite(path, doc)
    r = TomlReader(path, doc)
    name = r.get("name", str)
    if not name.strip():
        r.fail("name", "must not be empty")
    platform_link = r.get("platform_link", str, default="platform")
    r.get("base_link", str, default="base")
    r.get("description", str, default="")
    p_ref = r.lengths("reference_point.position_m", 3)
    kind = r.get("task.kind", str, default="position")
    if kind not in ("position", "planar", "tool"):
        r.fail(
            "task.kind",
            f"unknown task kind {kind!r}; supported: 'position' (of P), 'planar' (P in a plane, "
            "with task.normal) and 'tool' (the TCP of a [tool] chain)",
        )
    if (kind == "tool") != ("tool" in doc):
        r.fail(
            "task.kind" if "tool" in doc else "tool",
            "a [tool] table needs task.kind = 'tool' (the task is then the TCP)"
            if "tool" in doc
            else "task.kind = 'tool' needs a [tool] table (the tool chain on the platform)",
        )
    for key in TOOL_TASK_KEYS:
        if kind != "tool" and key in dict(doc.get("task") or {}):
            r.fail(f"task.{key}", "belongs to task.kind = 'tool' (the tool directions); remove it")
    task_space = read_task_space(r)
    normal = None
    if kind == "planar":
        normal = r.vector("task.normal", 3)
        if not np.all(np.isfinite(normal)) or np.linalg.norm(normal) < 1e-12:
            r.fail("task.normal", f"expected a non-zero [x, y, z] (frame K), got {normal.tolist()}")
        n = normal / np.linalg.norm(normal)
        heights = task_space.grid() @ n
        if np.ptp(heights) > 1e-9:
            r.fail(
                "task_space",
                f"a planar task needs a task space in one plane of normal {n.tolist()}; its points are "
                f"{np.ptp(heights) * 1e3:.3g} mm apart along the normal (give a cylinder with z_m = "
                "[z, z] and normal [0, 0, 1], or coplanar points)",
            )
    target = r.get("design.target", (str, float, int), default="0.05 mm")
    if not isinstance(target, str):
        r.fail(
            "design.target",
            f'write the unit with the number, e.g. target = "{target} mm" or "{target} um"',
        )
    try:
        target_m = parse_length(target, "design.target")
    except InvalidRequestError as err:
        r.fail("design.target", str(err))
    if target_m <= 0:
        r.fail("design.target", f"the required accuracy must be positive, got {target!r}")
    beta_arr = r.array("design.beta", default=list(DEFAULT_BETAS))
    if beta_arr.ndim != 1 or beta_arr.size == 0 or np.any(beta_arr <= 0):
        r.fail("design.beta", f"expected a list of positive numbers, got {beta_arr.tolist()!r}")
    betas = tuple(float(b) for b in beta_arr)
    design_beta = float(r.get("design.design_beta", (float, int), default=2.0))
    if design_beta <= 0:
        r.fail("design.design_beta", f"β must be positive, got {design_beta!r}")
    cost = read_cost(r)
    design_extra: dict[str, object] = {}
    alpha = r.get("design.orientation_target", str, default=None)
    if alpha is not None:
        try:
            design_extra["orientation_target_rad"] = parse_angle(alpha, "design.orientation_target")
        except InvalidRequestError as err:
            r.fail("design.orientation_target", str(err))
    if "tool_axis" in dict(doc.get("design") or {}):
        axis = r.vector("design.tool_axis", 3)
        if not np.all(np.isfinite(axis)) or np.linalg.norm(axis) < 1e-12:
            r.fail("design.tool_axis", f"expected a non-zero [x, y, z] (platform frame), got {axis.tolist()}")
        design_extra["tool_axis"] = tuple(float(x) for x in axis)
    forms = [k for k in ("limbs", "closed_loop", "mjcf") if k in doc]
    if len(forms) > 1:
        r.fail(
            forms[1], f"give the limbs one way: [[limbs]], [closed_loop] or [mjcf], not {' and '.join(forms)}"
        )
    limbs = []
    if "closed_loop" in doc:
        # one URDF tree with closure frame pairs (docs/closed-loop.md)
        limbs = closed_loop.limbs_from_toml(folder, r)
    elif "mjcf" in doc:
        # one MJCF file whose loops are <weld> equalities (docs/closed-loop.md, "MJCF")
        limbs = mjcf.limbs_from_toml(folder, r)
    limbs_doc = r.get("limbs", list) if not forms or forms == ["limbs"] else []
    if not limbs and len(limbs_doc) < 2:
        r.fail(
            "limbs", "a parallel mechanism needs at least two [[limbs]] (or a [closed_loop] or [mjcf] table)"
        )
    seen: dict[str, int] = {}
    for i, ld in enumerate(limbs_doc):
        if not isinstance(ld, dict):
            r.fail(f"limbs[{i}]", "expected a [[limbs]] table")
        lr = TomlReader(path, ld, prefix=f"limbs[{i}].")
        lname = lr.get("name", str)
        if not lname.strip():
            lr.fail("name", "must not be empty")
        if lname in seen:
            lr.fail("name", f"limb name {lname!r} is also used by limbs[{seen[lname]}]; names must be unique")
        seen[lname] = i
        urdf = folder / lr.get("urdf", str)
        actuated = lr.strings("actuated", default=[])
        home = lr.lengths("home") if "home" in ld else None
        if home is not None and home.ndim != 1:
            lr.fail("home", f"expected a list of numbers, one per joint, got {ld['home']!r}")
        dh = read_dh(lr) if "dh" in ld else None
        loops = read_loops(lr) if "loops" in ld else []
        model, visual = load_urdf(lname, urdf, urdf_texts.get(lname))
        limb = make_limb(lname, model, actuated, platform_link, home, urdf, dh, visual, loops)
        if dh is not None:
            check_dh_matches(limb, dh, f"python scripts/dh_to_urdf.py {folder}")
        limbs.append(limb)
    # [drawing]: the ±t convention, nominal sizes, feature lengths (docs/report.md); its keys are
    # model.drawing.TABLE_KEYS, registered in model/keys.py
    joints = [
        j for limb in limbs for j in (*limb.joint_names, limb.attach_name, *(lp.name for lp in limb.loops))
    ]
    drawing = read_drawing(r.get("drawing", dict, default={}), path, joints)
    mech = Mechanism.from_limbs(
        name,
        limbs,
        p_ref,
        task_space,
        target_m,
        betas,
        design_beta,
        root=folder,
        description=r.get("description", str, default=""),
        extra={
            "cost": cost,
            "calibration": r.get("calibration", dict, default={}),
            "design": design_extra,
            "drawing": drawing,
        },
        check_home_closure=check_home_closure,
        task_normal=normal,
    )
    if kind != "tool":
        return mech
    # [tool]: the serial chain on the platform; the task is its TCP (docs/hybrid.md)
    tool_doc = r.get("tool", dict)
    dh = read_dh(TomlReader(path, tool_doc, prefix="tool.")) if "dh" in tool_doc else None
    tool = read_tool(r, folder, platform_link, mech.n_actuators, dh)
    scope = r.get("tool.compensation", str, default="machine")
    if scope not in ("machine", "module"):
        r.fail("tool.compensation", f"expected 'machine' or 'module', got {scope!r}")
    extra = {**mech.extra, "tool_scope": scope}
    return dataclasses.replace(mech, tool=tool, tool_directions=read_tool_directions(r, tool), extra=extra)


def read_cost(r: TomlReader) -> dict:
    """The optional ``[cost]`` table (docs/theory.md): every field a finite number, checked here."""
    cost = r.get("cost", dict, default={})
    for kind in ("length", "angle"):
        for field in r.get(f"cost.{kind}", dict, default={}):
            r.get(f"cost.{kind}.{field}", (float, int))
    for name, entry in r.get("cost.parameters", dict, default={}).items():
        if not isinstance(entry, dict):
            r.fail(f'cost.parameters."{name}"', f"expected a table of cost fields, got {entry!r}")
        for field, value in entry.items():
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                r.fail(f'cost.parameters."{name}".{field}', f"expected a finite number, got {value!r}")
    return dict(cost)


def read_task_space(r: TomlReader) -> TaskSpace:
    """The ``[task_space]`` table: a cylinder grid or an explicit point list (frame K, metres)."""
    kind = r.get("task_space.kind", str)
    if kind == "cylinder":
        for key in ("points_m",):
            if key in r.get("task_space", dict):
                r.fail(f"task_space.{key}", "belongs to kind = 'points', not 'cylinder'; remove it")
        z = r.lengths("task_space.z_m", 2)
        rings_f = r.array("task_space.rings")
        whole = rings_f.ndim == 1 and rings_f.size > 0 and np.all(rings_f == np.round(rings_f))
        if not whole or np.any(rings_f < 1):
            r.fail("task_space.rings", f"expected a list of integers ≥ 1, got {rings_f.tolist()!r}")
        rings = tuple(int(x) for x in rings_f)
        radius = float(r.get("task_space.radius_m", (float, int)))
        if abs(radius) > MAX_LENGTH_M:
            r.fail("task_space.radius_m", f"a length beyond ±{MAX_LENGTH_M:g} m, got {radius!r}")
        if radius <= 0:
            r.fail("task_space.radius_m", f"the cylinder radius must be > 0, got {radius!r}")
        layers = int(r.get("task_space.layers", int))
        if layers < 1:
            r.fail("task_space.layers", f"need at least 1 layer, got {layers!r}")
        if z[1] < z[0]:
            r.fail("task_space.z_m", f"write it as [z_min, z_max], got {z.tolist()!r}")
        center = r.lengths("task_space.center_xy_m", 2, default=[0.0, 0.0])
        if layers * (1 + sum(rings)) > MAX_GRID_POINTS:
            n = layers * (1 + sum(rings))
            r.fail("task_space", f"{n} grid points; at most {MAX_GRID_POINTS} are allowed")
        return TaskSpace(
            kind="cylinder",
            radius_m=radius,
            z_range_m=(float(z[0]), float(z[1])),
            layers=layers,
            rings=rings,
            center_xy_m=(float(center[0]), float(center[1])),
        )
    if kind == "points":
        for key in ("radius_m", "z_m", "layers", "rings", "center_xy_m"):
            if key in r.get("task_space", dict):
                r.fail(f"task_space.{key}", "belongs to kind = 'cylinder', not 'points'; remove it")
        pts = r.lengths("task_space.points_m")
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
            r.fail("task_space.points_m", "need a list of [x, y, z] points in metres")
        if len(pts) > MAX_GRID_POINTS:
            r.fail("task_space.points_m", f"{len(pts)} points; at most {MAX_GRID_POINTS} are allowed")
        return TaskSpace(kind="points", points_m=pts)
    r.fail("task_space.kind", f"unknown kind {kind!r}; use 'cylinder' or 'points'")
    raise AssertionError  # unreachable


def read_loops(r: TomlReader) -> list[tuple[str, str, str, str]]:
    """A limb's ``[[limbs.loops]]`` tables: ``(name, frame_a, frame_b, kind)`` per internal loop.

    Keys: ``frames`` (two frame names of the limb's URDF that coincide when the loop is closed;
    the second one's placement error is the loop's), ``type`` (``"6d"``, the default, or ``"3d"``:
    only the frames' origins coincide), ``name`` (default ``loop<k>``).
    """
    out = []
    for k, entry in enumerate(r.get("loops", list)):
        if not isinstance(entry, dict):
            r.fail(f"loops[{k}]", f"expected a table (frames, type, name), got {entry!r}")
        lr = TomlReader(r.path, entry, prefix=f"{r.prefix}loops[{k}].")
        frames = lr.get("frames", list)
        if len(frames) != 2 or not all(isinstance(f, str) for f in frames):
            lr.fail("frames", f"expected two frame names [frame_a, frame_b], got {frames!r}")
        kind = lr.get("type", str, default="6d").lower()
        if kind not in ("6d", "3d"):
            lr.fail("type", f"unknown loop type {kind!r}; use '6d' (frames coincide) or '3d' (points meet)")
        out.append((lr.get("name", str, default=f"loop{k + 1}"), frames[0], frames[1], kind))
    return out


def read_dh(r: TomlReader) -> DHTable:
    """A limb's ``[limbs.dh]`` table (angles in degrees in the file, radians in the result)."""
    types = tuple(r.strings("dh.joint_types"))
    bad = [t for t in types if t not in ("R", "P")]
    if bad or not types:
        r.fail("dh.joint_types", f"expected a list of 'R' and 'P', one per joint, got {list(types)!r}")
    n = len(types)
    links = r.array("dh.links")
    if links.ndim == 2 and links.shape[1:] == (4,) and np.abs(links[:, 1:3]).max(initial=0.0) > MAX_LENGTH_M:
        r.fail("dh.links", f"a length d or a beyond ±{MAX_LENGTH_M:g} m; is the unit right (metres)?")
    if links.shape != (n + 1, 4):
        r.fail("dh.links", f"need {n + 1} rows [theta_deg, d_m, a_m, phi_deg] for {n} joints")
    links = links.copy()
    links[:, 0] = np.radians(links[:, 0])
    links[:, 3] = np.radians(links[:, 3])
    end = r.lengths("dh.end", 2)
    limits = r.array("dh.limits")
    if limits.shape != (n, 2):
        r.fail("dh.limits", f"need {n} rows [lower, upper] (deg for R, m for P)")
    if np.any(limits[:, 0] > limits[:, 1]):
        k = int(np.flatnonzero(limits[:, 0] > limits[:, 1])[0])
        r.fail("dh.limits", f"row {k + 1} is reversed: lower {limits[k, 0]:g} > upper {limits[k, 1]:g}")
    limits = limits.copy()
    for k, t in enumerate(types):
        if t == "R":
            limits[k] = np.radians(limits[k])
    names = tuple(r.strings("dh.joint_names"))
    if len(names) != n:
        r.fail("dh.joint_names", f"{len(names)} names for {n} joint_types; give one name per joint")
    if len(set(names)) != n:
        r.fail("dh.joint_names", f"names must be unique, got {list(names)!r}")
    return DHTable(
        links=links,
        end=(float(end[0]), math.radians(end[1])),
        joint_types=types,
        joint_names=names,
        limits=limits,
    )
