"""The measurement models of a calibration, one per instrument a shop may own (docs/instruments.md).

``tracker`` (P's position), ``tracker-multi`` (K reflectors: the pose), ``tracker-6d`` (position and
orientation), ``ballbar`` (ISO 230-4 circles), ``probe`` (touches on a sphere artifact, or on the
faces of a plane artifact, :mod:`.plane`). Each is a
small class (:class:`~.base.Instrument`); :func:`instrument_for` builds the one a
:class:`~pkmtol.calibration.settings.CalibrationSettings` names.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from pkmtol.calibration.instruments.ballbar import Ballbar
from pkmtol.calibration.instruments.base import Candidates, Instrument
from pkmtol.calibration.instruments.frame import TrackerFrame
from pkmtol.calibration.instruments.plane import PlaneProbe, default_block
from pkmtol.calibration.instruments.probe import SphereProbe
from pkmtol.calibration.instruments.tracker import TrackerPoints
from pkmtol.calibration.instruments.tracker6d import Tracker6D
from pkmtol.exceptions import InvalidRequestError
from pkmtol.model.mechanism import Mechanism

if TYPE_CHECKING:
    from pkmtol.calibration.settings import CalibrationSettings

__all__ = ["Candidates", "Instrument", "default_centres", "instrument_for", "task_geometry"]


def task_geometry(mechanism: Mechanism) -> tuple[float, float, float, float, float]:
    """``(cx, cy, radius, z_min, z_max)`` of the task space [m] (a point list: its bounding cylinder)."""
    ts = mechanism.task_space
    if ts.kind == "cylinder":
        return (*ts.center_xy_m, ts.radius_m, *ts.z_range_m)
    g = ts.grid()
    c = g[:, :2].mean(axis=0)
    r = float(np.max(np.linalg.norm(g[:, :2] - c, axis=1))) or 0.1
    return float(c[0]), float(c[1]), r, float(g[:, 2].min()), float(g[:, 2].max())


def default_centres(mechanism: Mechanism, heights: int, ring: int = 4, radius: float = 0.5) -> np.ndarray:
    """Station centres (heights·(1 + ring), 3) [m]: the task axis and ``ring`` points around it.

    The ring is at ``radius`` times the task radius, evenly spaced; per height (1: mid-height;
    else z_min to z_max).
    """
    cx, cy, r, z0, z1 = task_geometry(mechanism)
    zs = [0.5 * (z0 + z1)] if heights == 1 else np.linspace(z0, z1, heights)
    out = []
    for z in zs:
        out.append((cx, cy, z))
        for i in range(ring):
            a = 2 * np.pi * i / ring
            out.append((cx + radius * r * np.cos(a), cy + radius * r * np.sin(a), z))
    return np.array(out, dtype=float)


def instrument_for(settings: CalibrationSettings, mechanism: Mechanism) -> Instrument:
    """The measurement model that ``settings`` names, for ``mechanism`` (SI units throughout).

    Raises:
        InvalidRequestError: the instrument's settings do not fit (e.g. tracker-multi with < 3 targets).
    """
    frame = TrackerFrame(identify=settings.tracker_frame == "identify")
    p = np.asarray(mechanism.reference_point_m, dtype=float)
    name = settings.instrument
    if name in ("tracker", "tracker-multi"):
        return TrackerPoints(settings.targets(mechanism), settings.noise_m, frame, name)
    if name == "tracker-6d":  # a hybrid's probe sits on the TCP frame: the TCP, or the spindle nose
        point = settings.targets(mechanism)[0] if mechanism.tool is not None else p
        return Tracker6D(point, settings.noise_m, settings.orientation_noise_rad, frame)
    if name == "ballbar":
        _, _, r, _, _ = task_geometry(mechanism)
        centres = np.asarray(settings.stations_m, dtype=float).reshape(-1, 3)
        if not len(centres):
            centres = default_centres(mechanism, 1)
        circles = tuple((c, plane) for c in centres for plane in settings.circle_planes)
        length = settings.ballbar_length_m or 0.25 * r
        return Ballbar(p, circles, length, settings.circle_points, settings.noise_m)
    if settings.artifact == "plane":
        if len(settings.stations_m):
            raise InvalidRequestError(
                "stations_m places the spheres of a sphere artifact; a plane artifact is the default "
                "block, its faces chosen by artifact_faces: leave stations_m out, or use artifact = 'sphere'"
            )
        faces = tuple(settings.artifact_faces)
        centres, normals, extents = default_block(task_geometry(mechanism), faces, settings.artifact_radius_m)
        return PlaneProbe(
            p,
            centres,
            normals,
            extents,
            settings.artifact_radius_m,
            settings.approach_directions,
            settings.noise_m,
            face_names=faces,
        )
    centres = np.asarray(settings.stations_m, dtype=float).reshape(-1, 3)
    if not len(centres):
        centres = default_centres(mechanism, 3, ring=8, radius=0.9)
        centres[:, 2] = np.minimum(centres[:, 2], centres[:, 2].max() - settings.artifact_radius_m)
    return SphereProbe(p, centres, settings.artifact_radius_m, settings.approach_directions, settings.noise_m)
