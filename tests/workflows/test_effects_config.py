"""The [effects] configuration section and the diagnosis engine hook (wiring, not physics runs)."""

import math

import numpy as np
import pytest

from bedstruct.diagnose.catalogue import CATALOGUE, effect
from bedstruct.errors import ConfigError
from bedstruct.diagnose.engine_simulator import effects_config
from bedstruct.workflows import load_config
from bedstruct.workflows._common import contact_model, psd_sampler, tool_motion


def test_every_catalogue_engine_parameter_is_a_config_key():
    cfg = load_config(preset="tiny")
    for e in CATALOGUE:
        for key in e.engine_parameters(e.prior[1]):
            assert key in cfg["effects"], (e.name, key)
        # and the top of the prior is a valid configuration
        cfg2 = load_config(preset="tiny")
        cfg2["effects"].update(effects_config({e.name: e.prior[1]}))
        load_config(cfg2)


def test_magnitude_zero_is_the_base_model():
    base = load_config(preset="tiny")
    for e in CATALOGUE:
        assert effects_config({e.name: 0.0}) == {}
    cfg = load_config(preset="tiny")
    cfg["effects"].update(effects_config({e.name: 0.0 for e in CATALOGUE}))
    assert contact_model(cfg) == contact_model(base)
    rng_a, rng_b = np.random.default_rng(4), np.random.default_rng(4)
    np.testing.assert_array_equal(psd_sampler(cfg)(500, rng_a), psd_sampler(base)(500, rng_b))


def test_contact_model_mapping():
    cfg = load_config(preset="tiny")
    cfg["effects"].update(effects_config({"wall_friction": 0.2, "non_sphericity": 0.1,
                                          "capillary_bridges": 0.5, "contact_ageing": 1.0}))
    m = contact_model(cfg)
    mu = cfg["contact"]["friction"]
    t = m.tables()
    assert t.friction[0, 1] == pytest.approx(mu + 0.2) and t.friction[0, 0] == pytest.approx(mu)
    assert m.rolling_model == "epsd" and m.rolling_stiffness_factor == 2.25
    assert m.rolling_friction == pytest.approx(cfg["contact"]["rolling_friction"] + 0.1)
    cap = effect("capillary_bridges").engine_parameters(0.5)  # asperity-scale bridges
    assert m.capillary and m.capillary_surface_tension == pytest.approx(
        cap["capillary_surface_tension"]) and 0 < m.capillary_surface_tension < 0.072
    assert m.capillary_contact_angle == pytest.approx(math.radians(20))
    assert m.capillary_film_thickness == pytest.approx(cap["capillary_film_thickness"])
    assert m.contact_ageing and m.ageing_bond_ratio == 1.0 and m.ageing_time_constant == 10.0
    # a polished wall: friction excess below -mu clips at 0
    cfg["effects"]["wall_friction_excess"] = -1.0
    assert contact_model(cfg).tables().friction[0, 1] == 0.0


def test_fines_tail_carries_the_mass_fraction():
    cfg = load_config(preset="tiny")
    phi = 0.1
    cfg["effects"].update(effects_config({"missing_fines": phi}))
    draw = psd_sampler(cfg)
    scale = cfg["psd"]["scale"]
    r = draw(40000, np.random.default_rng(1))
    cut = 0.5 * scale * cfg["psd"]["d_min"]
    fines = r < cut
    frac = (r[fines] ** 3).sum() / (r ** 3).sum()
    assert frac == pytest.approx(phi, rel=0.05)
    assert r.min() >= 0.5 * scale * 8e-6 and draw.r_min == pytest.approx(0.5 * scale * 8e-6)
    # volume-weighted median of the fines: 20 um x scale, truncated at d_min (40 um)
    d = 2 * r[fines] / scale
    order = np.argsort(d)
    cum = np.cumsum(d[order] ** 3) / np.sum(d ** 3)
    assert d[order][np.searchsorted(cum, 0.5)] == pytest.approx(20e-6, rel=0.05)


