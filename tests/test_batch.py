"""``simpro-sim batch`` and sweeps.

* expansion: grid and Monte Carlo counts, names, uniqueness, reproducible
  draws and seeds; malformed sweep blocks give one-line errors naming the path;
* ``simpro-sim run`` on a sweep file runs the base scenario and says so;
* a failing variant and an invalid file are reported, the others complete,
  exit code 1; ``--strict`` refuses the batch up front (exit 2);
* ``--resume`` does not recompute complete variants and recomputes an
  incomplete one;
* the process pool and a Dask LocalCluster (2 workers) give the same summary;
* summary plots are written; the stability criterion on synthetic signals;
* the shipped example sweeps expand and validate.

Runs are 1 s long with per-variant plots off, so the file takes seconds.
"""

from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from simpro_mj.batch.stability import stability_of
from simpro_mj.commands.main import main
from simpro_mj.config.scenario import load_scenario, scenario_hash, scenarios_dir
from simpro_mj.config.sweep import expand, parse_sweep
from simpro_mj.config.variants import load_sweep
from simpro_mj.core.errors import UserInputError
from simpro_mj.report import marker

BASE = {
    "duration_s": 1.0,
    "actuator": {"model": "linear"},
    "setpoint": {"pitch_deg": [{"type": "step", "time_s": 0.2, "value": 1.0}]},
}


def _write(path: Path, doc: dict) -> Path:
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return path


def _grid_file(tmp_path: Path, name: str = "g", **grid) -> Path:
    grid = grid or {"controller.outer.type": ["I", "PI"], "controller.outer.gains": [2, 4]}
    return _write(tmp_path / f"{name}.yaml", dict(BASE, name=name, sweep={"grid": grid}))


