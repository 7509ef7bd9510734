"""The engine simulator of the diagnosis: cache, scale model, box walls, engine validation."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import bedstruct.diagnose as dg
from bedstruct.diagnose.catalogue import CAPILLARY_ASPERITY
from bedstruct.diagnose.measurements import MeasurementSet
from bedstruct.diagnose.measurement_io import measurement_from_dict
from bedstruct.errors import ConfigError
from bedstruct.diagnose.engine_simulator import EngineSimulator, effects_config
from bedstruct.workflows.config import load_config


def _psd_design():
    m = measurement_from_dict({"name": "psd", "kind": "psd", "percentiles": [10, 50, 90],
                               "value": [0, 0, 0], "uncertainty": 1e-6,
                               "conditions": {"stage": "before"}})
    return MeasurementSet((m,))


def test_cache_returns_the_stored_call_and_keys_on_everything_that_matters(tmp_path):
    # the PSD before spreading needs no workflow run: the cache is exercised in milliseconds
    cfg = {"preset": "tiny", "cache": str(tmp_path / "cache")}
    sim = EngineSimulator(_psd_design(), cfg)
    a = sim({}, {"missing_fines": 0.1}, 3)
    files = list((tmp_path / "cache").glob("*.json"))
    assert len(files) == 1 and sim.n_cached == 0
    again = EngineSimulator(_psd_design(), cfg)          # a new process would see the same
    b = again({}, {"missing_fines": 0.1}, 3)
    assert again.n_cached == 1 and np.array_equal(a["psd"], b["psd"])
    # the stored value is what is returned: tamper with it and the cache answers
    doc = json.loads(files[0].read_text())
    (entry,) = doc["observables"].values()
    entry["value"] = [1.0, 2.0, 3.0]
    files[0].write_text(json.dumps(doc))
    assert again({}, {"missing_fines": 0.1}, 3)["psd"].tolist() == [1.0, 2.0, 3.0]
    k = again.cache_key({}, {"missing_fines": 0.1}, 3)
    assert k != again.cache_key({}, {"missing_fines": 0.1}, 4)
    assert k != again.cache_key({}, {"missing_fines": 0.05}, 3)
    assert k != again.cache_key({"friction": 0.5}, {"missing_fines": 0.1}, 3)
    assert k != EngineSimulator(_psd_design(), dict(cfg, overrides=["spread.speed=0.2"])) \
        .cache_key({}, {"missing_fines": 0.1}, 3)
    # LIGGGHTS/LAMMPS calls carry the deck revision (entries of older decks are stale); the
    # embedded calls' keys do not depend on it
    import bedstruct.diagnose.engine_cache as dsim
    ext = EngineSimulator(_psd_design(), dict(cfg, overrides=["engine=liggghts"]))
    ek = ext.cache_key({}, {"missing_fines": 0.1}, 3)
    assert ek != k
    rev = dsim._DECK_REVISION
    try:
        dsim._DECK_REVISION = rev + 1
        assert ext.cache_key({}, {"missing_fines": 0.1}, 3) != ek
        assert again.cache_key({}, {"missing_fines": 0.1}, 3) == k
    finally:
        dsim._DECK_REVISION = rev
    # an unreadable entry is ignored (and recomputed), never trusted
    files[0].write_text("{not json")
    c = again({}, {"missing_fines": 0.1}, 3)
    np.testing.assert_array_equal(c["psd"], a["psd"])


def test_prefetch_runs_a_batch_in_worker_processes_with_the_same_results(tmp_path):
    """``jobs = 2``: a batch of calls runs in two spawned processes; each call's observations
    equal the serial simulator's, later calls take them without running again, and the
    workers fill the cache. ``jobs = 1`` runs nothing ahead."""
    calls = [({}, {"missing_fines": 0.1}, s) for s in (3, 4, 5)] + [({}, {}, 3)]
    serial = EngineSimulator(_psd_design(), {"preset": "tiny"})
    expected = [serial(*c)["psd"] for c in calls]
    assert EngineSimulator(_psd_design(), {"preset": "tiny"}).prefetch(calls) == 0
    par = EngineSimulator(_psd_design(), {"preset": "tiny", "jobs": 2, "cache": str(tmp_path)})
    assert par.prefetch(calls + calls[:1], progress=True) == 4   # duplicates run once
    assert len(list(tmp_path.glob("*.json"))) == 4
    assert par.prefetch(calls) == 0                       # all fetched (and cached)
    got = [par(*c)["psd"] for c in calls]
    for g, e in zip(got, expected):
        np.testing.assert_array_equal(g, e)
    assert par.n_cached == 0                              # served from the fetched batch
    with pytest.raises(ConfigError, match="jobs"):
        EngineSimulator(_psd_design(), {"preset": "tiny", "jobs": 0})
    # a call that fails in its worker stops the batch with that call's own error
    bad = EngineSimulator(_psd_design(), {"preset": "tiny", "jobs": 2})
    with pytest.raises(ConfigError, match="not known to the engine"):
        bad.prefetch([({"viscosity": 1.0}, {}, 0)] + calls)


def test_fingerprints_hand_the_whole_batch_to_a_parallel_simulator():
    """compute_fingerprints asks for every point x seed at once (one batch), before it
    reads them one by one."""
    from bedstruct.diagnose import SurrogateSimulator, catalogue, compute_fingerprints, \
        diagnosis_design, twin_design
    from bedstruct.diagnose.surrogate import BASE_PARAMETERS
    design = diagnosis_design(twin_design(), catalogue())
    inner = SurrogateSimulator(design)
    batches, calls, calls_before = [], [], []

    class Recording:
        name = "surrogate"

        def prefetch(self, batch, progress=False):
            batches.append(list(batch))
            calls_before.append(len(calls))
            return 0

        def __call__(self, base, effects, seed):
            calls.append((dict(base), dict(effects), seed))
            return inner(base, effects, seed)
    effects = catalogue()[:2]
    compute_fingerprints(Recording(), design, dict(BASE_PARAMETERS), effects, replicates=2)
    first = batches[0]
    assert len(first) == (1 + 1 + 2 * len(effects)) * 2
    assert all(c in first for c in calls)
    assert calls_before[0] == 0   # the probe call is in the batch, not run on its own first


def test_cached_observables_are_shared_between_designs_with_equal_conditions():
    sim = EngineSimulator(dg.engine_twin_design(), {"preset": "tiny"})
    seed = dg.load_measurements(dg.__file__.replace("bedstruct/diagnose/__init__.py",
                                                    "data/measurements/seed.toml"))
    spec = {m.name: json.dumps(sim._spec(m), sort_keys=True) for m in sim.design}
    for m in seed:  # every seed observable maps onto a twin-design entry (same runs)
        assert json.dumps(sim._spec(m), sort_keys=True) in spec.values(), m.name
    # the tiny preset has 2 layers: layers 3 and 4 are its layer 2
    assert json.dumps(sim._spec(seed["bed_height_layer4"]), sort_keys=True) == spec["bed_height_layer2"]
    # a narrow box has side walls, the seed's 30 mm box is the periodic strip
    assert sim._spec(sim.design["static_angle_narrow_box"])["walled"] is True
    assert sim._spec(sim.design["static_angle"])["walled"] is False


def test_effect_parameters_are_mapped_to_the_scale_model():
    tiny = EngineSimulator(_psd_design(), {"preset": "tiny"})
    seed = EngineSimulator(_psd_design(), {"preset": "seed"})
    fx = effects_config({"blade_startup": 0.2, "contact_ageing": 1.0, "missing_fines": 0.1,
                         "capillary_bridges": 0.5})
    assert seed.scale_effects(fx) == fx          # the seed preset is full scale
    s = tiny.scale_effects(fx)
    cfg = tiny.base_cfg
    stroke_ratio = (cfg["spread"]["plate_length"] / cfg["spread"]["speed"]) / (18.9e-3 / 0.0254)
    assert s["spread.ramp_time"] == pytest.approx(0.2 * stroke_ratio)
    assert s["spread.vibration_frequency"] * s["spread.ramp_time"] == pytest.approx(
        fx["spread.vibration_frequency"] * fx["spread.ramp_time"])
    assert s["contact.ageing_time_constant"] == pytest.approx(10.0 / 1000)
    # the bond's break slip is the same fraction of a (coarse-grained) particle
    assert s["contact.ageing_break_slip"] == pytest.approx(fx["contact.ageing_break_slip"] * cfg["psd"]["scale"])
    assert s["psd.fines_median_diameter"] / cfg["psd"]["d_min"] == pytest.approx(20e-6 / 28e-6)
    # capillary bridges at the same Bond number (force / weight) as the seed powder: the
    # engine's pull-off 2 pi (2 R*) gamma' cos(theta) at the coarse-grained size
    ps = cfg["psd"]["scale"]
    d_seed, d_tiny = 52.08e-6, 52.08e-6 * ps

    def bond(p, d):
        f = 2 * math.pi * (d / 2) * p["contact.capillary_surface_tension"] * math.cos(
            p["contact.capillary_contact_angle"])
        return f / (math.pi / 6 * d ** 3 * 8300.0 * 9.81)
    assert bond(s, d_tiny) == pytest.approx(bond(fx, d_seed))
    # bridge volume 2 pi R*^2 t scales as a volume
    v = lambda p, d: 2 * math.pi * (d / 4) ** 2 * p["contact.capillary_film_thickness"]  # noqa: E731
    assert v(s, d_tiny) == pytest.approx(v(fx, d_seed) * ps ** 3)
    assert CAPILLARY_ASPERITY["asperity_radius"] < 1e-6
    with pytest.raises(ConfigError, match="blade_time_scale"):
        EngineSimulator(_psd_design(), {"preset": "tiny", "blade_time_scale": 0.0})


def test_validate_names_its_simulator_and_rejects_unknown_ones():
    with pytest.raises(ConfigError, match="simulator"):
        dg.validate("tiny", simulator="lammps")
    with pytest.raises(ConfigError, match="preset"):
        dg.validate("mini")                      # an engine-only preset
    d = dg.engine_twin_design()
    roles = {m.role for m in d}
    assert roles == {"calibrate", "validate"}
    assert d["static_angle_narrow_box"].conditions.get("box_width") == pytest.approx(3e-3)
    # the full campaign measures what the diagnosis would ask for next: every candidate
    full = dg.engine_twin_design("full")
    from bedstruct.diagnose.diagnosis import candidate_design
    assert not candidate_design(dg.catalogue(), full).names
    assert set(d.names) < set(full.names)
    assert {full[n].role for n in set(full.names) - set(d.names)} == {"calibrate"}
    assert full["avalanche_angle_rest600"].conditions.get("rest_time") == 600.0
    with pytest.raises(ConfigError, match="campaign"):
        dg.engine_twin_design("everything")
    with pytest.raises(ConfigError, match="full campaign already"):
        dg.validate("tiny", campaign="full")     # the surrogate's design is one


def test_cli_validate_cache_needs_the_engine(capsys):
    from bedstruct.cli import main
    rc = main(["diagnose", "validate", "--cache", "/nonexistent"])
    assert rc != 0
    assert "--simulator engine" in capsys.readouterr().err


def test_scale_models_read_every_layer_the_design_needs_and_validate_picks_its_own():
    """The diagnosis' scale models: a 6 mm platform (a free toe ahead of x1/x2 heaps), no
    dumps, and (small) three layers: layer 3 is the dynamic angle's, nothing reads a fourth."""
    from bedstruct.diagnose.validation.design import engine_scale_model
    from bedstruct.diagnose.engine_simulator import PRESET_OVERRIDES
    d = dg.engine_twin_design()
    needed = max(int(m.conditions.get("layer", 1)) for m in d)
    for preset in ("tiny", "small"):
        sim = EngineSimulator(_psd_design(), {"preset": preset})
        sc = sim.base_cfg["spread"]
        assert sc["plate_length"] == pytest.approx(6e-3)
        assert sim.base_cfg["output"]["frames"] is False
        assert sim.overrides[:len(PRESET_OVERRIDES[preset])] == list(PRESET_OVERRIDES[preset])
    small = EngineSimulator(_psd_design(), {"preset": "small"}).base_cfg["spread"]
    assert len(small["gaps"]) == needed == 3
    assert small["pile_particles"] == 2600
    assert [engine_scale_model(p) for p in ("mini", "tiny", "small")] == ["tiny", "tiny", "small"]
    assert dg.ENGINE_PRESETS["small"]["replicates"] >= 3


