"""Catalogue entries and the surrogate's anchors on the seed report."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bedstruct.diagnose import (CATALOGUE, BASE_PARAMETERS, SurrogateSimulator, catalogue, effect,
                                engine_hooks, halsey_film_thickness, load_sim_config,
                                measurement_from_dict, MeasurementSet, make_simulator)
from bedstruct.diagnose.catalogue import CAPILLARY_ASPERITY, kelvin_radius
from bedstruct.errors import ConfigError


def test_catalogue_has_the_six_effects_documented():
    names = [e.name for e in CATALOGUE]
    assert names == ["contact_ageing", "capillary_bridges", "non_sphericity", "missing_fines",
                     "wall_friction", "blade_startup"]
    for e in CATALOGUE:
        lo, hi = e.prior
        assert lo <= 0.0 < hi
        assert e.sources and all("doi:" in s or "Seed report" in s or "arXiv" in s for s in e.sources)
        assert len(e.physics) > 80 and len(e.signature) > 40
        assert e.identify_with
        assert e.engine_parameters(0.0, {"contact": {"friction": 0.4, "rolling_friction": 0.05}})
        assert e.reference_magnitudes == (0.5 * hi, hi)
    hooks = engine_hooks()
    assert hooks["capillary_bridges"]["contact.capillary"] is True
    ca = CAPILLARY_ASPERITY
    assert hooks["capillary_bridges"]["contact.capillary_film_thickness"] == pytest.approx(
        halsey_film_thickness(0.8) * (ca["asperity_radius"] / ca["reference_radius"]) ** 2)
    assert effect("capillary_bridges").engine_parameters(0.0)["contact.capillary"] is False
    assert effect("blade_startup").engine_parameters(0.1)["spread.ramp_time"] == pytest.approx(0.1)
    # the top of each prior on the default configuration (offsets from its coefficients)
    assert hooks["wall_friction"] == {"contact.wall_friction": pytest.approx(0.4 + 0.4)}
    assert hooks["non_sphericity"]["contact.rolling_friction"] == pytest.approx(0.05 + 0.3)
    with pytest.raises(ConfigError, match="unknown effect"):
        catalogue(["humidity"])
    with pytest.raises(ValueError, match="finite"):
        effect("wall_friction").engine_parameters(float("nan"))


def test_halsey_film_grows_with_humidity():
    t = [halsey_film_thickness(rh) for rh in (0.1, 0.3, 0.5, 0.7, 0.9)]
    assert all(b > a for a, b in zip(t, t[1:]))
    assert halsey_film_thickness(math.exp(-5.0)) == pytest.approx(0.354e-9)
    with pytest.raises(ValueError):
        halsey_film_thickness(1.0)


def _design(*specs):
    ms = []
    for s in specs:
        d = dict(s)
        d.setdefault("role", "candidate")
        d.setdefault("uncertainty", 1.0)
        ms.append(measurement_from_dict(d))
    return MeasurementSet(tuple(ms))


def _dyn(f, windows=((0.1, 1.0),), **cond):
    return dict(name=f"dyn{f}", kind="dynamic_angle_series", windows=[list(w) for w in windows],
                conditions=dict(speed=0.0254 * f, layer=3, **cond))


def test_surrogate_reproduces_the_seed_anchors():
    d = _design(dict(name="aor", kind="static_angle"), _dyn(1), _dyn(2), _dyn(5),
                *[dict(name=f"pf{f}{r}", kind="packing_fraction",
                       conditions=dict(speed=0.0254 * f, layer=1, region=r))
                  for f in (1, 5) for r in ("start", "end")])
    sim = SurrogateSimulator(d, noise=0)
    o = sim({}, {}, 0)
    assert o["aor"][0] == pytest.approx(32.1)
    assert sim({"cohesion_energy_density": 3.0e7}, {}, 0)["aor"][0] == pytest.approx(28.9)
    np.testing.assert_allclose([o[f"dyn{f}"][0] for f in (1, 2, 5)], [27.3, 29.6, 38.3], atol=1e-9)
    mid = lambda f: 0.5 * (o[f"pf{f}start"][0] + o[f"pf{f}end"][0])   # noqa: E731
    assert mid(1) - mid(5) == pytest.approx(0.05, abs=1e-9)
    assert o["pf1start"][0] - o["pf1end"][0] == pytest.approx(0.035 * 2 / 3, abs=1e-9)


def test_surrogate_effect_signatures():
    w = ((0.0, 0.05), (0.05, 0.3), (0.3, 1.0))
    d = _design(_dyn(1, w), _dyn(5, w), dict(name="psd", kind="psd", percentiles=[10, 50, 90],
                                             unit="um", conditions=dict(stage="before")),
                dict(name="aor", kind="static_angle", conditions=dict(box_width=3e-3)),
                dict(name="aor_wide", kind="static_angle", conditions=dict(box_width=3e-2)),
                dict(name="aor_rest", kind="static_angle", conditions=dict(rest_time=600.0)),
                dict(name="blade", kind="tool_force_ratio", unit="1",
                     conditions=dict(speed=0.0254, layer=2)))
    sim = SurrogateSimulator(d, noise=0)
    b = sim({}, {}, 0)

    def diff(**eff):
        o = sim({}, eff, 0)
        return {n: o[n] - b[n] for n in o.names}
    age = diff(contact_ageing=1.0)
    assert age["dyn1"][0] > 3.0 and age["dyn1"][2] < 0.2          # transient spike, then relaxed
    assert age["aor_rest"][0] > 10 * age["aor"][0]                 # ageing needs rest
    ramp = diff(blade_startup=0.1)
    assert ramp["dyn5"][0] < ramp["dyn1"][0] < 0                   # lower early angle, most at x5
    fines = diff(missing_fines=0.1)
    assert fines["psd"][0] < -3e-6 and abs(fines["psd"][2]) < abs(fines["psd"][0])
    wall = diff(wall_friction=0.3)
    assert wall["aor"][0] > 5 * wall["aor_wide"][0] > 0            # a narrow-box effect
    # the blade's vertical / horizontal load: 0.17 on a powder bed, up with wall friction
    assert b["blade"][0] == pytest.approx(0.17) and wall["blade"][0] == pytest.approx(0.03)
    rough = diff(non_sphericity=0.2)
    assert rough["dyn5"][2] > rough["dyn1"][2] > 0                 # grows with speed
    cap = diff(capillary_bridges=0.6)
    assert cap["aor"][0] == pytest.approx(cap["aor_wide"][0]) and cap["aor"][0] > 2


def test_surrogate_noise_is_seeded_and_partly_common():
    d = _design(dict(name="aor", kind="static_angle"))
    sim = SurrogateSimulator(d, correlation=0.5)
    a = np.array([sim({}, {}, s)["aor"][0] for s in range(400)])
    b = np.array([sim({}, {"wall_friction": 0.1}, s)["aor"][0] for s in range(400)])
    assert sim({}, {}, 3)["aor"][0] == a[3]
    assert np.std(a) == pytest.approx(0.35, rel=0.12)
    assert np.corrcoef(a, b)[0, 1] == pytest.approx(0.25, abs=0.12)   # rho^2 of the common part
    with pytest.raises(ConfigError, match="unknown parameter"):
        sim({"youngs_modulus": 1e9}, {}, 0)
    with pytest.raises(ConfigError, match="unknown effect"):
        sim({}, {"static_charge": 1.0}, 0)


def test_sim_config_file_and_engine_hook(tmp_path):
    p = tmp_path / "sim.toml"
    p.write_text('[simulator]\nkind = "surrogate"\nreplicates = 3\n[base]\ncohesion_energy_density = 3.5e7\n'
                 '[catalogue]\nexclude = ["blade_startup"]\n[diagnosis]\nselect_alpha = 0.02\n')
    cfg = load_sim_config(p)
    assert cfg.replicates == 3 and cfg.base["cohesion_energy_density"] == 3.5e7
    assert "blade_startup" not in [e.name for e in cfg.effects] and cfg.select_alpha == 0.02
    assert cfg.base["friction"] == BASE_PARAMETERS["friction"]
    assert (cfg.refine, cfg.confirm_rounds) == (2, 2)     # the defaults of diagnose()
    assert cfg.diagnose_settings()["partial_shrink"] == 0.5
    assert cfg.diagnose_settings()["heldout_alpha"] == 0.1
    p.write_text('[diagnosis]\nrefine = 0\nconfirm_rounds = 1\npartial_shrink = 1.0\n'
                 'heldout_alpha = 0.01\n')
    cfg = load_sim_config(p)
    assert (cfg.refine, cfg.confirm_rounds) == (0, 1) and cfg.as_dict()["confirm_rounds"] == 1
    assert cfg.diagnose_settings()["partial_shrink"] == 1.0
    assert cfg.diagnose_settings()["heldout_alpha"] == 0.01 and cfg.as_dict()["heldout_alpha"] == 0.01
    p.write_text('[simulator]\nkind = "engine"\n[engine]\npreset = "tiny"\n')
    sim = make_simulator(load_sim_config(p), _design(dict(name="aor", kind="static_angle")))
    assert sim.name == "engine"  # the engine simulator (not run here)
    p.write_text('[simulator]\nkind = "engine"\n[engine]\npresett = "tiny"\n')
    with pytest.raises(ConfigError, match="presett"):
        make_simulator(load_sim_config(p), _design(dict(name="aor", kind="static_angle")))
    for text, key in (('[simulator]\nkind = "lammps"\n', "kind"),
                      ('[simulator]\nreplicates = 1\n', "replicates"),
                      ('[recalibrate]\nparameters = ["young"]\n', "parameters"),
                      ('[diagnosis]\nalpha = 2.0\n', "alpha"),
                      ('[diagnosis]\nconfirm_rounds = -1\n', "confirm_rounds"),
                      ('[diagnosis]\npartial_shrink = 1.5\n', "partial_shrink"),
                      ('[diagnosis]\nheldout_alpha = 0.0\n', "heldout_alpha"),
                      ('[diagnosis]\nrefine = 1.5\n', "refine"),
                      ('[base]\nyoung = 1e9\n', "young")):
        p.write_text(text)
        with pytest.raises(ConfigError, match=key):
            load_sim_config(p)


def test_capillary_asperity_force_is_a_few_particle_weights_and_grows_with_humidity():
    # Bond number of the pull-off force the engine's Willett form gives at contact,
    # 2 pi (2 R*) gamma' cos(theta), for two equal 52 um CoCr spheres (R* = D50/4)
    d = 52.08e-6
    weight = math.pi / 6 * d ** 3 * 8300.0 * 9.81
    bo = []
    for rh in (0.1, 0.3, 0.5, 0.8):
        p = effect("capillary_bridges").engine_parameters(rh)
        bo.append(2 * math.pi * (d / 2) * p["contact.capillary_surface_tension"]
                  * math.cos(p["contact.capillary_contact_angle"]) / weight)
    assert all(b2 > b1 for b1, b2 in zip(bo, bo[1:]))
    assert 2.0 < bo[0] and bo[-1] < 50.0       # not the full-sphere ~2000 weights
    full = 2 * math.pi * (d / 2) * 0.072 * math.cos(math.radians(20)) / weight
    assert 1500 < full < 2500
    # Kelvin radius: gamma V_m / (R T ln(1/RH)); at RH = 1/e it is 0.53 nm
    assert kelvin_radius(math.exp(-1.0)) == pytest.approx(0.072 * 1.8e-5 / (8.314462618 * 293.15))


@pytest.mark.parametrize("name", ["seed-engine-tiny", "seed-engine-small", "engine-twins-tiny"])
def test_shipped_simulation_configurations_load_and_build(name):
    # the example configurations in data/measurements are documented commands: each must
    # load, name real catalogue effects and build its engine simulator (nothing is run)
    from pathlib import Path
    from bedstruct.diagnose import load_measurements
    root = Path(__file__).resolve().parents[2] / "data" / "measurements"
    cfg = load_sim_config(root / f"{name}.sim.toml")
    assert cfg.kind == "engine" and cfg.replicates >= 2 and cfg.effects
    sim = make_simulator(cfg, load_measurements(root / "seed-angles.toml"))
    assert sim.name == "engine"


def test_a_catalogue_with_no_effect_left_is_refused_before_any_run(tmp_path):
    """``effects = []`` (or every effect excluded) names the file and the table, and
    ``diagnose(..., effects=())`` is refused before the simulator is called."""
    from bedstruct.diagnose import diagnose
    p = tmp_path / "sim.toml"
    for text in ('[catalogue]\neffects = []\n',
                 '[catalogue]\neffects = ["missing_fines"]\nexclude = ["missing_fines"]\n'):
        p.write_text(text)
        with pytest.raises(ConfigError, match=r"sim\.toml \[catalogue\]: no effect is left"):
            load_sim_config(p)
    ms = _design(dict(name="aor", kind="static_angle", role="calibrate", value=33.0))
    calls = []
    with pytest.raises(ConfigError, match="at least one catalogue effect"):
        diagnose(ms, lambda *a: calls.append(a), base=BASE_PARAMETERS, effects=())
    assert calls == []


def test_a_file_without_a_calibration_observable_is_refused_before_any_run(tmp_path):
    """Every observable held out: nothing to fit, said naming the file before a run."""
    from bedstruct.diagnose import diagnose, load_measurements
    f = tmp_path / "held.toml"
    f.write_text('[[observable]]\nname = "aor"\nkind = "static_angle"\nrole = "validate"\n'
                 'value = 33.0\nuncertainty = 1.0\n', encoding="utf-8")
    calls = []
    with pytest.raises(ConfigError, match=r"held\.toml: no observable has role 'calibrate'"):
        diagnose(load_measurements(f), lambda *a: calls.append(a), base=BASE_PARAMETERS)
    assert calls == []


@pytest.mark.parametrize("name, dose", [("blind-engine-tiny-probed2", "count"),
                                        ("blind-engine-tiny-dosed", "volume")])
def test_blind_benchmark_configurations_state_how_piles_are_dosed(name, dose):
    # the recorded batches replay with piles of a fixed sphere count; the dosed batch's
    # file spreads the base pile's solid volume whatever the size distribution
    from pathlib import Path
    from bedstruct.diagnose import load_measurements
    root = Path(__file__).resolve().parents[2] / "data" / "measurements"
    cfg = load_sim_config(root / f"{name}.sim.toml")
    assert cfg.bridge["engine"] == "liggghts" and cfg.bridge["probes"] == "reference"
    sim = make_simulator(cfg, load_measurements(root / "seed-angles.toml"))
    assert sim.pile_dose == dose
    base = sim.run_config(dict(cfg.base), {}, 0)["spread"]["pile_particles"]
    fines = sim.run_config(dict(cfg.base), {"missing_fines": 0.12}, 0)["spread"]["pile_particles"]
    assert (fines == base) if dose == "count" else (fines > 1.5 * base)
