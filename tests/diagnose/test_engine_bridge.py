"""The engine bridge: measurements from another code diagnosed against that code's baseline.

The user's engine is the surrogate plus a fixed offset shaped like an effect's response
(two codes that differ at the same nominal parameters the way a catalogue effect would
move the bed). Without the bridge a null twin of that engine is read as the effect; with
the bridge, built from the engine's own runs at the base point, it is not, and a real
effect on top of the offset is still found.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from bedstruct.diagnose import (BASE_PARAMETERS, Observations, SurrogateSimulator, catalogue,
                                compute_fingerprints, diagnose, diagnosis_design,
                                load_sim_config)
from bedstruct.diagnose.bridge import EngineBridge, bridge_offset, engine_bridge
from bedstruct.diagnose.validation.twins import _twin_measurements
from bedstruct.diagnose.validation.design import twin_design
from bedstruct.errors import ConfigError


class OffsetEngine:
    """Another code: the surrogate's runs plus a fixed offset per observable."""

    name = "offset engine"

    def __init__(self, sim, offset):
        self.sim, self.offset = sim, offset

    def __call__(self, base, effects, seed):
        obs = self.sim(base, effects, seed)
        return Observations({n: obs[n] + self.offset.get(n, 0.0) for n in obs.names},
                            source="offset engine")


@pytest.fixture(scope="module")
def setup():
    eff = catalogue()
    design = diagnosis_design(twin_design(), eff)
    sim = SurrogateSimulator(design)
    fps = compute_fingerprints(sim, design, BASE_PARAMETERS, eff, replicates=3, alpha=0.01)
    # the offset: blade start-up's response at its prior's top, averaged over seeds
    top = [e for e in eff if e.name == "blade_startup"][0].prior[1]
    diff = [{n: sim(BASE_PARAMETERS, {"blade_startup": top}, s)[n]
             - sim(BASE_PARAMETERS, {}, s)[n] for n in design.names} for s in range(8)]
    offset = {n: np.mean([d[n] for d in diff], axis=0) for n in design.names}
    return eff, sim, fps, OffsetEngine(sim, offset), offset


def _twin(engine, tmp_path, effects, seed):
    return _twin_measurements(twin_design(), engine, dict(BASE_PARAMETERS), effects, seed,
                              tmp_path, seed, engine.sim.noise_sd())


def _bridge(setup, ms):
    eff, sim, fps, engine, _ = setup
    return engine_bridge(ms, sim, base=BASE_PARAMETERS, bridge={"engine": "liggghts", "runs": 6},
                         engine_simulator=engine)


def test_the_offset_is_the_engines_baseline_minus_the_simulators(setup, tmp_path):
    eff, sim, fps, engine, offset = setup
    ms = _twin(engine, tmp_path, {}, 11)
    b = _bridge(setup, ms)
    assert b.n_runs == 6 and b.reference.endswith("6 runs") and not b.left_out
    for n in ms.names:
        # the estimated offset lies within 4 of its standard deviations of the true one
        assert np.all(np.abs(b.offset[n] - offset[n]) <= 4 * b.offset_sd[n] + 1e-12), n
        assert np.all(b.offset_sd[n] > 0)
    out = b.apply(ms)
    for m in ms:
        assert np.allclose(out[m.name].values, m.values - b.offset[m.name])
        assert np.all(out[m.name].uncertainty > m.uncertainty)


def test_a_null_twin_of_another_code_is_no_effect_once_bridged(setup, tmp_path):
    eff, sim, fps, engine, _ = setup
    ms = _twin(engine, tmp_path, {}, 21)
    plain = diagnose(ms, sim, base=BASE_PARAMETERS, effects=eff, fingerprints=fps, refine=0,
                     seed=5)
    # without the bridge the code-to-code offset is read as a gap the simulator must close
    assert plain.attribution.verdict != "none"
    bridged = diagnose(ms, sim, base=BASE_PARAMETERS, effects=eff, fingerprints=fps, refine=0,
                       seed=5, bridge=_bridge(setup, ms))
    assert bridged.attribution.verdict == "none", bridged.attribution.reason
    assert bridged.settings["bridge"]["engine"] == "liggghts"
    assert any("liggghts baseline" in n for n in bridged.data_notes())


def test_an_effect_on_top_of_the_offset_is_still_found(setup, tmp_path):
    eff, sim, fps, engine, _ = setup
    ms = _twin(engine, tmp_path, {"missing_fines": 0.08}, 31)
    d = diagnose(ms, sim, base=BASE_PARAMETERS, effects=eff, fingerprints=fps, refine=0,
                 seed=5, bridge=_bridge(setup, ms))
    assert d.attribution.verdict == "attributed", d.attribution.reason
    assert d.attribution.selected[0].effect == "missing_fines"