def test_narrow_box_is_run_with_side_walls_and_the_wide_box_periodic(monkeypatch):
    """The repose configuration each static angle is simulated with (runs replaced by a stub)."""
    import types

    import bedstruct.workflows.repose as repose
    seen = []

    def fake_run_repose(cfg, *, out, replicates):
        seen.append((bool(cfg["repose"]["periodic_width"]), cfg["contact"]["wall_friction"]))
        return types.SimpleNamespace(angle_deg=30.0 + len(seen))
    monkeypatch.setattr(repose, "run_repose", fake_run_repose)
    d = dg.engine_twin_design()
    design = MeasurementSet((d["static_angle"], d["static_angle_narrow_box"]))
    obs = EngineSimulator(design, {"preset": "tiny"})({}, {"wall_friction": 0.3}, 0)
    mu = load_config(preset="tiny")["contact"]["friction"]   # the wall: mu + 0.3
    assert seen == [(True, pytest.approx(mu + 0.3)), (False, pytest.approx(mu + 0.3))]
    assert obs["static_angle"][0] == 31.0 and obs["static_angle_narrow_box"][0] == 32.0


def test_an_angle_after_rest_rests_the_pile_on_the_ageing_clock(monkeypatch, tmp_path):
    """``rest_time`` of a static angle reaches the repose run (scaled like the ageing law's
    times) when contacts age; without ageing the rested pile is the unrested one (one run).
    The cache keeps the two apart, and the keys of calls without a rest are those written
    before the option existed."""
    import types

    import bedstruct.workflows.repose as repose
    seen = []

    def fake_run_repose(cfg, *, out, replicates):
        seen.append(cfg["repose"]["rest_time"])
        return types.SimpleNamespace(angle_deg=30.0 + 5.0 * cfg["repose"]["rest_time"])
    monkeypatch.setattr(repose, "run_repose", fake_run_repose)
    rested = measurement_from_dict({"name": "after_rest", "kind": "static_angle", "value": 0.0,
                                    "uncertainty": 1.0,
                                    "conditions": {"rest_time": 600.0, "box_width": 0.03}})
    design = MeasurementSet((dg.engine_twin_design()["static_angle"], rested))
    sim = EngineSimulator(design, {"preset": "tiny", "cache": str(tmp_path)})
    obs = sim({}, {"contact_ageing": 1.0}, 0)
    assert seen == [0.0, pytest.approx(600.0 / sim.ageing_time_scale)]
    assert obs["after_rest"][0] == pytest.approx(30.0 + 5.0 * 600.0 / sim.ageing_time_scale)
    seen.clear()
    obs = sim({}, {}, 0)                      # no ageing: the same run serves both
    assert seen == [0.0] and obs["after_rest"][0] == obs["static_angle"][0] == 30.0
    import hashlib

    from bedstruct.diagnose.engine_cache import _CACHE_SCHEMA
    cfg = sim.run_config({}, {}, 0)
    assert cfg["repose"].pop("rest_time") == 0.0
    old_doc = {"schema": _CACHE_SCHEMA, "config": cfg, "wide_box": sim.wide_box,
               "speed_scale": sim.speed_scale}
    old_key = hashlib.sha256(json.dumps(old_doc, sort_keys=True, default=float).encode()).hexdigest()[:32]
    assert sim.cache_key({}, {}, 0) == old_key
    # ... also with another effect on (its inert ageing parameters are not rescaled)
    cap = sim.run_config({}, {"capillary_bridges": 0.3}, 0)
    cap["repose"].pop("rest_time")
    assert cap["contact"]["ageing_break_slip"] == 1e-6
    cap_doc = {"schema": _CACHE_SCHEMA, "config": cap, "wide_box": sim.wide_box,
               "speed_scale": sim.speed_scale}
    assert sim.cache_key({}, {"capillary_bridges": 0.3}, 0) == hashlib.sha256(
        json.dumps(cap_doc, sort_keys=True, default=float).encode()).hexdigest()[:32]
    # a call with contact ageing on carries the ageing model's revision (older entries stale)
    aged = sim.run_config({}, {"contact_ageing": 1.0}, 0)
    aged["repose"].pop("rest_time")
    stale = {"schema": _CACHE_SCHEMA, "config": aged, "wide_box": sim.wide_box,
             "speed_scale": sim.speed_scale}
    stale_key = hashlib.sha256(json.dumps(stale, sort_keys=True, default=float).encode()).hexdigest()[:32]
    assert sim.cache_key({}, {"contact_ageing": 1.0}, 0) != stale_key


