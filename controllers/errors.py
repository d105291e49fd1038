"""Exceptions of the controller side.

They subclass the built-ins (as python-control does) so that callers can
catch them either by their own name or as ``ValueError`` / ``RuntimeError``.
"""

from __future__ import annotations


class KinematicsError(ValueError):
    """A pose or joint vector that the kinematic model cannot handle."""


class WorkspaceError(KinematicsError):
    """A pose or joint vector outside the reachable workspace.

    The message names the limit that is violated (stroke of leg i, guide arc),
    the value reached and the allowed range.
    """


class ConvergenceError(RuntimeError):
    """An iterative solver (forward kinematics) did not converge."""


class DesignError(ValueError):
    """A controller specification that cannot be met (e.g. pole placement)."""