def test_an_observable_the_engine_could_not_observe_is_left_out():
    runs = [Observations({"a": [1.0], "b": [np.nan]}), Observations({"a": [3.0], "b": [2.0]})]
    b = bridge_offset(runs, {"a": [0.0], "b": [0.0]}, {"a": [0.0], "b": [0.0]},
                      {"a": [1.0], "b": [1.0]}, engine="lammps")
    assert b.left_out == ("b",) and float(b.offset["a"][0]) == 2.0
    # the larger of the two scatters over n: sqrt(2) / sqrt(2)
    assert float(b.offset_sd["a"][0]) == pytest.approx(1.0)
    assert "b left out" in b.note()
    with pytest.raises(ConfigError, match="at least 2 runs"):
        bridge_offset(runs[:1], {"a": [0.0]}, {"a": [0.0]}, {"a": [1.0]}, engine="lammps")


def test_a_bridge_with_components_of_another_shape_is_refused():
    from bedstruct.diagnose import MeasurementSet, measurement_from_dict
    m = measurement_from_dict({"name": "a", "kind": "static_angle", "value": 33.0,
                               "uncertainty": 1.0, "unit": "deg"})
    b = EngineBridge("lammps", {"a": np.zeros(2)}, {"a": np.ones(2)}, 4, {}, "emulator")
    with pytest.raises(ConfigError, match="components"):
        b.apply(MeasurementSet((m,)))


@pytest.mark.parametrize("table, message", [
    ('[bridge]\nengine = "liggghts"\nrun = 4\n', "key 'run': unknown"),
    ('[bridge]\nruns = 4\n', "key 'engine' is required"),
    ('[bridge]\nengine = "gromacs"\n', "expected one of embedded, liggghts, lammps"),
    ('[bridge]\nengine = "liggghts"\nruns = 1\n', "need >= 2 runs"),
    ('[bridge]\nengine = "liggghts"\nruns = "6"\n', "expected int"),
])
def test_the_bridge_table_is_checked(tmp_path, table, message):
    p = tmp_path / "sim.toml"
    p.write_text('[simulator]\nkind = "engine"\n\n[engine]\npreset = "tiny"\n\n' + table)
    with pytest.raises(ConfigError, match=message):
        load_sim_config(p)


def test_the_bridge_table_needs_an_engine_simulator_and_keeps_its_cache_beside_the_file(tmp_path):
    p = tmp_path / "sim.toml"
    p.write_text('[simulator]\nkind = "surrogate"\n\n[bridge]\nengine = "liggghts"\n')
    with pytest.raises(ConfigError, match="kind = \"engine\""):
        load_sim_config(p)
    p.write_text('[simulator]\nkind = "engine"\n\n[bridge]\nengine = "lammps"\ncache = "runs"\n')
    cfg = load_sim_config(p)
    assert cfg.bridge == {"engine": "lammps", "runs": 6, "seed": 0, "cache": str(tmp_path / "runs")}
    assert cfg.as_dict()["bridge"]["engine"] == "lammps"


def test_on_an_emulator_the_offset_is_taken_from_its_prediction(tmp_path):
    from bedstruct.diagnose import (EmulatedSimulator, MeasurementSet, build_library,
                                    design_spec, fit_emulator, measurement_from_dict)
    m = measurement_from_dict({"name": "aor", "kind": "static_angle", "role": "calibrate",
                               "uncertainty": 0.5, "value": 33.0})
    ms = MeasurementSet((m,))
    sim = SurrogateSimulator(ms)
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=6, n_per_effect=6)
    emu = fit_emulator(build_library(sim, spec, tmp_path, progress=False))
    b = engine_bridge(ms, EmulatedSimulator(emu), base=BASE_PARAMETERS,
                      bridge={"engine": "lammps", "runs": 8},
                      engine_simulator=OffsetEngine(sim, {"aor": np.array([2.0])}))
    p = emu.predict(BASE_PARAMETERS, {})
    assert b.reference == "emulator" and b.n_runs == 8
    runs = b.runs["aor"][:, 0]
    assert b.offset["aor"][0] == pytest.approx(runs.mean() - p.mean[0])
    assert abs(b.offset["aor"][0] - 2.0) < 4 * b.offset_sd["aor"][0]
    want = np.sqrt(max(runs.std(ddof=1), p.noise_sd[0]) ** 2 / 8 + p.sd[0] ** 2)
    assert b.offset_sd["aor"][0] == pytest.approx(want)