def test_effects_keys_are_checked():
    with pytest.raises(ConfigError, match="effects.fines_mass_fraction"):
        load_config(preset="tiny", overrides=["effects.fines_mass_fraction=1.5"])
    with pytest.raises(ConfigError, match="effects.capillary_film_thickness"):
        load_config(preset="tiny", overrides=["effects.capillary=true"])
    with pytest.raises(ConfigError, match="unknown config key"):
        load_config(preset="tiny", overrides=["effects.humidity=0.3"])


def test_tool_motion_uses_the_ramp_program():
    from bedstruct import Box
    from bedstruct.dem import Material, ContactModel, Plane, Simulation
    cfg = load_config(preset="tiny")
    cfg["effects"].update(effects_config({"blade_startup": 0.01}))
    sim = Simulation(Box([0, 0, 0], [1e-3, 1e-3, 1e-3], boundary="ff ff ff"),
                     ContactModel(Material(1e6, 0.3, 8300.0)),
                     walls=[Plane((1e-4, 0, 0), (1, 0, 0), name="tool")], gravity=(0, 0, 0),
                     n_threads=1, dt=1e-6, force=True)
    sim.add_particles([[5e-4, 5e-4, 5e-4]], [5e-5])
    tool_motion(sim, cfg, "tool", (0.1, 0.0, 0.0))
    sim.run(steps=1000)
    st = sim.wall_states()[0]
    t = sim.time
    assert st.velocity[0] == pytest.approx(0.1 * (1 - math.exp(-t / 0.01)), rel=1e-9)
    assert st.velocity[2] == pytest.approx(2 * math.pi * 120 * 2e-6 * math.cos(2 * math.pi * 120 * t),
                                           rel=1e-6)
    # without the effect: plain constant velocity
    base = load_config(preset="tiny")
    tool_motion(sim, base, "tool", (0.1, 0.0, 0.0))
    assert not sim._programs and sim.wall_states()[0].velocity[0] == 0.1


def test_engine_simulator_maps_base_and_effects():
    from bedstruct.diagnose.measurements import MeasurementSet
    from bedstruct.diagnose.measurement_io import measurement_from_dict
    from bedstruct.diagnose.engine_simulator import diagnosis_simulator
    m = measurement_from_dict({"name": "psd", "kind": "psd", "role": "candidate",
                               "uncertainty": 1e-6, "percentiles": [10, 50, 90],
                               "conditions": {"stage": "before"}})
    sim = diagnosis_simulator(MeasurementSet((m,)), {"preset": "tiny", "ageing_time_scale": 1000})
    cfg = sim.run_config({"cohesion_energy_density": 3.6e7, "friction": 0.3}, {"contact_ageing": 1.0},
                         seed=2)
    assert cfg["contact"]["cohesion"] == pytest.approx(load_config(preset="tiny")["contact"]["cohesion"])
    assert cfg["contact"]["friction"] == 0.3 and cfg["seed"] == 2
    assert cfg["effects"]["ageing_time_constant"] == pytest.approx(0.01)
    with pytest.raises(ConfigError, match="base parameter"):
        sim.run_config({"stiffness": 1.0}, {}, 0)
    with pytest.raises(ConfigError, match="engine"):
        diagnosis_simulator(MeasurementSet((m,)), {"presett": "tiny"})
    # fines change the PSD observable, magnitude 0 does not
    p0 = sim({}, {}, 0)["psd"]
    assert np.array_equal(sim({}, {"missing_fines": 0.0}, 0)["psd"], p0)
    assert sim({}, {"missing_fines": 0.1}, 0)["psd"][0] < 0.95 * p0[0]
    assert effect("missing_fines").engine_parameters(0.1)["fines_mass_fraction"] == 0.1


@pytest.mark.slow
def test_engine_simulator_smoke_tiny():
    """One full call on the tiny preset (about a minute on one core)."""
    import bedstruct.diagnose as dg
    from bedstruct.diagnose.engine_simulator import diagnosis_simulator
    from pathlib import Path
    ms = dg.load_measurements(Path(__file__).parents[2] / "data" / "measurements" / "seed.toml")
    design = dg.diagnosis_design(ms, dg.catalogue(["wall_friction"]))
    sim = diagnosis_simulator(design, {"preset": "tiny"})
    obs = sim({}, {}, 0)
    assert set(design.names) <= set(obs.names) and obs.source == "engine"
    assert 10 < obs["static_angle"][0] < 70
