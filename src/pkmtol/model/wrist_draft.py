"""The A/C wrist of the hybrid families (``pkmtol new r2rps_ups_wrist``, ``tricept_wrist``).

:func:`wrist_fields` gives the :class:`~pkmtol.model.families.RobotDraft` fields a module gets
with the wrist (docs/robots.md, "The hybrid machines"): the C axis along the platform axis,
``c_height`` beyond O'; the A axis across it through P (``offset`` beyond O', the module's task
point, so that the tool axis always passes through P: the decoupled inverse kinematics of
docs/hybrid.md); the spindle nose ``nose`` beyond A along the spindle; the TCP ``tool_length``
beyond the nose. The chain is written as a D–H table (``[tool.dh]``) and its URDF generated
from it. The task: the TCP in a cylinder and the tool axis in a cone of 15° about the direction
45° from z towards +x (away from the A = 0 pole of the head, where C only spins the tool).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

import pkmtol.values as values
from pkmtol.exceptions import InvalidArgumentError
from pkmtol.model.dh import DHTable

#: The ``description`` of each hybrid family's robot.
DESCRIPTIONS = {
    "r2rps_ups_wrist": (
        "R(2-RPS&RP)&UPS module with an A/C wrist: the 5-DOF hybrid machining robot (paper §4)"
    ),
    "tricept_wrist": "Tricept 3-UPS&UP with an A/C wrist: a 5-axis hybrid machine",
}

#: ``pkmtol new`` help of the wrist's dimensions.
WRIST_HELP = {
    "offset": "P (the wrist centre, on the A axis) beyond O' along the platform axis [m]",
    "c_height": "the wrist's C axis starts this far beyond O' along the platform axis [m]",
    "nose": "the spindle nose this far beyond the A axis (which crosses the platform axis at P) [m]",
    "tool_length": "the TCP this far beyond the spindle nose along the tool axis [m]",
    "task_radius": "radius of the cylindrical task space of the TCP [m]",
    "task_z": "height range of the TCP's task space: MIN MAX [m]",
    "task_center_x": "the TCP's task cylinder's axis at x = this [m]",
}


def wrist_fields(
    comment: tuple[str, ...],
    offset: float,
    c_height: float,
    nose: float,
    tool_length: float,
    task_radius: float,
    task_z: tuple[float, float],
    task_center_x: float,
) -> dict[str, Any]:
    """``task_space``, ``comment`` and ``tool`` of a module's draft with the A/C wrist.

    Raises:
        InvalidArgumentError: a dimension that cannot make the wrist (naming its option).
    """
    c = values.number("--c-height", c_height, positive=True)
    if not c < offset:
        raise InvalidArgumentError("--c-height", c, f"the C axis must start before P (--offset {offset:g} m)")
    n = values.number("--nose", nose, positive=True)
    length = values.number("--tool-length", tool_length)
    if length < 0:
        raise InvalidArgumentError("--tool-length", length, "a tool length must be ≥ 0 [m]")
    z = values.vector("--task-z", task_z, 2)
    if not z[0] < z[1]:
        raise InvalidArgumentError("--task-z", f"{z[0]:g} {z[1]:g}", "write it as MIN MAX, MIN < MAX [m]")
    table = DHTable(
        links=np.array(
            [
                [0.0, c, 0.0, 0.0],
                [math.pi / 2, offset - c, 0.0, math.pi / 2],
                [math.pi, 0.0, 0.0, math.pi / 2],
            ]
        ),
        end=(n, math.pi / 2),
        joint_types=("R", "R"),
        joint_names=("wrist_c", "wrist_a"),
        limits=np.radians([[-180.0, 180.0], [-100.0, 100.0]]),
    )
    task = {
        "kind": "cylinder",
        "radius_m": values.number("--task-radius", task_radius, positive=True),
        "center_xy_m": [values.number("--task-center-x", task_center_x), 0.0],
        "z_m": [float(z[0]), float(z[1])],
        "layers": 3,
        "rings": [8, 16],
    }
    tool = {
        "urdf": "wrist.urdf",
        "actuated": ("wrist_c", "wrist_a"),
        "nose_frame": "spindle_nose",
        "length": f"{round(1e3 * length, 6):g} mm",
        "home": (round(math.pi / 2, 6), round(math.pi / 4, 6)),
        "table": table,
        "axis": (round(math.sqrt(0.5), 8), 0.0, round(math.sqrt(0.5), 8)),
        "cone": "15 deg",
        "rings": (6,),
    }
    return {
        "task_space": task,
        "comment": (
            *comment,
            "With the A/C wrist and the spindle: the whole hybrid machine (docs/hybrid.md).",
        ),
        "tool": tool,
    }