def test_apply_refuses_an_observable_the_bridge_did_not_run_and_keeps_the_rest(setup, tmp_path):
    from bedstruct.diagnose import MeasurementSet, measurement_from_dict
    eff, sim, fps, engine, _ = setup
    ms = _twin(engine, tmp_path, {}, 41)
    b = _bridge(setup, ms)
    extra = measurement_from_dict({"name": "aor_other", "kind": "static_angle", "value": 30.0,
                                   "uncertainty": 1.0, "unit": "deg"})
    with pytest.raises(ConfigError, match="'aor_other' was not run on the liggghts engine"):
        b.apply(MeasurementSet(ms.measurements + (extra,)))
    # a candidate (no value) passes unchanged; an observable the runs could not see is left out
    cand = measurement_from_dict({"name": "aor_next", "kind": "static_angle", "role": "candidate",
                                  "uncertainty": 1.0, "unit": "deg"})
    first = ms.names[0]
    seen = replace(b, left_out=(first,), offset={k: v for k, v in b.offset.items() if k != first})
    out = seen.apply(MeasurementSet(ms.measurements + (cand,)))
    assert first not in out and "aor_next" in out and len(out) == len(ms)


def test_the_cli_diagnoses_through_the_configured_bridge(setup, tmp_path, monkeypatch, capsys):
    import json

    import bedstruct.diagnose as dg
    import bedstruct.diagnose.bridge as bridge_module
    from bedstruct.cli import main
    eff, sim, fps, engine, offset = setup
    real = bridge_module.engine_bridge
    seen = {}

    def on_the_offset_engine(ms, simulator, **kw):
        seen.update(kw)
        return real(ms, simulator, base=kw["base"], bridge=kw["bridge"],
                    engine_simulator=OffsetEngine(simulator, offset))

    monkeypatch.setattr(dg, "make_simulator", lambda cfg, design: SurrogateSimulator(design))
    monkeypatch.setattr(bridge_module, "engine_bridge", on_the_offset_engine)
    real_file = _twin(engine, tmp_path, {}, 51).path
    cfg = tmp_path / "sim.toml"
    cfg.write_text('[simulator]\nkind = "engine"\n[engine]\npreset = "tiny"\n'
                   '[bridge]\nengine = "liggghts"\nruns = 6\n')
    code = main(["diagnose", "--sim", str(cfg), "--real", str(real_file), "--out",
                 str(tmp_path / "out"), "--refine", "0", "--json"])
    assert code == 0, capsys.readouterr().err
    assert seen["bridge"]["engine"] == "liggghts" and seen["engine"] == {"preset": "tiny"}
    doc = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    assert doc["settings"]["bridge"]["n_runs"] == 6
    assert doc["sim_config"]["bridge"]["engine"] == "liggghts"
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["verdict"] == "none"


class SlowFinesEngine:
    """Another code whose powder answers half as strongly to missing fines."""

    name = "slow-fines engine"

    def __init__(self, sim):
        self.sim = sim

    def __call__(self, base, effects, seed):
        eff = dict(effects)
        if "missing_fines" in eff:
            eff["missing_fines"] = 0.5 * float(eff["missing_fines"])
        return Observations(dict(self.sim(base, eff, seed).values), source="slow-fines engine")


def test_a_probe_recovers_the_engines_response_difference_exactly():
    eff = catalogue()
    design = diagnosis_design(twin_design(), eff)
    sim = SurrogateSimulator(design)
    shift = {n: np.full(design[n].n_components, 0.1 * (k + 1)) for k, n in enumerate(design.names)}

    def engine(base, effects, seed):   # the surrogate plus a shift wherever fines are missing
        obs = sim(base, effects, seed)
        on = float(effects.get("missing_fines", 0.0)) != 0.0
        return Observations({n: obs[n] + (shift[n] if on else 0.0) for n in obs.names})

    b = engine_bridge(design, sim, base=BASE_PARAMETERS,
                      bridge={"engine": "liggghts", "runs": 4, "probe_runs": 3},
                      engine_simulator=engine, effects=eff)
    # paired by seed, the diagnosing simulator's own runs cancel: the shift itself
    assert set(b.effect_shift["missing_fines"]) == set(b.offset)
    for n in b.offset:
        assert np.allclose(b.effect_shift["missing_fines"][n], shift[n], atol=1e-12), n
        assert np.allclose(b.effect_shift["wall_friction"][n], 0.0, atol=1e-12), n
    # LIGGGHTS realises neither contact ageing nor a blade start-up: not probed
    # LIGGGHTS has no ageing model, no tool start-up, and its liquid bridges skip the
    # catalogue's humidity films (far below their volume cut-off)
    assert set(b.unprobed) == {"contact_ageing", "blade_startup", "capillary_bridges"}
    assert b.probe_magnitudes["missing_fines"] == 0.12 and b.probe_runs == 3
    bsim = b.simulator(sim)
    half = bsim(BASE_PARAMETERS, {"missing_fines": 0.06}, 5)
    plain = sim(BASE_PARAMETERS, {"missing_fines": 0.06}, 5)
    n0 = next(iter(b.offset))
    assert np.allclose(half[n0] - plain[n0], 0.5 * shift[n0])
    assert np.allclose(bsim(BASE_PARAMETERS, {}, 5)[n0], sim(BASE_PARAMETERS, {}, 5)[n0])
    assert "probe" in b.note() and b.as_dict()["probe_magnitudes"]["missing_fines"] == 0.12


