"""Controller side of simpro-sim: kinematics, joint loops, task-space loop, cueing.

Imports only numpy, scipy and python-control, never MuJoCo, so that the
same code can run on the rig's control computer.

The names below are exported lazily (PEP 562): ``import controllers.errors``
(what the command line needs to start) costs nothing, and a submodule is
imported when one of its names is first used (``scipy.signal``, which the
cueing filters need, alone takes seconds to import on a loaded machine).
"""

import importlib

#: exported name -> submodule
_EXPORTS = {
    "ConvergenceError": "errors",
    "DesignError": "errors",
    "KinematicsError": "errors",
    "WorkspaceError": "errors",
    "H0": "geometry",
    "PAPER_POINTS_MM": "geometry",
    "PlatformGeometry": "geometry",
    "nominal_geometry": "geometry",
    "forward_kinematics": "kinematics",
    "inverse_kinematics": "kinematics",
    "jacobian": "kinematics",
    "leg_lengths": "kinematics",
    "paper_inverse_kinematics": "kinematics",
    "reachable": "kinematics",
    # joint and task-space loops
    "JointDesign": "design",
    "Plant": "design",
    "place_poles": "design",
    "JointControllers": "joint",
    "SamplingError": "task_space",
    "TaskSpaceController": "task_space",
    "leg_velocity_feedforward": "velocity_feedforward",
    "velocity_gains": "velocity_feedforward",
    # motion cueing and perception
    "CanalModel": "vestibular",
    "OtolithModel": "vestibular",
    "VestibularModel": "vestibular",
    "ClassicalWashout": "washout",
    "WashoutParams": "washout",
}

__all__ = list(_EXPORTS)


def __getattr__(name: str):
    if name in _EXPORTS:
        return getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
    raise AttributeError(f"module 'controllers' has no attribute {name!r}")


def __dir__():
    return sorted(__all__)
