"""A scenario's run, each piece of work done once (see the package docstring).

:class:`Run` builds the scenario as every simulation does
(:class:`~simpro_mj.sim.build.Build`: the plant compiled once, the set-points on
the 1 ms grid, the design plants after the preflight's payload check).

:meth:`Run.execute` then runs the preflight (:func:`~simpro_mj.analysis.preflight.preflight`:
a payload the cylinders cannot hold is refused, exit 2; gains above the
analysed limit are warned about), steps the co-simulation and measures it
(:func:`~simpro_mj.analysis.metrics.compute_metrics`, the end stops).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from simpro_mj.analysis.metrics import compute_metrics
from simpro_mj.analysis.preflight import (
    check_gains_before_identifying,
    check_gains_move,
    check_payload,
    preflight,
)
from simpro_mj.analysis.verdict import verdict
from simpro_mj.plant.faults import flag_series
from simpro_mj.sim.build import Build
from simpro_mj.sim.compiling import note, prepare_step
from simpro_mj.sim.readiness import signal_ready

if TYPE_CHECKING:  # the result module loads MuJoCo: when a run is built, not on import
    from simpro_mj.sim.result import SimResult


def warn(lines, quiet: bool) -> None:
    """Print warnings on stderr as ``warning: ...`` lines, unless ``quiet``."""
    if not quiet:
        for line in lines:
            sys.stderr.write(f"warning: {line}\n")


def _stepping(k: int) -> None:
    """Progress callback (every 1000 steps): readiness once a signal would still find a
    logged second to write (not at k = 0)."""
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
    end_stop_hits : list of EndStop
        Slides that reached an end stop with no fault scheduled.
    """

    result: SimResult
    metrics: dict
    warnings: list[str] = field(default_factory=list)
    preflight: dict = field(default_factory=dict)
    end_stop_hits: list[EndStop] = field(default_factory=list)

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


@dataclass
class EndStop:
    """A slide (``leg`` 1..3) that reached its ``stop`` (lower, upper) at ``time_s``."""

    leg: int
    stop: str
    time_s: float


def end_stop_warnings(columns, scenario, stroke) -> tuple[list[str], list[EndStop]]:
    """Slides that reached an end stop while no fault was scheduled.

    The shipped scenarios keep every slide well inside its stroke; reaching a
    stop without a fault means the loop is unstable or the set-point too
    aggressive, which a plot of the pose alone would not tell.

    Parameters
    ----------
    columns : mapping
        The logged columns (``time_s``, ``q<i>_m``).
    scenario : Scenario
        The typed scenario (its fault schedule).
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
                hits.append(EndStop(i, name, float(t[idx[0]])))
    lines = [
        f"leg {h.leg} reached its {h.stop} end stop at t = {h.time_s:.3f} s with no "
        "fault scheduled: the closed loop is probably unstable (see the gain warnings) or "
        "the set-point too aggressive"
        for h in hits
    ]
    return lines, hits


class Run(Build):
    """One scenario's run: the scenario built once (:class:`~simpro_mj.sim.build.Build`:
    compiled plant, set-points, design plants), checked, stepped and measured.

    Its parameters are :class:`~simpro_mj.sim.build.Build`'s (``scenario``, ``model``,
    ``say``), with the set-points of the scenario.
    """

    def preflight(self) -> tuple[list[str], dict]:
        """The checks before stepping, on this run's plant and set-points: the payload
        first (a refusal costs no identification), then the design plants and the rest."""
        setpoints = (self.t, self.ref)
        if self.spec.controller.mode == "task_space":  # before any analysis
            check_gains_move(self.spec.controller.outer.gains, self.spec.duration_s)
        payload = check_payload(self.spec, self.model, setpoints)
        if self.identified_source is None:
            from simpro_mj.identification.auto import experiment_s

            if experiment_s(self.scenario) > 0:  # an experiment to come: refuse first
                check_gains_before_identifying(self.spec)
        self.design_plants()
        return preflight(self.spec, self.model, setpoints=setpoints, payload=payload)

    def design_plants_record(self) -> dict:
        """What the joint loops were placed on (``metrics.json`` → ``design_plants``).

        ``design_plant`` (``paper``: eqs. 34-35; ``identified``: the models below),
        ``source`` of the models (``preset``: the scenario's ``controller.inner.
        identified``; ``identified``: the Fig. 12 experiment on this run's own plant,
        run now or cached; ``linearised``: the plant model's linearisation; ``reduced``:
        the experiment on the reduced chain, run now or cached) and the
        models, m/(s^3 V), 1/s, 1/s^2. ``scenario.yaml`` keeps the scenario as given,
        so under ``identify: auto`` this is where a plant's own models are written.
        """
        inner = self.spec.controller.inner
        source = self.identified_source or "preset"
        return {
            "design_plant": inner.design_plant,
            "source": "identified" if source == "cache" else source,
            "models": inner.identified.model_dump(),
        }

    def execute(
        self,
        *,
        quiet: bool = False,
        progress=_stepping,
        bar: bool = False,
        stop=None,
    ) -> RunOutcome:
        """Preflight, simulate and measure; warnings on stderr unless ``quiet``.
        ``progress`` and ``stop`` (the run's stop token) go to
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
        res = self.simulation().run(progress, stop=stop)
        res.sim.update(loaded)
        metrics = compute_metrics(res.columns, self.spec)
        if res.status == "ok":  # ran to its end: does the pose settle? (analysis.verdict)
            judged = verdict(res.columns, res.noise_floor)
            res.status, res.reason = judged["status"], judged["reason"]
            metrics.update(verdict=judged)
        metrics.update(status=res.status, reason=res.reason, sensor_floor=res.sensor_floor,
                       design_plants=self.design_plants_record())  # fmt: skip
        stop_lines, hits = end_stop_warnings(res.columns, self.spec, self.stroke())
        warn(stop_lines, quiet)
        return RunOutcome(res, metrics, warnings + stop_lines, figures, hits)
