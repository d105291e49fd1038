"""design_plant: identified on the scenario's own plant.

See :mod:`simpro_mj.identification.auto`.
"""

from __future__ import annotations

import json

import pytest

import simpro_mj.identification.auto as ai
from simpro_mj.config.scenario import load_scenario
from simpro_mj.core.errors import UserInputError

IDENT = "controller.inner.design_plant=identified"


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("SIMPRO_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(ai, "_memo", {})
    return tmp_path / "identified"


def test_the_presets_own_plant_needs_no_experiment(cache, fake_identify):
    sc = load_scenario("step_pitch", [IDENT])
    models, source = ai.identified_models(sc)
    assert source == "preset" and fake_identify == []
    assert models == sc.controller.inner.identified.model_dump()


def test_a_changed_plant_is_identified_once_then_read_from_the_cache(cache, fake_identify):
    sc = load_scenario("step_pitch", [IDENT, "plant.payload.mass_kg=80"])
    models, source = ai.identified_models(sc)
    assert source == "identified" and len(fake_identify) == 1
    assert fake_identify[0]["model"]["payload"]["mass_kg"] == 80.0  # the scenario's plant
    assert models["actuator1"]["a0"] == 180.0
    files = list(cache.glob("*.json"))
    assert len(files) == 1 and json.loads(files[0].read_text()) == models
    ai._memo.clear()  # a new process: the file answers
    again, source = ai.identified_models(sc)
    assert source == "cache" and again == models and len(fake_identify) == 1
    other = load_scenario("step_pitch", [IDENT, "plant.payload.mass_kg=81"])
    assert ai.identified_models(other)[1] == "identified" and len(fake_identify) == 2


def test_damaged_cache_file_is_identified_again(cache, fake_identify):
    sc = load_scenario("step_pitch", [IDENT, "plant.payload.mass_kg=80"])
    ai.identified_models(sc)
    (f,) = cache.glob("*.json")
    f.write_text("{not json")
    ai._memo.clear()
    assert ai.identified_models(sc)[1] == "identified" and len(fake_identify) == 2


def test_preset_choice_and_paper_design_run_no_experiment(cache, fake_identify):
    sc = load_scenario(
        "step_pitch", [IDENT, "plant.payload.mass_kg=80", "controller.inner.identify=preset"]
    )
    assert ai.identified_models(sc)[1] == "preset"
    paper = load_scenario("step_pitch", ["plant.payload.mass_kg=80"])
    assert ai.with_identified(paper) == (paper, "preset")
    assert fake_identify == []
    with pytest.raises(UserInputError, match="controller.inner.identify"):
        load_scenario("step_pitch", ["controller.inner.identify=always"])


def test_the_simulation_designs_on_the_scenarios_own_plant(cache, monkeypatch):
    """The real experiment, short: the heavy cabin with a lighter payload identifies
    a higher natural frequency than its preset's models, and the joint controllers
    are placed on what was identified (k_p b kept: corrected_design)."""
    sc = load_scenario(
        "step_pitch",
        ["plant.preset=heavy_cabin", IDENT, "plant.payload.mass_kg=60", "duration_s=0.2"],
    )
    import simpro_mj.identification.identify as ident
    from simpro_mj.sim.build import Build

    monkeypatch.setitem(ident.DEFAULT_IDENTIFY_PARAMS, "duration_s", 4.0)  # short PRBS
    preset_a0 = sc.controller.inner.identified.actuator1.a0
    cs = Build(sc).simulation()
    assert cs.identified_source == "identified"
    own = cs.scenario["controller"]["inner"]["identified"]
    assert own["actuator1"]["a0"] > 1.2 * preset_a0  # lighter: stiffer per kg
    assert len(list(cache.glob("*.json"))) == 1


def test_a_batch_counts_the_identification_line_instead_of_printing_it(
    cache, fake_identify, capsys
):
    from simpro_mj.core import notices

    said, phases = [], []
    scs = [load_scenario("step_pitch", [IDENT, f"plant.payload.mass_kg={m}"]) for m in (80, 90)]
    with notices.collecting(phases.append) as c:
        for sc in scs:
            ai.with_identified(sc, said.append)
    assert said == [] and len(fake_identify) == 2
    ((text, count),) = c.counts.items()
    assert text.startswith("identifying the scenario's own plant (Fig. 12)") and count == 2
    assert phases == ["identifying", "simulating"] * 2
    ai.with_identified(
        load_scenario("step_pitch", [IDENT, "plant.payload.mass_kg=70"]), said.append
    )
    assert len(said) == 1 and said[0] == text  # outside a batch: said at once


def test_experiment_seconds_name_the_variants_that_identify(cache, fake_identify):
    from simpro_mj.batch.runner import EXPERIMENT_WEIGHT, expected_cost

    new = load_scenario("step_pitch", [IDENT, "plant.payload.mass_kg=80"])
    ip = ai.plant_tree(new)["identify"]
    assert ai.experiment_s(new) == pytest.approx(3 * (ip["settle_s"] + ip["duration_s"]))
    assert ai.experiment_s(load_scenario("step_pitch", [IDENT])) == 0.0  # the preset's plant
    paper = load_scenario("step_pitch", ["plant.payload.mass_kg=80"])
    assert ai.experiment_s(paper) == 0.0  # designed on the paper's plants
    variant = new.model_dump()  # a batch variant's resolved scenario
    assert expected_cost(variant) == pytest.approx(
        new.duration_s + EXPERIMENT_WEIGHT * ai.experiment_s(new)
    )
    ai.identified_models(new)  # now cached: the run alone
    assert ai.experiment_s(new) == 0.0 and expected_cost(variant) == new.duration_s
    # no experiment: the reduced chain's identification, or the paper's design plants
    sets = ["controller.inner.identify=reduced", "plant.payload.mass_kg=90"]
    reduced = load_scenario("step_pitch", sets).model_dump()
    assert expected_cost(reduced) == reduced["duration_s"]
    assert expected_cost(paper.model_dump()) == paper.duration_s


def test_threads_needing_one_new_plant_run_one_experiment(cache, monkeypatch):
    # a batch's two threads start on variants of the same new plant: the second waits
    # for the first's models instead of running the experiment again
    import threading

    import simpro_mj.identification.identify as ident

    calls, b_started = [], threading.Event()

    def slow(tree, legs=(1, 2, 3), records=None):
        calls.append(threading.current_thread().name)
        b_started.wait(10.0)  # the other thread is on its way before this one ends
        threading.Event().wait(0.3)  # and has time to reach the experiment, were it let
        return {f"actuator{i}": ident.Fit(b=10.0, a1=20.0, a0=300.0) for i in legs}

    monkeypatch.setattr(ident, "identify", slow)
    sc = load_scenario("step_pitch", [IDENT, "plant.payload.mass_kg=80"])
    got = {}

    def one(name):
        if name == "b":
            b_started.set()
        got[name] = ai.identified_models(sc)

    a = threading.Thread(target=one, args=("a",), name="a")
    a.start()
    while not calls:  # thread a is inside the experiment
        threading.Event().wait(0.01)
    b = threading.Thread(target=one, args=("b",), name="b")
    b.start()
    a.join(30.0)
    b.join(30.0)
    assert calls == ["a"]
    assert got["a"] == (got["b"][0], "identified") and got["b"][1] == "cache"


def test_far_out_gains_on_a_changed_plant_are_refused_before_the_experiment(cache, fake_identify):
    """The refusal at 10 times the stability limit costs no identification: it is
    checked on the preset's models first (heavy_cabin: limit 14.0, so 150 is refused)."""
    from simpro_mj.job.run import Run

    sc = load_scenario(
        "step_pitch",
        ["plant.preset=heavy_cabin", "plant.payload.mass_kg=231.5", "controller.outer.gains=150"],
    )
    assert ai.experiment_s(sc) > 0  # a changed plant: an experiment would run
    with pytest.raises(UserInputError, match=r"at controller.outer.gains: 150 is 11 times .* 14"):
        Run(sc).preflight()
    assert fake_identify == []  # refused first


def test_the_linearised_models_need_no_experiment(cache, fake_identify):
    """identify: linearised fits the experiment's linear model: no experiment, no cache
    file, and on step_pitch's plant within 6 % of the preset's identified models on
    every parameter (1.6 / 2.1 / 0.6 % on leg 1; legs 2 and 3 down to -5.8 %: the
    as-built plant is not the preset's; docs/paper-notes.md)."""
    sc = load_scenario("step_pitch", [IDENT, "controller.inner.identify=linearised"])
    assert ai.experiment_s(sc) == 0.0
    models, source = ai.identified_models(sc)
    assert source == "linearised" and fake_identify == [] and not list(cache.glob("*.json"))
    given = sc.controller.inner.identified  # the preset's: the experiment's fit
    for a in ("actuator1", "actuator2", "actuator3"):
        for k in ("b", "a1", "a0"):
            assert models[a][k] == pytest.approx(getattr(getattr(given, a), k), rel=0.06)


def test_a_plant_whose_seals_stick_is_refused_by_the_linearisation(cache, fake_identify):
    """The heavy cabin's seals (150 N running, 250 N breakaway) dominate its experiment:
    the describing function's equivalent viscous friction is about 7.2e4 N s/m against
    the seal's 300, a stick-slip no linear model represents; refused in one line
    naming the choice and the alternatives."""
    sc = load_scenario(
        "step_pitch",
        ["plant.preset=heavy_cabin", IDENT, "controller.inner.identify=linearised"],
    )
    with pytest.raises(
        UserInputError, match=r"at controller.inner.identify: linearised: the seals' dry.*auto"
    ):
        ai.identified_models(sc)
    assert fake_identify == []


def test_metrics_name_the_models_the_loops_were_placed_on(cache, fake_identify):
    """``scenario.yaml`` keeps the scenario as given (the preset's models under
    ``identified``); ``metrics.json`` → ``design_plants`` says what the joint loops
    were placed on: the plant's own models from the experiment, the same whether it
    ran now or was read from the cache, and the preset's where nothing was identified."""
    from simpro_mj.api import run

    sets = {"controller.inner.design_plant": "identified", "plant.payload.mass_kg": 80}
    sets["duration_s"] = 0.2
    first = run("step_pitch", sets).metrics["design_plants"]
    own = {f"actuator{i}": {"b": 10.0 + i, "a1": 20.0, "a0": 180.0} for i in (1, 2, 3)}
    assert first == {"design_plant": "identified", "source": "identified", "models": own}
    ai._memo.clear()  # a new process: the cache file answers
    assert run("step_pitch", sets).metrics["design_plants"] == first
    assert len(fake_identify) == 1
    paper = run("step_pitch", {"duration_s": 0.2})
    preset = paper.scenario.controller.inner.identified.model_dump()
    want = {"design_plant": "paper", "source": "preset", "models": preset}
    assert paper.metrics["design_plants"] == want


def test_a_plants_tree_follows_the_identify_defaults_as_they_are_now(monkeypatch):
    """The tree a run's plant is identified from is merged when asked, not kept for the
    process: a tree kept from a first call would carry the defaults of that moment (a
    4 s record patched in by a test) into every later identification in the process."""
    import simpro_mj.identification.identify as ident

    sc = load_scenario("step_pitch", [IDENT, "plant.payload.mass_kg=80"])
    assert ai.plant_tree(sc)["identify"]["duration_s"] == 20.0
    with monkeypatch.context() as m:
        m.setitem(ident.DEFAULT_IDENTIFY_PARAMS, "duration_s", 4.0)
        assert ai.plant_tree(sc)["identify"]["duration_s"] == 4.0
    assert ai.plant_tree(sc)["identify"]["duration_s"] == 20.0


def test_the_reduced_experiment_identifies_a_changed_plant_and_caches_apart(cache, fake_identify):
    """identify: reduced runs the experiment on the reduced chain (no MuJoCo record:
    the experiment's function is not called), caches its models apart from the
    experiment's (another file for the same plant), and reads them back; on the heavy
    cabin at 231.5 kg its leg 1 is the sticking leg the experiment fits (a0 of tens
    of 1/s^2, not the hundreds of the held pair)."""
    sets = ["plant.preset=heavy_cabin", "plant.payload.mass_kg=231.5", IDENT]
    sc = load_scenario("step_pitch", [*sets, "controller.inner.identify=reduced"])
    assert ai.experiment_s(sc) == 0.0  # no MuJoCo experiment to schedule
    models, source = ai.identified_models(sc)
    assert source == "reduced" and fake_identify == []
    assert 5.0 < models["actuator1"]["a0"] < 100.0 < models["actuator2"]["a0"]
    (f,) = cache.glob("*.json")
    assert json.loads(f.read_text()) == models
    ai._memo.clear()
    assert ai.identified_models(sc) == (models, "reduced")
    auto = load_scenario("step_pitch", sets)
    assert ai.identified_models(auto)[1] == "identified" and len(fake_identify) == 1
    assert len(list(cache.glob("*.json"))) == 2
