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

# Joint and task-space loops (issue 4); appended, numpy/scipy only.
from .design import JointDesign, Plant, place_poles  # noqa: E402
from .joint import JointControllers  # noqa: E402
from .task_space import SamplingError, TaskSpaceController  # noqa: E402

__all__ += [
    "JointDesign",
    "Plant",
    "place_poles",
    "JointControllers",
    "SamplingError",
    "TaskSpaceController",
]

# Motion cueing and perception (issue 16); numpy/scipy only.
from .vestibular import CanalModel, OtolithModel, VestibularModel  # noqa: E402
from .washout import ClassicalWashout, WashoutParams  # noqa: E402

__all__ += ["CanalModel", "OtolithModel", "VestibularModel", "ClassicalWashout", "WashoutParams"]