def _read_csv(path: Path) -> list[dict]:
    with path.open(encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


MC = {
    "samples": 5,
    "seed": 7,
    "parameters": {
        "plant.payload.mass_kg": {"distribution": "uniform", "low": 200, "high": 300},
        "sensors.potentiometer.offset_mm": {"distribution": "normal", "mean": 0, "std": 1.5},
        "actuator.pneumatics.supply_pressure_bar_gauge": {
            "distribution": "normal", "mean": 6, "std": 0.2, "low": 5.9, "high": 6.1,
        },
        "controller.inner.discretisation": {"distribution": "choice", "values": ["tustin", "zoh"]},
    },
}  # fmt: skip


# ------------------------------------------------------------------ expansion


def test_grid_expansion_counts_names_values(tmp_path):
    sf = load_sweep(_grid_file(tmp_path))
    names = [v.name for v in sf.variants]
    assert names == ["type=I_gains=2", "type=I_gains=4", "type=PI_gains=2", "type=PI_gains=4"]
    assert all(v.error is None for v in sf.variants)
    v = sf.variants[3]
    assert v.scenario["controller"]["outer"]["type"] == "PI"
    assert v.scenario["controller"]["outer"]["gains"] == [4.0, 4.0, 4.0]  # one number: all axes
    assert "sweep" not in v.scenario
    assert {x.seed for x in sf.variants} == {1}  # grid points share the noise
    assert len({scenario_hash(x.scenario) for x in sf.variants}) == 4
    # --set applies to every variant's base; the swept value wins on its own path
    sf2 = load_sweep(_grid_file(tmp_path), ["duration_s=0.5", "controller.outer.type=PI"])
    assert all(x.scenario["duration_s"] == 0.5 for x in sf2.variants)
    assert sf2.variants[0].scenario["controller"]["outer"]["type"] == "I"


def test_grid_names_unique_and_safe(tmp_path):
    path = _grid_file(
        tmp_path,
        **{
            "controller.outer.gains": [[1, 2, 3], [1, 2, 3], 2],
            "sensors.imu.rate_ms": [5],
            "sensors.potentiometer.rate_ms": [1],
        },
    )
    names = [v.name for v in load_sweep(path).variants]
    assert len(set(names)) == 3
    assert names[0] == "gains=1,2,3_imu.rate_ms=5_potentiometer.rate_ms=1"
    assert names[1].endswith("_2")
    assert all("/" not in n and " " not in n for n in names)


def test_monte_carlo_expansion_reproducible(tmp_path):
    doc = dict(BASE, name="mc", sweep={"grid": {"controller.mode": ["joint_only", "task_space"]},
                                       "monte_carlo": MC})  # fmt: skip
    path = _write(tmp_path / "mc.yaml", doc)
    a, b = load_sweep(path), load_sweep(path)
    assert len(a.variants) == 10
    assert a.variants[0].name == "mc000_mode=joint_only"
    assert a.variants[9].name == "mc004_mode=task_space"
    assert len({v.name for v in a.variants}) == 10
    assert [v.values for v in a.variants] == [v.values for v in b.variants]
    # paired: both modes see the same plants and the same noise seeds
    for i in range(5):
        jo, ts = a.variants[i], a.variants[5 + i]
        assert {k: v for k, v in jo.values.items() if k != "controller.mode"} == {
            k: v for k, v in ts.values.items() if k != "controller.mode"
        }
        assert jo.seed == ts.seed == 1 + i
        assert jo.scenario["seed"] == 1 + i
    for v in a.variants:
        assert 200 <= v.values["plant.payload.mass_kg"] <= 300
        assert len(v.values["sensors.potentiometer.offset_mm"]) == 3
        assert 5.9 <= v.values["actuator.pneumatics.supply_pressure_bar_gauge"] <= 6.1
        assert v.scenario["plant"]["payload"]["mass_kg"] == v.values["plant.payload.mass_kg"]
    assert len({v.values["plant.payload.mass_kg"] for v in a.variants[:5]}) == 5
    # a draw does not depend on the number of samples nor on the other parameters
    fewer = dict(MC, samples=3, parameters=dict(list(MC["parameters"].items())[:1]))
    c = load_sweep(_write(tmp_path / "mc3.yaml", dict(BASE, sweep={"monte_carlo": fewer})))
    assert [v.name for v in c.variants] == ["mc000", "mc001", "mc002"]
    for i in range(3):
        key = "plant.payload.mass_kg"
        assert c.variants[i].values[key] == a.variants[i].values[key]
    other = load_sweep(
        _write(tmp_path / "s8.yaml", dict(BASE, sweep={"monte_carlo": dict(MC, seed=8)}))
    )
    assert other.variants[0].values != a.variants[0].values


def _mc(path: str, **dist) -> dict:
    return {"monte_carlo": {"samples": 2, "parameters": {path: dist}}}


MASS = "plant.payload.mass_kg"
SG = "sweep.grid"
SMC = "sweep.monte_carlo"


@pytest.mark.parametrize(
    ("block", "expected"),
    [
        ({"grid": {"controller.outer.gian": [1]}}, f"unknown key at {SG}.controller.outer.gian"),
        ({"grid": {"controller.outer.gian": [1]}}, "(did you mean 'gains'?)"),
        ({"grid": {"controller.outer.gains": 3}}, f"wrong type at {SG}.controller.outer.gains"),
        ({"grid": {"name": ["a"]}}, f"invalid key at {SG}.name"),
        ({"gird": {}}, "unknown key at sweep.gird: allowed keys are ['grid', 'monte_carlo']"),
        ({"monte_carlo": {"seed": 1, "parameters": {}}}, f"missing key at {SMC}.samples"),
        (
            _mc(MASS, distribution="gauss", mean=1, std=1),
            f"invalid value at {SMC}.parameters.{MASS}.distribution: 'gauss'; allowed: one of "
            "['uniform', 'normal', 'choice']",
        ),
        (
            _mc(MASS, distribution="uniform", low=3),
            f"missing key at {SMC}.parameters.{MASS}.high",
        ),
        (
            _mc(MASS, distribution="normal", mean=3, std=-1),
            f"invalid value at {SMC}.parameters.{MASS}.std: -1; allowed: >= 0",
        ),
        (
            _mc("actuator.pneumatics.supply_pressure_bar", distribution="uniform", low=5, high=6),
            "(did you mean 'supply_pressure_bar_gauge'?)",
        ),
        (
            {"monte_carlo": {"samples": 0, "parameters": {"seed": {"distribution": "choice"}}}},
            f"invalid value at {SMC}.samples: 0",
        ),
    ],
)
def test_invalid_sweep_blocks_one_line(block, expected):
    with pytest.raises(UserInputError) as err:
        parse_sweep(block)
    msg = str(err.value)
    assert expected in msg
    assert "\n" not in msg


def test_run_on_a_sweep_file_runs_the_base_and_says_so(tmp_path, capsys):
    path = _grid_file(tmp_path)
    sc = load_scenario(str(path))
    assert "sweep" not in sc.model_dump()
    assert sc.controller.outer.type == "I"
    assert sc == load_scenario(str(_write(tmp_path / "plain.yaml", dict(BASE, name="g"))))
    err = capsys.readouterr().err
    assert "declares 4 variants" in err and "simpro-sim batch" in err
    bad = _write(tmp_path / "bad.yaml", dict(BASE, sweep={"grid": {"controller.nope": [1]}}))
    with pytest.raises(UserInputError, match="unknown key at sweep.grid.controller.nope"):
        load_scenario(str(bad))


def test_shipped_sweeps_expand_and_validate(capsys):
    gain = load_sweep(scenarios_dir() / "sweep_outer_gain.yaml")
    mc = load_sweep(scenarios_dir() / "sweep_monte_carlo.yaml")
    assert len(gain.variants) == 64 and len(mc.variants) == 40
    for sf in (gain, mc):
        assert [v.error for v in sf.variants if v.error] == []
        load_scenario(sf.path)  # the base scenario runs with `simpro-sim run`
    assert gain.variants[0].scenario["actuator"]["model"] == "linear"


# ------------------------------------------------------------------ running


def test_failing_variant_and_invalid_file_reported_others_complete(tmp_path, monkeypatch, capsys):
    import simpro_mj.sim.loop as sim_mod

    real = sim_mod.CoSimulation.run

    def flaky(self, progress=None, **kwargs):
        if self.scenario["controller"]["outer"]["gains"][0] == 4.0:
            raise RuntimeError("injected\nfailure")
        return real(self, progress, **kwargs)

    monkeypatch.setattr(sim_mod.CoSimulation, "run", flaky)
    good = _grid_file(tmp_path, **{"controller.outer.gains": [2, 4]})
    bad = _write(tmp_path / "bad.yaml", dict(BASE, controller={"mode": "task-space"}))
    out = tmp_path / "out"
    argv = ["batch", str(good), str(bad), "--out", str(out), "--jobs", "1", "--no-plots"]
    rc = main([*argv, "--json"])
    assert rc == 1
    doc = json.loads(capsys.readouterr().out)
    rows = _read_csv(out / "summary.csv")
    # 1 s: the 1 deg step at 0.2 s may still be settling at the end (the verdict)
    assert rows[0]["status"] in ("ok", "not_settled")
    assert [r["status"] for r in rows[1:]] == ["failed", "invalid"]
    assert rows[1]["reason"] == "RuntimeError: injected failure"
    assert rows[2]["reason"].startswith("invalid value at controller.mode: 'task-space'")
    assert "(did you mean 'task_space'?)" in rows[2]["reason"]
    assert rows[0]["controller.outer.gains"] == "2" and rows[0]["stable"] == "true"
    assert float(rows[0]["pitch_rms_err_deg"]) > 0
    assert (out / "g" / "gains=2" / "metrics.json").is_file()
    assert not (out / "g" / "gains=4").exists()
    assert doc["counts"]["ok"] + doc["counts"]["not_settled"] == 1
    assert doc["counts"]["failed"] == 1
    assert doc["counts"]["invalid"] == 1
    # --strict refuses the whole batch before anything runs, one line naming the file
    out2 = tmp_path / "strict"
    rc = main(["batch", str(good), str(bad), "--out", str(out2), "--jobs", "1", "--strict"])
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("\n") == 1 and str(bad) in err and "controller.mode" in err
    assert not out2.exists()


def _counted_runs(monkeypatch) -> list:
    """The outer gain of every run that steps, in order (the list fills as they run)."""
    import simpro_mj.sim.loop as sim_mod

    real, calls = sim_mod.CoSimulation.run, []

    def counting(self, progress=None, **kwargs):
        calls.append(self.scenario["controller"]["outer"]["gains"][0])
        return real(self, progress, **kwargs)

    monkeypatch.setattr(sim_mod.CoSimulation, "run", counting)
    return calls


def test_resume_skips_complete_and_recomputes_incomplete(tmp_path, monkeypatch):
    from simpro_mj.report.marker import record

    calls = _counted_runs(monkeypatch)
    path = _grid_file(tmp_path, **{"controller.outer.gains": [1, 2, 3]})
    out = tmp_path / "out"
    argv = ["batch", str(path), "--out", str(out), "--jobs", "1", "--no-plots"]
    assert main(argv) == _batch_exit(out)
    assert calls == [1.0, 2.0, 3.0]
    first = (out / "summary.csv").read_text()
    folders = [out / "g" / f"gains={g}" for g in (1, 2, 3)]
    mtime = (folders[0] / "metrics.json").stat().st_mtime_ns
    # an interrupted run and a missing file are incomplete (the status written as
    # simpro-sim writes it: listed in the folder's marker, else it is the user's file)
    met = json.loads((folders[1] / "metrics.json").read_text())
    met["status"] = "interrupted"
    (folders[1] / "metrics.json").write_text(json.dumps(met))
    record(folders[1], ["metrics.json"], "run")
    (folders[2] / "timeseries.csv").unlink()
    calls.clear()
    assert main([*argv, "--resume"]) == _batch_exit(out)
    assert calls == [2.0, 3.0]
    assert (folders[0] / "metrics.json").stat().st_mtime_ns == mtime
    assert _drop_wall_clock(first) == _drop_wall_clock((out / "summary.csv").read_text())
    # a changed scenario (hash) is recomputed too
    calls.clear()
    assert main([*argv, "--resume", "--set", "seed=5"]) == _batch_exit(out)
    assert calls == [1.0, 2.0, 3.0]


def test_plots_drawn_for_examples_and_failing_variants_only(tmp_path):
    """``--plots examples`` (the default) draws the first variant's figures only;
    ``failing`` also those of every variant whose status is not ok (gain 30 is past
    the outer loop's stability limit), moved in whole (no temporary folder left);
    ``none`` none. The rows are the same whichever is drawn."""
    path = _grid_file(tmp_path, **{"controller.outer.gains": [2, 4, 30]})
    common = [str(path), "--set", "duration_s=3", "--jobs", "1"]
    out = {w: tmp_path / w for w in ("examples", "failing", "none")}
    assert main(["batch", *common, "--out", str(out["examples"])]) == 1
    assert main(["batch", *common, "--out", str(out["failing"]), "--plots", "failing"]) == 1
    assert main(["batch", *common, "--out", str(out["none"]), "--no-plots"]) == 1
    rows = _read_csv(out["failing"] / "summary.csv")
    status = {r["variant"]: r["status"] for r in rows}
    assert status["gains=30"] != "ok" and status["gains=4"] == "ok", status
    figures = {"task_space.png", "joints.png", "valves.png", "pressures.png"}

    def drawn(which: str, variant: str) -> set:
        return {p.name for p in (out[which] / "g" / variant).glob("*.png")}

    for variant, verdict in status.items():
        example = variant == "gains=2"
        assert drawn("examples", variant) == (figures if example else set())
        assert drawn("failing", variant) == (figures if example or verdict != "ok" else set())
        assert drawn("none", variant) == set()
        assert marker.is_complete(out["failing"] / "g" / variant)  # the figures listed as ours
    assert not [p for p in tmp_path.rglob("*") if ".simpro-tmp-" in p.name]
    csvs = [_drop_wall_clock((o / "summary.csv").read_text()) for o in out.values()]
    assert csvs[0] == csvs[1] == csvs[2]


def test_timeseries_written_as_asked_rows_and_resume_the_same(tmp_path, monkeypatch):
    """``--timeseries failing`` writes the CSV of the variant not ok only (gain 30, past
    the outer loop's limit), ``none`` none: every folder is complete all the same, its
    ``metrics.json`` holds the measured stability, the rows are those of ``all``, and
    ``--resume`` reruns nothing. A folder without the CSV whose ``metrics.json`` does
    not say it was not asked for is incomplete (rerun); a folder without the stored
    stability takes it from its CSV, the same row."""
    from simpro_mj.batch.worker import MEASURED_STABILITY
    from simpro_mj.report.marker import TIMESERIES_WRITTEN, record

    calls = _counted_runs(monkeypatch)
    path = _grid_file(tmp_path, **{"controller.outer.gains": [2, 4, 30]})
    common = [str(path), "--set", "duration_s=3", "--jobs", "1", "--no-plots"]
    out = {w: tmp_path / w for w in ("all", "failing", "none")}
    for which, folder in out.items():
        assert main(["batch", *common, "--out", str(folder), "--timeseries", which]) == 1
    status = {r["variant"]: r["status"] for r in _read_csv(out["all"] / "summary.csv")}
    assert status["gains=30"] != "ok" and status["gains=2"] == status["gains=4"] == "ok"
    for which, folder in out.items():
        for variant, verdict in status.items():
            v = folder / "g" / variant
            want = which == "all" or (which == "failing" and verdict != "ok")
            assert (v / "timeseries.csv").is_file() == want, (which, variant)
            doc = json.loads((v / "metrics.json").read_text())
            assert doc.get(TIMESERIES_WRITTEN, True) is want
            assert doc[MEASURED_STABILITY]["stable"] is (variant != "gains=30")
            assert marker.is_complete(v)
    first = [_drop_wall_clock((o / "summary.csv").read_text()) for o in out.values()]
    assert first[0] == first[1] == first[2]
    # the responses figure overlays the series there are
    assert (out["all"] / "plots" / "g_responses.png").is_file()
    assert (out["failing"] / "plots" / "g_responses.png").is_file()
    assert not (out["none"] / "plots" / "g_responses.png").exists()
    calls.clear()
    for which, folder in out.items():
        argv = ["batch", *common, "--out", str(folder), "--timeseries", which, "--resume"]
        assert main(argv) == 1
        assert _drop_wall_clock((folder / "summary.csv").read_text()) == first[0]
    assert calls == []
    # no CSV and no word that it was not asked for: incomplete, rerun
    v = out["none"] / "g" / "gains=4"
    doc = json.loads((v / "metrics.json").read_text())
    del doc[TIMESERIES_WRITTEN]
    (v / "metrics.json").write_text(json.dumps(doc))
    record(v, ["metrics.json"], "run")
    assert not marker.is_complete(v)
    # an earlier batch's folder without the stored stability: read from its CSV
    v = out["all"] / "g" / "gains=30"
    doc = json.loads((v / "metrics.json").read_text())
    del doc[MEASURED_STABILITY]
    (v / "metrics.json").write_text(json.dumps(doc))
    record(v, ["metrics.json"], "run")
    for which in ("none", "all"):
        argv = ["batch", *common, "--out", str(out[which]), "--timeseries", which, "--resume"]
        assert main(argv) == 1
        assert _drop_wall_clock((out[which] / "summary.csv").read_text()) == first[0]
    assert calls == [4.0]


def _batch_exit(out) -> int:
    """A batch's exit status from its summary: 0 when every variant is ok, else 1."""
    rows = _read_csv(out / "summary.csv")
    assert rows and all(r["status"] in ("ok", "not_settled", "limit_cycle") for r in rows)
    return 0 if all(r["status"] == "ok" for r in rows) else 1


def _drop_wall_clock(text: str) -> list[dict]:
    rows = list(csv.DictReader(text.splitlines()))
    for r in rows:
        r.pop("realtime_factor")
    return rows


@pytest.mark.slow  # a process pool and a local Dask cluster over 8 runs each
def test_threads_and_dask_agree_and_plots_written(tmp_path):
    pytest.importorskip("distributed")
    grid = {"controller.outer.type": ["I", "PI"], "controller.outer.gains": [2, 30]}
    path = _grid_file(tmp_path, **grid)
    mc = _write(tmp_path / "mc.yaml", dict(BASE, name="mc", sweep={
        "grid": {"controller.mode": ["joint_only", "task_space"]},
        "monte_carlo": dict(MC, samples=2)}))  # fmt: skip
    pool, dask = tmp_path / "threads", tmp_path / "dask"
    common = [str(path), str(mc), "--set", "duration_s=1.5"]
    # gain 30 is unstable: the runs complete, never ok (the verdict), exit 1, stable false;
    # two worker processes (the default), then a local cluster of one worker process (and its
    # nanny): the tasks shipped to another process are what the comparison is about
    assert main(["batch", *common, "--jobs", "2", "--out", str(pool)]) == 1
    assert main(["batch", *common, "--jobs", "1", "--out", str(dask), "--scheduler", "local",
                 "--no-plots"]) == 1  # fmt: skip
    a = _drop_wall_clock((pool / "summary.csv").read_text())
    b = _drop_wall_clock((dask / "summary.csv").read_text())
    assert len(a) == 8 and a == b
    for folder in ("g/type=PI_gains=30", "mc/mc001_mode=task_space"):
        ts_a = (pool / folder / "timeseries.csv").read_text()
        assert ts_a == (dask / folder / "timeseries.csv").read_text()
        assert json.loads((dask / folder / "metrics.json").read_text())["status"] in (
            "ok",
            "limit_cycle",
            "not_settled",
            "diverged",
        )
    assert (pool / "g" / "type=I_gains=2" / "task_space.png").is_file()
    assert not (dask / "g" / "type=I_gains=2" / "task_space.png").exists()
    plots = sorted(p.name for p in (pool / "plots").iterdir())
    assert plots == ["g_responses.png", "g_vs_gains.png", "mc_mc_ss_error.png", "mc_responses.png"]
    assert all((pool / "plots" / p).stat().st_size > 10_000 for p in plots)
    summary = json.loads((pool / "summary.json").read_text())
    lim = {s["outer_type"]: s for s in summary["stability"]}
    assert set(lim) == {"I", "PI"}
    # the real inner loops behind the ramp set-point filter (Fig. 13, 60 / 30 / 30 ms); the
    # I law by backward Euler (Fig. 7's forward reading: 7.52; no filter: 9.46, 18.63)
    assert math.isclose(lim["I"]["analytic_limit"], 14.084, rel_tol=1e-3)
    assert math.isclose(lim["PI"]["analytic_limit"], 10.537, rel_tol=1e-3)
    assert lim["I"]["largest_stable"] == 2.0 and lim["I"]["smallest_unstable"] == 30.0
    groups = {g["group"]: g for g in summary["monte_carlo"][0]["groups"]}
    assert set(groups) == {"mode=joint_only", "mode=task_space"}


def test_missing_dask_is_one_line_exit_2(tmp_path, monkeypatch, capsys):
    import sys

    monkeypatch.setitem(sys.modules, "distributed", None)
    path = _grid_file(tmp_path)
    rc = main(["batch", str(path), "--out", str(tmp_path / "o"), "--scheduler", "local"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1
    assert "pip install 'simpro-sim[cluster]'" in err
    assert not (tmp_path / "o" / "g").exists()


# ------------------------------------------------------------------ stability criterion


def _columns(t, err_pitch, ref_pitch=None):
    ref = np.radians(2.0) * (t >= 0.5) if ref_pitch is None else ref_pitch
    zero = np.zeros_like(t)
    home = 1.265
    return {
        "time_s": t,
        "roll_ref_rad": zero, "roll_rad": zero,
        "pitch_ref_rad": ref, "pitch_rad": ref - err_pitch,
        "heave_ref_m": zero + home, "heave_m": zero + home,
    }  # fmt: skip


@pytest.mark.parametrize(
    ("sigma", "stable"), [(-0.5, True), (-0.05, True), (0.3, False), (1.0, False)]
)
def test_stability_criterion_on_envelopes(sigma, stable):
    t = np.arange(0.0, 12.0, 0.001)
    err = np.radians(0.5) * np.exp(sigma * (t - 1.5)) * np.sin(2 * np.pi * 1.3 * t) * (t >= 0.5)
    s = stability_of(_columns(t, err))
    assert s.stable is stable, s
    assert s.growth_rate_1_s == pytest.approx(sigma, abs=0.08)


def test_stability_criterion_offset_and_held_oscillation():
    t = np.arange(0.0, 12.0, 0.001)
    # joint-only-like: a constant offset of 0.4 deg is not an instability
    offset = np.radians(0.4) * (t >= 1.0)
    assert stability_of(_columns(t, offset)).stable is True
    # an oscillation held at 3 deg by saturation (reference 2 deg) is one
    held = np.radians(3.0) * np.sin(2 * np.pi * 1.1 * t) * (t >= 1.0)
    s = stability_of(_columns(t, held))
    assert s.stable is False and "held" in s.why
    # noise at the sensor floor, no set-point: stable, no growth rate
    rng = np.random.default_rng(0)
    noise = np.radians(0.005) * rng.standard_normal(t.size)
    s = stability_of(_columns(t, noise, ref_pitch=np.zeros_like(t)))
    assert s.stable is True and s.growth_rate_1_s is None
    assert stability_of(_columns(t, offset), status="diverged").stable is False


def test_variant_stability_from_memory_is_the_folders(tmp_path):
    """A variant's stability is taken from its columns in memory rounded as
    ``timeseries.csv`` writes them: every figure equal, bit for bit, to the folder's
    read back (what ``--resume`` rebuilds a row from). An unstable gain (30, past the
    outer loop's limit) gives a growth rate and an oscillation to compare."""
    from simpro_mj.batch.stability import stability_of_folder
    from simpro_mj.batch.worker import AsWritten, run_variant
    from simpro_mj.report.results import NUMBER_FORMAT

    scenario = load_scenario(
        str(_grid_file(tmp_path)), ["duration_s=3", "controller.outer.gains=30"]
    )
    got = run_variant({"scenario": scenario, "out": str(tmp_path / "v"), "plots": "none"})
    again = stability_of_folder(tmp_path / "v", got["status"])
    assert got["stability"] == again and again.growth_rate_1_s is not None
    assert again.stable is False, again
    # the rounding is the file's: 12 significant digits, NaN kept
    cols = AsWritten({"x": np.array([1 / 3, np.nan, -2.0e-7 / 3, 1e300])})
    assert cols["x"][0] == 0.333333333333 and np.isnan(cols["x"][1])
    assert cols["x"][2] == -6.66666666667e-08 and cols["x"][3] == 1e300
    # each distinct value formatted once, every sample mapped back (-0.0 kept)
    x = np.array([0.5, -0.0, 2 / 3, 0.0, 2 / 3, 0.5, np.nan, 1 / 7])
    read = AsWritten({"x": x})["x"]
    assert [float(NUMBER_FORMAT % v) for v in x[[0, 2, 5, 7]]] == list(read[[0, 2, 5, 7]])
    assert read[2] == read[4] == 0.666666666667 and np.isnan(read[6])
    assert np.signbit(read[1]) and not np.signbit(read[3])


def test_jobs_and_paths_errors(tmp_path, capsys):
    path = _grid_file(tmp_path)
    assert main(["batch", str(path), "--jobs", "0", "--out", str(tmp_path / "o")]) == 2
    assert "--jobs" in capsys.readouterr().err
    # a folder expands to its YAML files; an empty one is an invalid row
    empty = tmp_path / "empty"
    empty.mkdir()
    rc = main(["batch", str(empty), "--out", str(tmp_path / "o2"), "--jobs", "1", "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert rc == 1 and doc["counts"]["invalid"] == 1
    assert os.path.exists(tmp_path / "o2" / "summary.csv")


# ------------------------------------------------------------------ sweep fuzz

_leaf = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**6), 10**6),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),
)
_vals = st.recursive(
    _leaf,
    lambda ch: st.one_of(
        st.lists(ch, max_size=4), st.dictionaries(st.text(max_size=8), ch, max_size=4)
    ),
    max_leaves=12,
)
_paths = st.sampled_from(
    ["controller.outer.gains", "controller.outer.type", "plant.payload.mass_kg",
     "sensors.imu.bias_deg", "duration_s", "nope.x", "seed", ""]
)  # fmt: skip
_dist = st.fixed_dictionaries(
    {"distribution": st.sampled_from(["uniform", "normal", "choice", "beta"])},
    optional={k: _vals for k in ("low", "high", "mean", "std", "values", "x")},
)
_blocks = st.one_of(
    _vals,
    st.fixed_dictionaries(
        {},
        optional={
            "grid": st.one_of(_vals, st.dictionaries(_paths, _vals, max_size=3)),
            "monte_carlo": st.one_of(
                _vals,
                st.fixed_dictionaries(
                    {},
                    optional={
                        "samples": _vals,
                        "seed": _vals,
                        "parameters": st.one_of(
                            _vals, st.dictionaries(_paths, st.one_of(_dist, _vals), max_size=3)
                        ),
                    },
                ),
            ),
            "bogus": _vals,
        },
    ),
)


@settings(max_examples=300, deadline=None, suppress_health_check=list(HealthCheck))
@example({"grid": {"\n": None}})  # a key with a newline once broke the one-line message
@given(_blocks)
def test_sweep_blocks_expand_or_raise_one_line_user_input_error(block):
    """Random sweep blocks: a valid one expands, anything else is one UserInputError line."""
    try:
        spec = parse_sweep(block)
        if spec is not None and spec.count <= 200:
            assert len(expand(spec)) == spec.count
    except UserInputError as exc:
        assert "\n" not in str(exc) and " at sweep" in str(exc)
