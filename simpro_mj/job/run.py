"""A scenario's run, each piece of work done once (see the package docstring).

The pieces, in the order :class:`Run` builds them:

1. the plant: the MJCF compiled once (:func:`~simpro_mj.plant.model.load_model`),
   shared by the preflight's static solves (which change the payload mass
   and restore it) and the loop;
2. the set-points on the 1 ms grid (:func:`~simpro_mj.config.reference.reference`),
   shared by the preflight's pose checks and the loop;
3. the design plants, after the preflight's payload check: with
   ``controller.inner.design_plant: identified`` the joint loops are placed
   (eqs. 36-37) on the scenario's own plant's models, Fig. 12's experiment run
   once and cached (:func:`~simpro_mj.identification.auto.with_identified`).

:meth:`Run.execute` then runs the preflight (:func:`~simpro_mj.analysis.preflight.preflight`:
a payload the cylinders cannot hold is refused, exit 2; gains above the
analysed limit are warned about), steps the co-simulation and measures it
(:func:`~simpro_mj.analysis.metrics.compute_metrics`, the end stops).
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, cast

import numpy as np

from simpro_mj.analysis.metrics import compute_metrics
from simpro_mj.analysis.preflight import (
    check_gains_before_identifying,
    check_gains_move,
    check_payload,
    preflight,
)
from simpro_mj.analysis.verdict import verdict
from simpro_mj.config.reference import reference
from simpro_mj.core.interrupts import held_signals
from simpro_mj.plant.faults import flag_series
from simpro_mj.plant.model_params import MAX_MODEL_PAYLOAD_KG
from simpro_mj.sim.compiling import note, prepare_step
from simpro_mj.sim.readiness import signal_ready

if TYPE_CHECKING:  # the result module loads MuJoCo: when a run is built, not on import
    from simpro_mj.sim.result import SimResult

__all__ = ["Run", "RunOutcome", "end_stop_warnings", "warn"]


def warn(lines, quiet: bool) -> None:
    """Print warnings on stderr as ``warning: ...`` lines, unless ``quiet``."""
    if not quiet:
        for line in lines:
            sys.stderr.write(f"warning: {line}\n")


def _say(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def _stepping(k: int) -> None:
    """Progress callback (every 1000 steps): readiness once the run has steps to keep.

    Not at k = 0: a signal sent the moment the file appears must still find
    a partial result with at least one logged second to write.
    """
    if k > 0:
        signal_ready("stepping")


@dataclass
class RunOutcome:
    """What one run produced, measured; everything ``metrics.json`` holds but the
    versions and the hash (:func:`simpro_mj.report.results.write_run` adds them).

    Attributes
    ----------
    result : SimResult
        The logged columns (copies), status, reason, the simulation's figures,
        the recorded ``qpos``.
    metrics : dict
        :func:`~simpro_mj.analysis.metrics.compute_metrics` with ``status``,
        ``reason`` and ``sensor_floor``.
    warnings : list of str
        The preflight's and the end stops', in that order.
    preflight : dict
        The preflight's figures (``payload``, ``stability``).
    end_stop_hits : list of dict
        Slides that reached an end stop with no fault scheduled.
    """

    result: SimResult
    metrics: dict
    warnings: list[str] = field(default_factory=list)
    preflight: dict = field(default_factory=dict)
    end_stop_hits: list[dict] = field(default_factory=list)

    @property
    def status(self) -> str:
        return self.result.status

    @property
    def scenario(self) -> dict:
        """The scenario as run (with its design plants)."""
        return self.result.scenario

    def extra(self) -> dict:
        """The rest of ``metrics.json``: ``sim`` (with the end-stop hits),
        ``warnings``, ``preflight``."""
        return {
            "sim": dict(self.result.sim, end_stop_hits=self.end_stop_hits),
            "warnings": list(self.warnings),
            "preflight": self.preflight,
        }


def end_stop_warnings(columns, scenario, stroke) -> tuple[list[str], list[dict]]:
    """Slides that reached an end stop while no fault was scheduled.

    The shipped scenarios keep every slide well inside its stroke; reaching a
    stop without a fault means the loop is unstable or the set-point too
    aggressive, which a plot of the pose alone would not tell.

    Parameters
    ----------
    columns : mapping
        The logged columns (``time_s``, ``q<i>_m``).
    scenario : mapping
        The resolved scenario (its fault schedule).
    stroke : sequence of (float, float)
        Each slide's range (m), the model's joint limits.
    """
    t = columns.get("time_s")
    if t is None or not len(t):
        return [], []
    quiet = flag_series(scenario, t) == 0
    hits = []
    for i in (1, 2, 3):
        q = columns.get(f"q{i}_m")
        if q is None:
            continue
        lo, hi = stroke[i - 1]
        for name, at in (("lower", q <= lo), ("upper", q >= hi)):
            idx = np.flatnonzero(at & quiet)
            if idx.size:
                hits.append({"leg": i, "stop": name, "time_s": float(t[idx[0]])})
    lines = [
        f"leg {h['leg']} reached its {h['stop']} end stop at t = {h['time_s']:.3f} s with no "
        "fault scheduled: the closed loop is probably unstable (see the gain warnings) or "
        "the set-point too aggressive"
        for h in hits
    ]
    return lines, hits


class Run:
    """One scenario, built once: design plants, compiled plant, set-points.

    Parameters
    ----------
    scenario : mapping
        A resolved scenario (:func:`simpro_mj.config.scenario.load_scenario`).
    model : mujoco.MjModel, optional
        A compiled plant of this scenario's ``plant`` (a comparison shares one
        between its two runs); compiled here when omitted.
    say : callable(str), optional
        Where one-line progress notes go (the identification's); stderr by default.

    Notes
    -----
    A payload above what the MJCF builder accepts
    (:data:`~simpro_mj.plant.model_params.MAX_MODEL_PAYLOAD_KG`) is compiled
    empty, so that the preflight refuses it with its own message and limit
    (``payload too heavy at plant.payload.mass_kg``).
    """

    def __init__(self, scenario: dict, *, model=None, say: Callable[[str], None] = _say):
        # the run's simulation modules (MuJoCo's bindings among them): loaded when a run
        # is built, not when a command that refuses bad input within a second imports
        # this module; a signal meanwhile is raised once they are in (core.interrupts)
        with held_signals():
            from simpro_mj.identification.auto import with_identified  # noqa: F401
            from simpro_mj.plant.model import load_model
            from simpro_mj.sim.loop import CoSimulation  # noqa: F401

        self.scenario = scenario
        self._say = say
        #: where the design plants came from, once :meth:`design_plants` ran
        self.identified_source: str | None = None
        plant = self.scenario["plant"]
        self.payload_too_heavy = float(plant["payload"]["mass_kg"]) > MAX_MODEL_PAYLOAD_KG
        if model is None:
            if self.payload_too_heavy:
                plant = dict(plant, payload=dict(plant["payload"], mass_kg=0.0))
            model = load_model(plant)
        self.model = model
        dt = float(model.opt.timestep)
        n = int(round(self.scenario["duration_s"] / dt))
        #: the 1 ms grid and the set-point poses on it (SI), evaluated once
        self.t = np.arange(n + 1) * dt
        self.ref = np.ascontiguousarray(reference(self.scenario, self.t))

    def stroke(self) -> list[tuple[float, float]]:
        """Each slide's range (m): the model's joint limits (the DNC-125-500 stroke)."""
        ranges = [self.model.joint(f"leg{i}").range for i in (1, 2, 3)]
        return [(float(lo), float(hi)) for lo, hi in ranges]

    def design_plants(self) -> None:
        """The scenario with its design plants (identified once when it asks; step 1)."""
        if self.identified_source is None:
            from simpro_mj.identification.auto import with_identified

            designed, self.identified_source = with_identified(self.scenario, self._say)
            self.scenario = cast(dict, designed)  # the resolved scenario, a dict

    def preflight(self) -> tuple[list[str], dict]:
        """The checks before stepping, on this run's plant and set-points: the payload
        first (a refusal costs no identification), then the design plants and the rest."""
        setpoints = (self.t, self.ref)
        if self.scenario["controller"]["mode"] == "task_space":  # before any analysis
            check_gains_move(self.scenario["controller"]["outer"]["gains"],
                             self.scenario["duration_s"])  # fmt: skip
        payload = check_payload(self.scenario, self.model, setpoints)
        if self.identified_source is None:
            from simpro_mj.identification.auto import experiment_s

            if experiment_s(self.scenario) > 0:  # an experiment to come: refuse first
                check_gains_before_identifying(self.scenario)
        self.design_plants()
        return preflight(self.scenario, self.model, setpoints=setpoints, payload=payload)

    def simulation(self):
        """The co-simulation of this run (:class:`~simpro_mj.sim.loop.CoSimulation`)."""
        from simpro_mj.plant.model import load_model
        from simpro_mj.sim.loop import CoSimulation

        if self.payload_too_heavy:  # the preflight refuses it first; never stepped empty
            load_model(self.scenario["plant"])  # raises the builder's own message
        self.design_plants()
        return CoSimulation(
            self.scenario,
            self.model,
            poses=self.ref,
            identified_source=self.identified_source,
        )

    def execute(
        self,
        *,
        quiet: bool = False,
        progress=_stepping,
        pace=None,
        bar: bool = False,
        stop=None,
    ) -> RunOutcome:
        """Preflight, simulate and measure; warnings on stderr unless ``quiet``.
        ``progress``, ``pace`` and ``stop`` (the run's stop token) go to
        :meth:`simpro_mj.sim.loop.CoSimulation.run`.

        Between the preflight and the simulation the compiled step is loaded
        (:func:`simpro_mj.sim.compiling.prepare_step`): a first compile is said on
        stderr unless ``quiet`` (with a bar of its functions if ``bar``), and its
        time is kept out of the run's ``realtime_factor`` (``metrics.json``:
        ``sim.wall_clock.kernel_load_s``). A mistake the preflight refuses costs
        no compile.

        Raises
        ------
        UserInputError
            From the preflight (a payload the cylinders cannot hold).
        """
        warnings, figures = self.preflight()
        warn(warnings, quiet)
        loaded = prepare_step(say=None if quiet else note, bar=bar)
        res = self.simulation().run(progress, pace=pace, stop=stop)
        res.sim.update(loaded)
        metrics = compute_metrics(res.columns, res.scenario)
        if res.status == "ok":  # ran to its end: does the pose settle? (analysis.verdict)
            judged = verdict(res.columns, res.noise_floor)
            res.status, res.reason = judged["status"], judged["reason"]
            metrics["verdict"] = judged
        metrics["status"] = res.status
        metrics["reason"] = res.reason
        metrics["sensor_floor"] = res.sensor_floor
        stop_lines, hits = end_stop_warnings(res.columns, res.scenario, self.stroke())
        warn(stop_lines, quiet)
        return RunOutcome(res, metrics, warnings + stop_lines, figures, hits)
