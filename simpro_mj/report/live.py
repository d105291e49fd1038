"""A live session into a result folder: the job behind ``simpro-sim live``.

The folder is a normal run's (:mod:`simpro_mj.report.results`): the same
``timeseries.csv`` columns, the received vehicle signals among them
(``veh_*``: what the washout was given, held between datagrams and faded to
rest when stale), ``qpos.npz`` for ``simpro-sim render``, the cueing metrics,
and two blocks of its own in ``metrics.json``:

* ``realtime``: ``lateness_us`` {p50, p99, max} of the chunk deadlines,
  ``missed_deadlines``, ``drift_ms`` (simulated minus wall time at the end,
  from the clock's first anchor), ``resyncs`` and ``lost_s``, ``packets``
  {received, bad, late, ...}, ``stale_s``, ``pose_sent``
  (:meth:`simpro_mj.sim.live.Pacer.realtime`);
* ``live``: where the input came from and where the pose went;

and ``realtime.npz``: each chunk deadline's simulated time (``time_s``) and
how late the session woke for it (``lateness_us``).

``scenario.yaml`` is the scenario run, its ``duration_s`` the session's; its
``setpoint.cueing`` names the washout and its parameters (its ``telemetry``
is not what drove the session: ``live`` says what did). A session ended by
SIGINT or SIGTERM is a session that ended: status ``ok``, ``realtime.ended``
``signal``, everything up to that moment written.
"""

from __future__ import annotations

from pathlib import Path

from simpro_mj.analysis.cue_metrics import cue_metrics
from simpro_mj.analysis.metrics import compute_metrics
from simpro_mj.analysis.preflight import preflight
from simpro_mj.config.models import Scenario
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.interrupts import writing
from simpro_mj.job.run import warn
from simpro_mj.report.results import write_folder
from simpro_mj.report.runner import kept_line, recording
from simpro_mj.sim.live import LiveOptions, run_session

#: Largest log a session may preallocate (bytes): beyond, raise logging.decimation.
MAX_LOG_BYTES = 1 << 30


def live_scenario(scenario: Scenario, duration_s: float | None) -> Scenario:
    """The scenario a session runs: ``duration_s`` the session's (default: the scenario's)."""
    if duration_s is not None:
        scenario = scenario.model_copy(update={"duration_s": float(duration_s)})
    every = scenario.logging.decimation
    rows = scenario.duration_s / 1e-3 / every + 1
    nbytes = rows * 8 * 60  # the log's columns, qpos, the head sensors
    if nbytes > MAX_LOG_BYTES:
        need = int(rows * 8 * 60 * every // MAX_LOG_BYTES) + 1
        raise UserInputError(
            f"invalid value at --duration: {scenario.duration_s:g} s logs "
            f"{nbytes / 2**20:.0f} MiB at logging.decimation {every}; allowed: a shorter "
            f"session or --set logging.decimation={need} or more"
        )
    return scenario


def actuator_tracking(columns) -> dict:
    """Commanded (``q*_ref_m``) against simulated (``q*_m``) actuator positions, per leg:
    the rms and largest difference (mm). Both are columns of ``timeseries.csv``."""
    import numpy as np

    out = {}
    for i in (1, 2, 3):
        d = (np.asarray(columns[f"q{i}_ref_m"]) - np.asarray(columns[f"q{i}_m"])) * 1e3
        out[f"q{i}"] = {
            "rms_mm": float(np.sqrt(np.mean(d**2))) if d.size else None,
            "max_abs_mm": float(np.abs(d).max()) if d.size else None,
        }
    return out


def execute_live(scenario: Scenario, options: LiveOptions, out, plots: bool = True, *,
                 say=None, quiet: bool = False):  # fmt: skip
    """Run a live session of a resolved scenario (:func:`live_scenario`) and write its folder.

    Returns
    -------
    (SimResult, dict)
        The result (``folder`` set) and what ``metrics.json`` holds.
    """
    out = Path(out)
    # the scenario with its set-points at home: what the preflight can check in advance
    home = scenario.model_dump() | {"setpoint": {"roll_deg": [], "pitch_deg": [], "heave_mm": []}}
    warnings: list[str] = []
    figures: dict = {}

    def checks() -> None:  # payload and gains at home; the washout keeps its box
        # the preflight takes the scenario with its design plants (design_plant:
        # identified: its own plant's models); MuJoCo loads here, when the session starts
        from simpro_mj.identification.auto import with_identified

        said, found = preflight(with_identified(home)[0])
        warnings.extend(said)
        figures.update(found)
        warn(warnings, quiet)

    session = run_session(scenario, options, say=say, checks=checks)
    res, realtime = session.result, session.realtime
    res.folder = None
    # from here on a signal waits for the folder to be written, then says it is kept
    with writing(lambda: kept_line(res)):
        ended = "signal" if res.status == "interrupted" else "duration"
        if res.status == "interrupted":
            res.status = "ok"
            res.reason = (
                f"session ended by a signal at t = {res.sim['simulated_s']:.3f} s "
                f"(of {scenario.duration_s:g} s)"
            )
        realtime.update(ended=ended)
        host, port = session.address
        fmt = realtime["packets"]["format"]  # for auto, the format it found
        source = f"udp {fmt} {host}:{port}"
        metrics = compute_metrics(res.columns, home)
        cue = cue_metrics(res.columns, scenario, info=dict(session.washout, source=source))
        metrics.update(cueing=cue, status=res.status, reason=res.reason)
        metrics.update(sensor_floor=res.sensor_floor)
        live = {
            "vehicle_input": source,
            "pose_out": None
            if options.send is None
            else {
                "to": f"{options.send[0]}:{options.send[1]}",
                "rate_hz": options.send_rate_hz,
                "format": options.send_format,
            },
            "stale_after_s": options.stale_after_s,
            "fade_s": options.fade_s,
            "rig_out": None
            if options.output is None or options.output_template is None
            else {
                "to": options.output,
                "rate_hz": options.output_rate_hz,
                "bits": options.output_template.bits,
                "text": options.output_template.text_counts,
            },
            "actuators": actuator_tracking(res.columns),
            "conditioning": {
                "bias_tau_s": options.bias_tau_s,
                "vibration_hz": options.vibration_hz,
            },
        }
        extra = {
            "sim": dict(res.sim),
            "warnings": warnings,
            "preflight": figures,
            "realtime": realtime,
            "live": live,
            "plots": plots,
        }
        arrays = dict(recording(res), **{"realtime.npz": session.lateness})
        res.folder, doc = write_folder(out, res.columns, metrics, scenario, extra, arrays)
    return res, doc