def test_probes_at_both_reference_magnitudes_follow_a_response_that_is_not_proportional():
    eff = catalogue()
    design = diagnosis_design(twin_design(), eff)
    sim = SurrogateSimulator(design)
    unit = {n: np.full(design[n].n_components, 0.1 * (k + 1)) for k, n in enumerate(design.names)}

    def engine(base, effects, seed):   # a shift that jumps on at any fraction, then grows
        obs = sim(base, effects, seed)
        a = float(effects.get("missing_fines", 0.0))
        c = 0.0 if a == 0.0 else 1.0 + 10.0 * a
        return Observations({n: obs[n] + c * unit[n] for n in obs.names})

    table = {"engine": "liggghts", "runs": 4, "probe_runs": 3}
    top = engine_bridge(design, sim, base=BASE_PARAMETERS, bridge=table,
                        engine_simulator=engine, effects=eff)
    both = engine_bridge(design, sim, base=BASE_PARAMETERS, bridge=dict(table, probes="reference"),
                         engine_simulator=engine, effects=eff)
    assert "missing_fines" not in top.inner_probes
    (a_in, sh_in, _), = both.inner_probes["missing_fines"]
    assert a_in == 0.06 and both.probe_magnitudes["missing_fines"] == 0.12
    n0 = next(iter(both.offset))
    assert np.allclose(sh_in[n0], 1.6 * unit[n0]) and np.allclose(
        both.effect_shift["missing_fines"][n0], 2.2 * unit[n0])
    # between the probes the two-probe correction is the engine's own; one probe's is not
    for a in (0.09, 0.12, 0.06):
        want = (1.0 + 10.0 * a) * unit[n0]
        assert np.allclose(both.correction({"missing_fines": a})[0][n0], want), a
    assert not np.allclose(top.correction({"missing_fines": 0.09})[0][n0], 1.9 * unit[n0])
    # below the inner probe: through 0; above the top: the last segment extended
    assert np.allclose(both.correction({"missing_fines": 0.03})[0][n0], 0.8 * unit[n0])
    assert np.allclose(both.correction({"missing_fines": 0.15})[0][n0], 2.5 * unit[n0])
    # the uncertainty of an interpolated correction weighs both probes' (zero here)
    assert np.allclose(both.correction({"missing_fines": 0.09})[1][n0], 0.0)
    assert "0.06 and 0.12" in both.note()
    assert both.as_dict()["inner_probes"]["missing_fines"][0]["magnitude"] == 0.06


def test_the_bridge_table_names_the_probe_sets(tmp_path):
    p = tmp_path / "sim.toml"
    p.write_text('[simulator]\nkind = "engine"\n\n[engine]\npreset = "tiny"\n\n'
                 '[bridge]\nengine = "liggghts"\nruns = 4\nprobe_runs = 2\nprobes = "all"\n')
    with pytest.raises(ConfigError, match="probes.*'top', 'reference'"):
        load_sim_config(p)
    p.write_text(p.read_text().replace('"all"', '"reference"'))
    assert load_sim_config(p).bridge["probes"] == "reference"
    # probes without probe runs would probe nothing: refused, not ignored
    p.write_text(p.read_text().replace("probe_runs = 2\n", ""))
    with pytest.raises(ConfigError, match="'probes' needs 'probe_runs'"):
        load_sim_config(p)


