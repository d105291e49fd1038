"""A scenario built once for its simulation: the one place a co-simulation is made.

:class:`Build` does, in this order and once each, what every simulation of a
scenario needs:

1. the plant: the MJCF compiled once (:func:`~simpro_mj.plant.model.load_model`),
   shared by the preflight's static solves (which change the payload mass
   and restore it) and the loop;
2. the set-points on the 1 ms grid (:func:`~simpro_mj.config.reference.reference`),
   shared by the preflight's pose checks and the loop (none for set-points
   written from outside, the live interface);
3. the design plants, when the run asks for them: with
   ``controller.inner.design_plant: identified`` the joint loops are placed
   (eqs. 36-37) on the scenario's own plant's models, Fig. 12's experiment run
   once and cached (:func:`~simpro_mj.identification.auto.with_identified`).

:meth:`Build.simulation` then makes the
:class:`~simpro_mj.sim.loop.CoSimulation` of those pieces. A scenario's run
(:class:`simpro_mj.job.run.Run`: preflight, step, measure), the live
interface, the frequency and chain responses and the replay all start here.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Literal, cast

import numpy as np

from simpro_mj.config.models import Scenario, as_scenario
from simpro_mj.config.reference import reference
from simpro_mj.core.cache import notice
from simpro_mj.core.interrupts import held_signals
from simpro_mj.plant.model_params import MAX_MODEL_PAYLOAD_KG

if TYPE_CHECKING:  # the loop loads MuJoCo: when a build is made, not on import
    from simpro_mj.sim.loop import CoSimulation
    from simpro_mj.sim.result import SimResult


class Build:
    """One scenario, built once: compiled plant, set-points, design plants.

    Parameters
    ----------
    scenario : Scenario or mapping
        A resolved scenario (:func:`simpro_mj.config.scenario.load_scenario`), typed
        or its dict; :attr:`spec` is the typed one, :attr:`scenario` the dict
        the run records.
    model : mujoco.MjModel, optional
        A compiled plant of this scenario's ``plant`` (a comparison shares one
        between its two runs); compiled here when omitted.
    setpoints : {"scenario", "external"}
        ``scenario``: the set-points evaluated here for the whole run.
        ``external``: written while the run goes (the live interface;
        :class:`~simpro_mj.sim.loop.CoSimulation`); none evaluated here.
    say : callable(str), optional
        Where one-line progress notes go (the identification's); stderr by default.

    Notes
    -----
    A payload above what the MJCF builder accepts
    (:data:`~simpro_mj.plant.model_params.MAX_MODEL_PAYLOAD_KG`) is compiled
    empty, so that the preflight refuses it with its own message and limit
    (``payload too heavy at plant.payload.mass_kg``); :meth:`simulation`
    raises the builder's own message.
    """

    def __init__(
        self,
        scenario: Scenario | Mapping,
        *,
        model=None,
        setpoints: Literal["scenario", "external"] = "scenario",
        say: Callable[[str], None] = notice,
    ):
        # the run's simulation modules (MuJoCo's bindings among them): loaded when a
        # scenario is built, not when a command that refuses bad input within a second
        # imports this module; a signal meanwhile is raised once they are in
        # (core.interrupts)
        with held_signals():
            from simpro_mj.identification.auto import with_identified  # noqa: F401
            from simpro_mj.plant.model import load_model
            from simpro_mj.sim.loop import CoSimulation  # noqa: F401

        if setpoints not in ("scenario", "external"):
            raise ValueError(f"setpoints={setpoints!r}; allowed: 'scenario' or 'external'")
        #: the typed scenario (:class:`~simpro_mj.config.models.Scenario`)
        self.spec = spec = as_scenario(scenario)
        #: the resolved scenario as a dict: what the run records and hashes
        self.scenario = spec.model_dump() if scenario is spec else cast(dict, scenario)
        self.setpoints = setpoints
        self._say = say
        #: where the design plants came from, once :meth:`design_plants` ran
        self.identified_source: str | None = None
        self.payload_too_heavy = spec.plant.payload.mass_kg > MAX_MODEL_PAYLOAD_KG
        if model is None:
            model = load_model(spec.plant.tree(empty=self.payload_too_heavy))
        self.model = model
        dt = float(model.opt.timestep)
        n = int(round(spec.duration_s / dt))
        #: the 1 ms grid and the set-point poses on it (SI), evaluated once
        self.t = np.arange(n + 1) * dt
        self.ref = None
        if setpoints == "scenario":
            self.ref = np.ascontiguousarray(reference(self.scenario, self.t))

    def stroke(self) -> list[tuple[float, float]]:
        """Each slide's range (m): the model's joint limits (the DNC-125-500 stroke)."""
        ranges = [self.model.joint(f"leg{i}").range for i in (1, 2, 3)]
        return [(float(lo), float(hi)) for lo, hi in ranges]

    def design_plants(self) -> str:
        """The scenario with its design plants (identified once when it asks); where
        they came from."""
        if self.identified_source is None:
            from simpro_mj.identification.auto import with_identified

            designed, self.identified_source = with_identified(self.scenario, self._say)
            if designed is not self.scenario:  # the plant's own models
                self.scenario = cast(dict, designed)
                self.spec = as_scenario(designed)
        return self.identified_source

    def simulation(self) -> CoSimulation:
        """The co-simulation of this scenario (:class:`~simpro_mj.sim.loop.CoSimulation`),
        its design plants resolved first."""
        from simpro_mj.plant.model import load_model
        from simpro_mj.sim.loop import CoSimulation

        if self.payload_too_heavy:  # the preflight refuses it first; never stepped empty
            load_model(self.spec.plant.tree())  # raises the builder's own message
        source = self.design_plants()
        return CoSimulation(
            self.scenario,
            self.model,
            setpoints=self.setpoints,
            poses=self.ref,
            identified_source=source,
        )


def simulate(scenario: Scenario | Mapping, progress=None, *, stop=None) -> SimResult:
    """Build and run a scenario, with no preflight and no measure (the replay, the
    responses' points); :class:`simpro_mj.job.run.Run` is the whole run."""
    return Build(scenario).simulation().run(progress, stop=stop)
