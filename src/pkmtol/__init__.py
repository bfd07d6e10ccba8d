"""pkmtol: accuracy design of lower-mobility parallel kinematic machines on Pinocchio."""

from pkmtol.exceptions import PkmtolError
from pkmtol.kinematics import ClosedChain, Pose
from pkmtol.mechanism import Limb, Mechanism, load_mechanism
from pkmtol.taskspace import TaskSpace

__all__ = sorted(
    [
        "ClosedChain",
        "Limb",
        "Mechanism",
        "PkmtolError",
        "Pose",
        "TaskSpace",
        "load_mechanism",
    ]
)
__version__ = "0.1.0"