def test_a_pile_without_flanks_is_missing_data_and_cached_as_such(monkeypatch, tmp_path):
    """No flank to fit (a cohesive block): NaN, never a straight-line reading of its flat top;
    the NaN is cached like any result, so the run is not repeated."""
    import types

    import bedstruct.workflows.repose as repose
    calls = []

    def fake_run_repose(cfg, *, out, replicates):
        calls.append(1)
        return types.SimpleNamespace(angle_deg=float("nan"))
    monkeypatch.setattr(repose, "run_repose", fake_run_repose)
    design = MeasurementSet((dg.engine_twin_design()["static_angle"],))
    cfg = {"preset": "tiny", "cache": str(tmp_path)}
    obs = EngineSimulator(design, cfg)({}, {"capillary_bridges": 0.8}, 0)
    assert np.isnan(obs["static_angle"][0])
    again = EngineSimulator(design, cfg)
    assert np.isnan(again({}, {"capillary_bridges": 0.8}, 0)["static_angle"][0])
    assert len(calls) == 1 and again.n_cached == 1


def test_each_engine_call_is_counted_and_reported_but_not_a_cached_one(monkeypatch, tmp_path):
    """A twin of a validation runs for hours: the simulator counts the calls that ran the
    engine and calls ``on_call`` after each, which the validation's bar shows; a cached
    answer runs nothing and is not counted."""
    import types

    import bedstruct.workflows.repose as repose
    monkeypatch.setattr(repose, "run_repose",
                        lambda cfg, *, out, replicates: types.SimpleNamespace(angle_deg=30.0))
    design = MeasurementSet((dg.engine_twin_design()["static_angle"],))
    sim = EngineSimulator(design, {"preset": "tiny", "cache": str(tmp_path)})
    seen = []
    sim.on_call = lambda s: seen.append(s.n_calls)
    for seed in (0, 1, 0):
        sim({}, {}, seed)
    assert seen == [1, 2] and sim.n_calls == 2 and sim.n_cached == 1


