"""Exceptions of the plant side (dm_control style: PhysicsError from warnings)."""

from __future__ import annotations


class SimproError(Exception):
    """Base class of simpro-sim's own errors."""


class UserInputError(SimproError, ValueError):
    """A user's mistake (bad scenario, bad ``--set``, unknown name).

    The CLI prints ``error: <message>`` on one line and exits with status 2.
    The message names the dotted field path and what is allowed.
    """


class PhysicsError(SimproError, RuntimeError):
    """The simulation diverged: a MuJoCo warning, a non-finite state, or an
    opened kinematic loop. Raised by :func:`simpro_mj.plant.model.check_physics`."""


class SweepError(SimproError, RuntimeError):
    """Every variant of a sweep that could run failed (a worker pool that broke, a
    worker that could not start): the sweep has no result to return.
    :func:`simpro_mj.api.sweep` raises it rather than returning rows that are all
    failures."""
