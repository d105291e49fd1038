"""The shipped cueing law judged on a set of drives: the done-when table.

Every drive (a shipped cueing scenario's input, or a telemetry file) goes through the
shipped MPC law (``cue_lane_change``'s block, or the scenario's own), the platform
loop's model and a rigid cabin's head (:mod:`simpro_mj.analysis.omct`: the loop model
reads within 0.01 of the whole chain on the shipped law, docs/cueing.md), and through
the bound (:mod:`controllers.cue_bound`, the law's own cost and limits, the whole drive
known). Per channel the drive judges (:func:`~simpro_mj.analysis.cue_metrics.cue_floors`),
:func:`judge` returns the perceived correlation, the mean lag, the gain and the bound's,
the share, the worst onset and the onsets missed, and the raw wrong-way peak.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: The shipped cueing scenarios judged with their own law and input.
SHIPPED = ("cue_braking", "cue_lane_change", "cue_braking_turn", "cue_step_fx", "cue_ramp_fx")
#: The scenario whose law a recording is played through.
LAW_OF_RECORDINGS = "cue_lane_change"
_DT = 0.01


@dataclass
class CorpusRow:
    """One judged channel of one drive."""

    drive: str
    channel: str
    correlation: float
    mean_lag_s: float
    gain: float
    bound_gain: float
    gain_share: float | None
    onset_delay_s: float | None
    onsets: int
    onsets_missed: int
    raw_wrong_way_mps2: float | None
    floors_missed: str


def judge_drive(name: str, block: Mapping, t, f, w, *, bound: bool = True) -> list[CorpusRow]:
    """The judged channels of one drive (``t`` on a 10 ms grid, ``f``, ``w`` V frame)."""
    from simpro_mj.analysis.cue_metrics import cue_floors
    from simpro_mj.analysis.omct import model_chain_metrics

    m = model_chain_metrics(block, np.asarray(t), np.asarray(f), np.asarray(w), bound=bound)
    floors = cue_floors(m)
    rows = []
    bound_ch = (m.get("bound") or {}).get("channels") or {}
    for c in floors.channels:
        x = m["channels"][c]
        rows.append(
            CorpusRow(
                drive=name,
                channel=c,
                correlation=float(x["correlation"]),
                mean_lag_s=float(x["mean_lag_s"]),
                gain=float(x["gain"]),
                bound_gain=float((bound_ch.get(c) or {}).get("gain", float("nan"))),
                gain_share=x.get("gain_share"),
                onset_delay_s=x.get("onset_delay_s"),
                onsets=int(x.get("onsets") or 0),
                onsets_missed=int(x.get("onsets_missed") or 0),
                raw_wrong_way_mps2=x.get("onset_raw_wrong_sign_peak"),
                floors_missed="; ".join(s for s in floors.missed if s.startswith(c)),
            )
        )
    return rows


def judge(files: Sequence = (), *, shipped: Sequence[str] = SHIPPED,
          changes: Mapping | None = None, bound: bool = True) -> list[CorpusRow]:  # fmt: skip
    """The shipped scenarios ``shipped`` and the telemetry ``files`` (played through
    :data:`LAW_OF_RECORDINGS`'s law, over their whole length), with the law's
    parameters changed by ``changes`` (YAML names)."""
    from simpro_mj.config.cueing import step_input
    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.config.telemetry import read_telemetry, resample

    rows: list[CorpusRow] = []
    drives = [(s, None) for s in shipped] + [(Path(p).stem, Path(p)) for p in files]
    law = load_scenario(LAW_OF_RECORDINGS).setpoint.cueing
    for name, path in drives:
        if path is None:
            scen = load_scenario(name)
            cue = scen.setpoint.cueing
            assert cue is not None  # a shipped cue scenario
            t = np.arange(0, float(scen.duration_s) + 1e-9, _DT)
            if cue.step is not None:
                f, w = step_input(cue.step, t)
            else:
                f, w = resample(read_telemetry(cue.telemetry, columns=cue.columns), t)
        else:
            cue = law
            tel = read_telemetry(path)
            t = np.arange(0, np.floor(tel.t[-1] / _DT + 1e-9) * _DT + 1e-9, _DT)
            f, w = resample(tel, t)
        assert cue is not None  # the law of the recordings: a cue scenario's
        block = {
            "algorithm": cue.algorithm,
            "parameters": {**cue.parameters.model_dump(), **dict(changes or {})},
        }
        rows += judge_drive(name, block, t, f, w, bound=bound)
    return rows


def table(rows: Sequence[CorpusRow]) -> str:
    """The rows as a Markdown table."""

    def num(v, fmt):
        return "-" if v is None or v != v else format(v, fmt)

    out = [
        "| drive | channel | correlation | mean lag (s) | gain | bound's gain | share | "
        "worst onset (s) (missed of) | raw wrong-way (m/s^2) | floors missed |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        out.append(
            f"| {r.drive} | {r.channel} | {num(r.correlation, '.3f')} | "
            f"{num(r.mean_lag_s, '.2f')} | {num(r.gain, '.3f')} | {num(r.bound_gain, '.3f')} | "
            f"{num(r.gain_share, '.2f')} | {num(r.onset_delay_s, '.3f')} "
            f"({r.onsets_missed} of {r.onsets}) | {num(r.raw_wrong_way_mps2, '.2f')} | "
            f"{r.floors_missed or 'none'} |"
        )
    return "\n".join(out)