@pytest.mark.slow
def test_engine_mini_validation(tmp_path):
    """One effect (wall friction), one null twin, on the DEM engine (minutes)."""
    r = dg.validate("mini", simulator="engine", engine={"preset": "tiny",
                                                         "cache": str(tmp_path / "cache")})
    assert r.simulator == "engine" and len(r.twins) + len(r.settings["failed"]) == 1
    assert r.null_false_attribution == 0.0 or r.settings["failed"]
    assert list(tmp_path.joinpath("cache").glob("*.json"))


def test_a_worker_whose_parent_was_killed_stops(tmp_path):
    """Engine-call workers do not outlive a killed parent (they would run on for minutes)."""
    import os
    import subprocess
    import sys
    import time
    script = tmp_path / "parent.py"
    script.write_text(
        "import multiprocessing, os, sys, time\n"
        "from bedstruct.diagnose.process_pool import _exit_with_parent\n"
        "def child(parent):\n"
        "    _exit_with_parent(parent, interval=0.1)\n"
        "    time.sleep(60)\n"
        "if __name__ == '__main__':\n"
        "    # the parent's pid is passed, as the pool's initializer does: a child that starts\n"
        "    # after its parent died must exit too\n"
        "    p = multiprocessing.get_context('spawn').Process(target=child, args=(os.getpid(),))\n"
        "    p.start()\n"
        "    print(p.pid, flush=True)\n"
        "    time.sleep(1.0)\n"
        "    os._exit(0)  # dies without shutting its child down, as a killed parent would\n")
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=60)
    pid = int(out.stdout.split()[0])
    deadline = time.time() + 30  # a loaded machine may take seconds to start the child
    alive = True
    while time.time() < deadline and alive:
        try:
            os.kill(pid, 0)
            time.sleep(0.1)
        except ProcessLookupError:
            alive = False
    assert not alive