def test_probes_let_an_engine_with_another_response_be_sized_in_its_own_terms(setup, tmp_path):
    eff, sim, fps, _, _ = setup
    engine = SlowFinesEngine(sim)
    ms = _twin(engine, tmp_path, {"missing_fines": 0.10}, 41)
    table = {"engine": "liggghts", "runs": 6}
    plain = diagnose(ms, sim, base=BASE_PARAMETERS, effects=eff, refine=1, seed=5,
                     bridge=engine_bridge(ms, sim, base=BASE_PARAMETERS, bridge=table,
                                          engine_simulator=engine, effects=eff))
    probed = diagnose(ms, sim, base=BASE_PARAMETERS, effects=eff, refine=1, seed=5,
                      bridge=engine_bridge(ms, sim, base=BASE_PARAMETERS,
                                           bridge=dict(table, probe_runs=6),
                                           engine_simulator=engine, effects=eff))
    for d in (plain, probed):
        assert d.attribution.verdict == "attributed", d.attribution.reason
        assert d.attribution.selected[0].effect == "missing_fines"
    a_plain = plain.attribution.selected[0]
    a_probed = probed.attribution.selected[0]
    # without probes the engine's fines read as half as many; with them, as they are
    assert a_plain.interval[1] < 0.08
    assert a_probed.interval[0] <= 0.10 <= a_probed.interval[1], a_probed
    assert abs(a_probed.magnitude - 0.10) < abs(a_plain.magnitude - 0.10)
    assert "BridgedSimulator" not in probed.simulator


@pytest.mark.parametrize("runs, probes", [(6, 1), (4, 5), (4, -1)])
def test_probe_runs_pair_with_base_runs(tmp_path, runs, probes):
    p = tmp_path / "sim.toml"
    p.write_text('[simulator]\nkind = "engine"\n\n[engine]\npreset = "tiny"\n\n'
                 f'[bridge]\nengine = "liggghts"\nruns = {runs}\nprobe_runs = {probes}\n')
    with pytest.raises(ConfigError, match="probe_runs"):
        load_sim_config(p)


def test_a_probe_of_an_effect_both_codes_realise_alike_is_a_correction_within_its_noise():
    """Two codes with the same physics and their own run-to-run noise: the probe correction
    is kept as measured, and its stated standard deviation is the scatter it shows (the
    components' corrections over their standard deviations have unit variance)."""
    eff = catalogue(["missing_fines", "wall_friction"])
    design = diagnosis_design(twin_design(), eff)
    sim = SurrogateSimulator(design)

    def engine(base, effects, seed):   # the same physics, its own run-to-run noise
        return sim(base, effects, seed + 1000)

    z = []
    for first in range(4):
        b = engine_bridge(design, sim, base=BASE_PARAMETERS,
                          bridge={"engine": "lammps", "runs": 6, "probe_runs": 6,
                                  "seed": 17 * first},
                          engine_simulator=engine, effects=eff)
        for e in ("missing_fines", "wall_friction"):
            shift = np.concatenate([b.effect_shift[e][n] for n in b.offset])
            sd = np.concatenate([b.effect_shift_sd[e][n] for n in b.offset])
            assert np.all(sd > 0.0) and np.all(shift != 0.0), e
            z.append(shift / sd)
    z = np.concatenate(z)
    # a t-like statistic over 5 degrees of freedom per component: variance 5/3; a shrunk
    # correction would give far less, an understated deviation far more
    assert len(z) >= 40
    assert 0.8 < float(np.mean(z ** 2)) < 3.0, float(np.mean(z ** 2))


def test_the_confirming_check_adds_the_probe_correction_variance_once_per_rerun():
    from bedstruct.diagnose import MeasurementSet, measurement_from_dict
    from bedstruct.diagnose.bridge import BridgedSimulator
    from bedstruct.diagnose.confirm import _bridge_variance
    ms = MeasurementSet((measurement_from_dict({"name": "aor", "kind": "static_angle", "value": 33.0,
                                                "uncertainty": 0.5, "unit": "deg"}),))
    b = EngineBridge("liggghts", {"aor": np.zeros(1)}, {"aor": np.zeros(1)}, 6, {}, "emulator",
                     probe_magnitudes={"capillary_bridges": 0.8},
                     effect_shift={"capillary_bridges": {"aor": np.array([-2.0])}},
                     effect_shift_sd={"capillary_bridges": {"aor": np.array([0.4])}})
    sim = BridgedSimulator(lambda base, effects, seed: Observations({"aor": [33.0]}), b)
    # at half the probe, the correction's sd is half of 0.4
    assert np.allclose(_bridge_variance(sim, {"capillary_bridges": 0.4}, ["aor"], ms), [0.04])
    assert np.allclose(_bridge_variance(sim, {}, ["aor"], ms), [0.0])
    assert np.allclose(_bridge_variance(lambda *a: None, {"capillary_bridges": 0.4}, ["aor"], ms), [0.0])
