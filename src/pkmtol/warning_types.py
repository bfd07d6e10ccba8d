"""pkmtol's warnings: the input is used, but something in it is dropped, assumed or odd.

:mod:`pkmtol.exceptions` re-exports them beside the errors (``pkmtol.exceptions.PkmtolWarning``);
the command line prints each as one line, ``pkmtol: warning: <message>``.
"""

from __future__ import annotations

import math
from pathlib import Path


class PkmtolWarning(UserWarning):
    """Base class of pkmtol's warnings: the input is used, but something in it is dropped or odd."""


class MissingMeshWarning(PkmtolWarning):
    """A visual mesh a limb URDF names does not exist: that visual is left out of the 3D scene.

    The accuracy results do not depend on visuals; the warning says which file is missing.

    Attributes:
        limb: Name of the limb.
        path: The URDF file.
        mesh: The mesh file name as the URDF gives it.
    """

    def __init__(self, limb: str, path: Path | str | None, mesh: str) -> None:
        self.limb = limb
        self.path = None if path is None else Path(path)
        self.mesh = mesh
        where = f" ({self.path})" if self.path is not None else ""
        super().__init__(
            f"limb '{limb}'{where}: mesh '{mesh}' not found; its visual is left out of the 3D scene "
            "(results are not affected); fix the filename or put the mesh next to the URDF"
        )


class MissingLimitWarning(PkmtolWarning):
    """A revolute or continuous URDF joint has no ``lower``/``upper`` limit: ±π is assumed.

    CAD exports often write ``<limit effort=... velocity=.../>`` without a range, which urdfdom
    reads as [0, 0] (a joint that cannot move, so every task point is unreachable). pkmtol reads
    the missing side as −π or +π instead; a continuous joint is read as revolute over [−π, π].

    Attributes:
        limb: Name of the limb.
        path: The URDF file.
        joint: The joint.
        lower: The lower limit used [rad].
        upper: The upper limit used [rad].
    """

    def __init__(
        self, limb: str, path: Path | str | None, joint: str, lower: float, upper: float, continuous: bool
    ) -> None:
        self.limb, self.joint, self.lower, self.upper = limb, joint, lower, upper
        self.path = None if path is None else Path(path)
        where = f" ({self.path})" if self.path is not None else ""
        what = (
            "is continuous; it is read as revolute over"
            if continuous
            else "has no lower/upper limit; assumed"
        )
        super().__init__(
            f"limb '{limb}'{where}: joint '{joint}' {what} [{lower:.6g}, {upper:.6g}] rad "
            f"([{math.degrees(lower):.6g}, {math.degrees(upper):.6g}] deg); to set its range, write "
            f'type="revolute" and <limit lower="..." upper="..." effort="..." velocity="..." /> (rad) '
            "in the URDF"
        )