def test_one_pile_per_call_for_the_spreading_runs_at_different_speeds(monkeypatch):
    # x1 and x5 spread the same settled pile: it is generated once (x5's raised v_max leaves
    # the time step, which the Rayleigh time sets, and so the pile unchanged)
    import bedstruct.workflows.spread as spread
    design = MeasurementSet(tuple(measurement_from_dict(
        {"name": f"roughness_x{f}", "kind": "roughness", "value": [0.0], "uncertainty": 1e-6,
         "unit": "m", "conditions": {"speed": f * 0.0254, "layer": 1}}) for f in (1, 5)))
    sim = EngineSimulator(design, {"preset": "tiny", "overrides": [
        "spread.gaps=[4.5e-4]", "spread.n_frames=2", "spread.pile_particles=300",
        "spread.pile_time=0.004", "spread.plate_length=1.2e-3", "spread.pile_length=0.6e-3"]})
    piles = []
    real = spread.generate_pile
    monkeypatch.setattr(spread, "generate_pile",
                        lambda cfg, **kw: piles.append(cfg["spread"]["speed"]) or real(cfg, **kw))
    obs = sim({}, {}, 1)
    assert len(piles) == 1 and sim.n_runs == 2
    assert np.isfinite(obs["roughness_x1"]).all() and np.isfinite(obs["roughness_x5"]).all()


