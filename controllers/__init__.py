"""Controller side of simpro-sim: kinematics, joint loops, task-space loop.

Imports only numpy, scipy and python-control, never MuJoCo, so that the
same code can run on the rig's control computer.
"""

from .errors import ConvergenceError, DesignError, KinematicsError, WorkspaceError
from .geometry import H0, PAPER_POINTS_MM, PlatformGeometry, nominal_geometry
from .kinematics import (
    forward_kinematics,
    inverse_kinematics,
    jacobian,
    leg_lengths,
    paper_inverse_kinematics,
    reachable,
)

__all__ = [
    "ConvergenceError",
    "DesignError",
    "KinematicsError",
    "WorkspaceError",
    "H0",
    "PAPER_POINTS_MM",
    "PlatformGeometry",
    "nominal_geometry",
    "forward_kinematics",
    "inverse_kinematics",
    "jacobian",
    "leg_lengths",
    "paper_inverse_kinematics",
    "reachable",
]
