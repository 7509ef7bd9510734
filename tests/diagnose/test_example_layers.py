"""The worked example's files (data/measurements/example-layers*.toml) and the twin code
that made them: no simulation runs here."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import bedstruct.diagnose as dg
from bedstruct.diagnose.validation import blind_twins
from bedstruct.diagnose.validation.blind_twins import TwinSpec, twin_measurements
from bedstruct.diagnose.engine_simulator import EngineSimulator
from bedstruct.diagnose.measurements import Observations
from bedstruct.diagnose.run_design import design_points, design_spec

ROOT = Path(__file__).resolve().parents[2]
MEAS = ROOT / "data" / "measurements" / "example-layers.toml"
SIM = ROOT / "data" / "measurements" / "example-layers.sim.toml"


def _script():
    spec = importlib.util.spec_from_file_location(
        "example_layers_twin", ROOT / "docs" / "scripts" / "example_layers_twin.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def design(tmp_path_factory):
    path = tmp_path_factory.mktemp("design") / "design.toml"
    path.write_text(_script().design_text(), encoding="utf-8")
    return dg.load_measurements(path)


def test_measurement_file_states_a_six_layer_walled_design():
    ms = dg.load_measurements(MEAS)
    s = ms.setup
    assert s.n_layers == 6 and s.side_walls is True
    assert s.wall_distance == pytest.approx(0.8e-3) and s.platform_length == pytest.approx(3e-3)
    np.testing.assert_allclose(s.layer_thickness, [300e-6] * 6)
    assert s.blade_speed == pytest.approx(0.0254)
    d, cum = s.psd_table
    assert (d[0], d[-1]) == pytest.approx((36e-6, 80e-6)) and cum[0] == 0.0 and cum[-1] == 1.0
    # not the seed's powder: its d10 / d90 are 29.8 / 86.1 um
    seed = dg.load_measurements(ROOT / "data" / "measurements" / "seed.toml")["psd_before"].values
    assert s.psd[0] > seed[0] + 10e-6 and s.psd[2] < seed[2] - 10e-6
    for k in range(1, 7):
        pf, bh = ms[f"packing_fraction_layer{k}"], ms[f"bed_height_layer{k}"]
        assert pf.conditions.layer == bh.conditions.layer == k
        assert 0.3 < pf.values[0] < 0.75
        # the bed is at most the sum of the gaps above the platform, and grows layer by layer
        assert 0.5 * 300e-6 * k < bh.values[0] < 300e-6 * k + 100e-6
    h = [ms[f"bed_height_layer{k}"].values[0] for k in range(1, 7)]
    assert np.all(np.diff(h) > 0)
    assert 5.0 < ms["static_angle"].values[0] < 90.0
    assert all(np.all(np.isfinite(m.uncertainty) & (m.uncertainty > 0)) for m in ms)
    roles = {m.name: m.role for m in ms}
    assert roles["static_angle"] == "calibrate"
    assert sorted(n for n, r in roles.items() if r == "validate") == sorted(
        ["packing_fraction_layer4", "packing_fraction_layer6", "bed_height_layer2",
         "bed_height_layer4", "bed_height_layer6"])


def test_measurement_file_is_the_scripts_design_with_the_twins_values(design):
    ms = dg.load_measurements(MEAS)
    assert ms.names == design.names
    for m, d in zip(ms, design):
        assert (m.kind, m.role, m.conditions.as_dict(), m.note) == \
            (d.kind, d.role, d.conditions.as_dict(), d.note)
        # stated = sqrt(reading^2 + scatter^2 / 3) is at least the design's reading error
        assert np.all(m.uncertainty >= d.uncertainty * (1 - 1e-12))
    assert ms.setup.given() == design.setup.given()
    for key in ("psd", "psd_table", "layer_thickness", "blade_speed", "platform_length",
                "platform_width", "side_walls", "wall_distance"):
        np.testing.assert_allclose(np.asarray(getattr(ms.setup, key), float),
                                   np.asarray(getattr(design.setup, key), float), rtol=1e-12)


def test_sim_config_builds_the_engine_simulator_of_the_design_without_running():
    ms = dg.load_measurements(MEAS)
    cfg = dg.load_sim_config(SIM)
    assert cfg.kind == "engine" and cfg.engine["preset"] == "tiny"
    assert [e.name for e in cfg.effects] == ["capillary_bridges", "non_sphericity"]
    design = dg.diagnosis_design(ms, cfg.effects)
    sim = EngineSimulator(design, cfg.engine)
    sp = sim.base_cfg["spread"]
    assert sp["side_walls"] is True and sp["width"] == pytest.approx(0.8e-3)
    np.testing.assert_allclose(sp["gaps"], [300e-6] * 6)
    assert sim.base_cfg["repose"]["periodic_width"] is False
    np.testing.assert_allclose(sim.base_cfg["psd"]["volume_fractions"], ms.setup.psd_table[1])
    assert sim.n_runs == 0
    # the library the config's comments cost: 9 points x 2 seeds = 18 engine runs
    lib = cfg.library_settings()
    spec = design_spec(cfg.base, vary=lib["vary"], effects=cfg.effects, n_base=lib["n_base"],
                       n_per_effect=lib["n_per_effect"], replicates=lib["library_replicates"])
    assert len(design_points(spec)) * lib["library_replicates"] == 18


def test_twin_file_keeps_the_designs_set_up(design, tmp_path, monkeypatch):
    truth = {m.name: m.values + 0.01 * m.values for m in design}
    calls = []

    def fake_simulator(engine, d, *, preset="tiny", overrides=()):
        calls.append((engine, d.setup))
        return lambda base, effects, seed: Observations(truth, source=engine)

    monkeypatch.setattr(blind_twins, "twin_simulator", fake_simulator)
    spec = TwinSpec("t", "effect", "capillary_bridges", 0.5, 1.0, 7)
    path = twin_measurements(spec, "liggghts", design, tmp_path / "twin.toml", repeats=3,
                             source="a test twin")
    assert calls == [("liggghts", design.setup)]
    ms = dg.load_measurements(path)
    assert ms.setup.given() == design.setup.given()
    np.testing.assert_allclose(ms.setup.psd_table[1], design.setup.psd_table[1])
    assert ms.setup.side_walls is True and ms.setup.n_layers == 6
    assert ms.source == "a test twin" and {m.provenance for m in ms} == {"a test twin"}
    assert ms.notes == design.notes
    for m in ms:
        # the mean of three readings of the truth, each with the design's reading noise
        assert abs(m.values[0] - truth[m.name][0]) < 4 * design[m.name].uncertainty[0]


def test_recorded_answer_is_the_one_the_docs_quote():
    import json
    rec = json.loads((ROOT / "docs" / "records" / "example-layers" / "answer.json")
                     .read_text(encoding="utf-8"))
    assert rec["verdict"] in ("attributed", "none", "unexplained")
    assert rec["simulator"] == "emulator[engine]" and rec["library_runs"] == 18
    doc = (ROOT / "docs" / "diagnose.md").read_text(encoding="utf-8")
    start = doc.index("## Worked example: a layer-by-layer packing experiment")
    section = doc[start:doc.index("\n## ", start + 1)]
    assert f"**`{rec['verdict']}`**" in section
    if rec["effect"] is not None:
        assert f"`{rec['effect']}`" in section
    # the three largest gaps of the record are the observables the section names first
    for row in rec["where"]:
        assert row["observable"].replace("_", " ") in section