@pytest.mark.parametrize("engine", ["embedded", "liggghts"])
def test_a_shared_pile_only_for_the_embedded_engine(monkeypatch, engine):
    # the LIGGGHTS/LAMMPS decks make their own pile (run_spread refuses a given one there)
    import bedstruct.workflows.spread as spread
    design = MeasurementSet((measurement_from_dict(
        {"name": "roughness_x1", "kind": "roughness", "value": [0.0], "uncertainty": 1e-6,
         "unit": "m", "conditions": {"speed": 0.0254, "layer": 1}}),))
    sim = EngineSimulator(design, {"preset": "tiny", "overrides": [f"engine={engine}"]})
    given = []

    class Stop(Exception):
        pass

    def fake_run_spread(cfg, *, out=None, pile=None, progress=False):
        given.append(pile)
        raise Stop

    monkeypatch.setattr(spread, "run_spread", fake_run_spread)
    monkeypatch.setattr(spread, "generate_pile", lambda cfg, **kw: ("the pile", 0))
    with pytest.raises(Stop):
        sim({}, {}, 1)
    assert given == (["the pile"] if engine == "embedded" else [None])


@pytest.mark.parametrize("force, expected", [((-2e-6, 0.0, -4e-7), 0.2),
                                             ((float("nan"),) * 3, float("nan"))])
def test_tool_force_ratio_is_the_layers_stroke_averaged_load(monkeypatch, force, expected):
    """The recoater load observable reads the layer's stroke-averaged tool load (F_z / F_x);
    a run that does not record it (LIGGGHTS/LAMMPS) gives missing data, not a number."""
    import types

    import bedstruct.workflows.spread as spread
    design = MeasurementSet((measurement_from_dict(
        {"name": "blade_load", "kind": "tool_force_ratio", "value": [0.17], "uncertainty": 0.005,
         "unit": "1", "conditions": {"speed": 0.0254, "layer": 2}}),))
    sim = EngineSimulator(design, {"preset": "tiny"})
    layers = [types.SimpleNamespace(index=k, tool_force_ratio=(
        spread.LayerResult.tool_force_ratio.fget(types.SimpleNamespace(tool_force=force))
        if k == 2 else 99.0)) for k in (1, 2)]

    def fake_run_spread(cfg, *, out=None, pile=None, progress=False):
        return types.SimpleNamespace(layers=layers)

    monkeypatch.setattr(spread, "run_spread", fake_run_spread)
    monkeypatch.setattr(spread, "generate_pile", lambda cfg, **kw: ("the pile", 0))
    value = sim({}, {}, 0)["blade_load"][0]
    if np.isnan(expected):
        assert np.isnan(value)
    else:
        assert value == pytest.approx(expected)


def test_cli_diagnose_cache_option_replaces_the_configs_cache(tmp_path, capsys):
    """``--cache`` was read by ``validate`` only: a diagnosis wrote its runs to the config's
    folder and started from scratch. PSD-only files need no workflow run (milliseconds)."""
    from bedstruct.cli import main
    (tmp_path / "sim.toml").write_text(
        '[simulator]\nkind = "engine"\nreplicates = 2\n[catalogue]\neffects = ["missing_fines"]\n'
        f'[engine]\npreset = "tiny"\ncache = "{tmp_path / "config-cache"}"\n')
    (tmp_path / "real.toml").write_text(
        '[[observable]]\nname = "psd_before"\nkind = "psd"\npercentiles = [10, 50, 90]\n'
        'value = [48.0, 55.0, 64.0]\nuncertainty = [0.6, 1.0, 1.7]\nunit = "um"\n'
        'role = "calibrate"\n[observable.conditions]\nstage = "before"\n'
        '[[observable]]\nname = "psd_quartiles"\nkind = "psd"\npercentiles = [25, 75]\n'
        'value = [51.0, 60.0]\nuncertainty = [0.8, 1.2]\nunit = "um"\n'
        'role = "validate"\n[observable.conditions]\nstage = "before"\n')
    args = ["diagnose", "--sim", str(tmp_path / "sim.toml"), "--real", str(tmp_path / "real.toml"),
            "--out", str(tmp_path / "out"), "--cache", str(tmp_path / "cli-cache")]
    assert main(args) == 0
    assert list((tmp_path / "cli-cache").glob("*.json"))
    assert not (tmp_path / "config-cache").exists()
    capsys.readouterr()
    rc = main(["diagnose", "--sim", "surrogate", "--real", str(tmp_path / "real.toml"),
               "--out", str(tmp_path / "o2"), "--cache", str(tmp_path / "c2")])
    assert rc != 0 and "--cache needs a simulation config" in capsys.readouterr().err


def test_relative_cost_follows_the_time_step_and_the_pile_and_orders_a_library_build_longest_first():
    from bedstruct.diagnose.run_design import DesignPoint
    from bedstruct.diagnose.run_library import _longest_first
    from bedstruct.dem import Simulation
    from bedstruct.workflows._common import contact_model, psd_sampler, typed

    sim = EngineSimulator(_psd_design(), {"preset": "tiny"})
    base = {"cohesion_energy_density": 3.6e7}
    assert sim.relative_cost(base, {}) == pytest.approx(1.0)
    # fines shrink the smallest sphere: the time step shrinks with its Rayleigh time
    cfg0, cfg1 = sim.run_config(base, {}, 0), sim.run_config(base, {"missing_fines": 0.06}, 0)
    steps = [Simulation.default_time_step(contact_model(c), psd_sampler(c).r_min,
                                          typed(c).time.v_max, typed(c).time.safety)
             for c in (cfg0, cfg1)]
    # and the pile of the same solid volume holds more spheres
    more = cfg1["spread"]["pile_particles"] / cfg0["spread"]["pile_particles"]
    assert more > 1.2
    fines = sim.relative_cost(base, {"missing_fines": 0.06})
    assert fines == pytest.approx(steps[0] / steps[1] * more, rel=1e-12)
    # the Rayleigh time, which sets both steps here, is proportional to the radius: the
    # ratio is that of the smallest diameters (the PSD's 28 um against the fines' 8 um)
    d_min = psd_sampler(cfg0).r_min / psd_sampler(cfg1).r_min
    assert d_min == pytest.approx(28.0 / 8.0, rel=1e-9)
    assert fines == pytest.approx(d_min * more, rel=1e-9)
    assert sim.relative_cost(base, {"wall_friction": 0.2}) == pytest.approx(1.0)
    todo = [(0, DesignPoint(base, {}, "base"), 1),
            (1, DesignPoint(base, {"missing_fines": 0.06}, "missing_fines"), 1),
            (2, DesignPoint(base, {"wall_friction": 0.2}, "wall_friction"), 1),
            (3, DesignPoint(base, {"missing_fines": 0.06}, "missing_fines"), 2)]
    assert [t[0] for t in _longest_first(sim, todo)] == [1, 3, 0, 2]
    assert _longest_first(object(), todo) == todo     # no estimate: design order
