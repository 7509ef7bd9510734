"""The diagnosis' effects as configuration options and the engine hook (wiring, not physics runs)."""

import math

import numpy as np
import pytest

from bedstruct.diagnose.catalogue import CATALOGUE, effect
from bedstruct.errors import ConfigError
from bedstruct.diagnose.engine_simulator import effects_config, with_options
from bedstruct.workflows import load_config
from bedstruct.workflows.config import _MOVED_EFFECT_KEYS
from bedstruct.workflows._common import contact_model, psd_sampler, tool_motion


def test_every_catalogue_engine_parameter_is_a_config_key():
    cfg = load_config(preset="tiny")
    for e in CATALOGUE:
        for key in e.engine_parameters(e.prior[1], cfg):
            section, _, name = key.partition(".")
            assert name in cfg[section], (e.name, key)
        # and the top of the prior is a valid configuration
        load_config(with_options(cfg, effects_config({e.name: e.prior[1]}, cfg)))


def test_magnitude_zero_is_the_base_model():
    base = load_config(preset="tiny")
    for e in CATALOGUE:
        assert effects_config({e.name: 0.0}, base) == {}
    cfg = with_options(base, effects_config({e.name: 0.0 for e in CATALOGUE}, base))
    assert contact_model(cfg) == contact_model(base)
    rng_a, rng_b = np.random.default_rng(4), np.random.default_rng(4)
    np.testing.assert_array_equal(psd_sampler(cfg)(500, rng_a), psd_sampler(base)(500, rng_b))


def test_contact_model_mapping():
    base = load_config(preset="tiny")
    cfg = with_options(base, effects_config({"wall_friction": 0.2, "non_sphericity": 0.1,
                                             "capillary_bridges": 0.5, "contact_ageing": 1.0},
                                            base))
    m = contact_model(cfg)
    mu = cfg["contact"]["friction"]
    t = m.tables()
    assert t.friction[0, 1] == pytest.approx(mu + 0.2) and t.friction[0, 0] == pytest.approx(mu)
    assert m.rolling_model == "epsd" and m.rolling_stiffness_factor == 2.25
    assert m.rolling_friction == pytest.approx(base["contact"]["rolling_friction"] + 0.1)
    cap = effect("capillary_bridges").engine_parameters(0.5)  # asperity-scale bridges
    assert m.capillary and m.capillary_surface_tension == pytest.approx(
        cap["contact.capillary_surface_tension"]) and 0 < m.capillary_surface_tension < 0.072
    assert m.capillary_contact_angle == pytest.approx(math.radians(20))
    assert m.capillary_film_thickness == pytest.approx(cap["contact.capillary_film_thickness"])
    assert m.contact_ageing and m.ageing_bond_ratio == 1.0 and m.ageing_time_constant == 10.0
    # a polished wall: an excess below -mu clips at 0 (a negative option is the particle value)
    cfg = with_options(base, effects_config({"wall_friction": -1.0}, base))
    assert cfg["contact"]["wall_friction"] == 0.0
    assert contact_model(cfg).tables().friction[0, 1] == 0.0


@pytest.mark.parametrize("effects, option, want", [
    ({"non_sphericity": 0.05}, "rolling_friction", 0.15),    # base 0.1 + shape 0.05
    ({"wall_friction": 0.2}, "wall_friction", 0.7),          # base friction 0.5 + excess 0.2
    ({"wall_friction": -0.2}, "wall_friction", 0.3)])
def test_offset_effects_give_absolute_values_on_a_non_default_base(effects, option, want):
    """An effect that changes a contact coefficient is applied to the configuration being
    diagnosed: the option holds the whole coefficient, read by the engine as it is."""
    base = load_config(preset="tiny", overrides=["contact.rolling_friction=0.1",
                                                 "contact.friction=0.5",
                                                 "contact.wall_friction=0.9"])
    cfg = load_config(with_options(base, effects_config(effects, base)))
    assert cfg["contact"][option] == pytest.approx(want, abs=1e-12)
    m = contact_model(cfg)
    t = m.tables()
    if option == "rolling_friction":
        assert m.rolling_model == "epsd"
        assert t.rolling_friction[0, 0] == pytest.approx(want) and \
            t.rolling_friction[0, 1] == pytest.approx(want)
    else:   # the particle-wall row; particles keep their friction
        assert t.friction[0, 1] == pytest.approx(want) and t.friction[0, 0] == pytest.approx(0.5)
    # the offset needs the configuration being diagnosed
    with pytest.raises(ValueError, match="base="):
        effects_config(effects)


def test_fines_tail_carries_the_mass_fraction():
    phi = 0.1
    cfg = with_options(load_config(preset="tiny"), effects_config({"missing_fines": phi}))
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


def test_effect_options_are_checked():
    with pytest.raises(ConfigError, match="psd.fines_mass_fraction"):
        load_config(preset="tiny", overrides=["psd.fines_mass_fraction=1.5"])
    with pytest.raises(ConfigError, match="contact.capillary_film_thickness"):
        load_config(preset="tiny", overrides=["contact.capillary=true"])
    with pytest.raises(ConfigError, match="unknown config key `contact.humidity`"):
        load_config(preset="tiny", overrides=["contact.humidity=0.3"])
    with pytest.raises(ConfigError, match="unknown config key `spread.blade_ramp_time`"):
        with_options(load_config(preset="tiny"), {"spread.blade_ramp_time": 0.1})


def test_an_effects_section_is_refused_naming_the_new_options(tmp_path):
    """A user file or a run folder's configuration with ``[effects]`` is refused, each
    of its keys named with the option that replaces it; nothing is translated."""
    f = tmp_path / "effects.toml"
    f.write_text('preset = "tiny"\n[effects]\ncapillary = true\nwall_friction_excess = 0.2\n'
                 'shape_rolling_friction = 0.1\nblade_ramp_time = 0.01\nfines_sigma_ln = 0.3\n')
    with pytest.raises(ConfigError) as err:
        load_config(f)
    msg = str(err.value)
    for key, option in [("capillary", "contact.capillary"), ("blade_ramp_time", "spread.ramp_time"),
                        ("fines_sigma_ln", "psd.fines_sigma_ln")]:
        assert f"effects.{key} -> {option}" in msg
    assert "effects.wall_friction_excess -> contact.wall_friction (the particle-wall friction" in msg
    assert "effects.shape_rolling_friction -> contact.rolling_friction (the whole" in msg
    assert "effects.contact_ageing" not in msg      # only the keys the file has
    with pytest.raises(ConfigError, match=r"effects.contact_ageing -> contact.ageing\)"):
        load_config(preset="tiny", overrides=["effects.contact_ageing=true"])
    stored = load_config(preset="tiny")
    stored["effects"] = {}   # a config.json with an empty section: every key is named
    with pytest.raises(ConfigError) as err:
        load_config(stored)
    assert all(f"effects.{k} -> {v}" in str(err.value) for k, v in _MOVED_EFFECT_KEYS.items())
    # every option named exists
    cfg = load_config(preset="tiny")
    for option in _MOVED_EFFECT_KEYS.values():
        section, _, key = option.split(" ")[0].partition(".")
        assert key in cfg[section], option


def test_tool_motion_uses_the_ramp_program():
    from bedstruct import Box
    from bedstruct.dem import Material, ContactModel, Plane, Simulation
    cfg = with_options(load_config(preset="tiny"), effects_config({"blade_startup": 0.01}))
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
    assert cfg["contact"]["ageing_time_constant"] == pytest.approx(0.01)
    assert cfg["contact"]["ageing"] and cfg["contact"]["ageing_bond_ratio"] == 1.0
    # the offset effects read the call's base parameters, not the preset's
    cfg = sim.run_config({"friction": 0.3, "rolling_friction": 0.1},
                         {"wall_friction": 0.2, "non_sphericity": 0.05}, seed=2)
    assert cfg["contact"]["wall_friction"] == pytest.approx(0.5)
    assert cfg["contact"]["rolling_friction"] == pytest.approx(0.15)
    with pytest.raises(ConfigError, match="base parameter"):
        sim.run_config({"stiffness": 1.0}, {}, 0)
    with pytest.raises(ConfigError, match="engine"):
        diagnosis_simulator(MeasurementSet((m,)), {"presett": "tiny"})
    # fines change the PSD observable, magnitude 0 does not
    p0 = sim({}, {}, 0)["psd"]
    assert np.array_equal(sim({}, {"missing_fines": 0.0}, 0)["psd"], p0)
    assert sim({}, {"missing_fines": 0.1}, 0)["psd"][0] < 0.95 * p0[0]
    assert effect("missing_fines").engine_parameters(0.1)["psd.fines_mass_fraction"] == 0.1


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


def test_every_effect_option_at_its_default_is_the_base_model_bit_for_bit():
    """The configuration's effect options at their defaults build the plain base contact
    model (no extension field set), and the engine's trajectory is the same to the bit."""
    from bedstruct import Box
    from bedstruct.dem import ContactModel, Material, Plane, Simulation
    cfg = load_config(preset="tiny", overrides=["contact.rolling_friction=0.1",
                                                "contact.cohesion=1e4"])
    c, m = cfg["contact"], cfg["material"]
    walls = {k: c[k] for k in ("wall_friction", "wall_cohesion") if c[k] >= 0}
    plain = ContactModel(Material(m["youngs_modulus"], m["poisson_ratio"], m["density"]),
                         restitution=c["restitution"], friction=c["friction"],
                         rolling_friction=c["rolling_friction"], cohesion=c["cohesion"],
                         rolling_model=c["rolling_model"], **walls)
    model = contact_model(cfg)
    assert model == plain and model.extension_code == 0

    def run(model):
        box = Box([0, 0, 0], [1.2e-3, 1.2e-3, 3e-3], boundary="pp pp ff")
        sim = Simulation(box, model, walls=[Plane((0, 0, 0), (0, 0, 1))], n_threads=1, seed=3)
        sim.insert_raindrop(60, 1e-4, region=((0, 0, 0), (1.2e-3, 1.2e-3, 1.5e-3)))
        sim.run(steps=300)
        return sim.frame()
    a, b = run(plain), run(model)
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.velocities, b.velocities)
    # the PSD without fines and the tool without start-up are the base ones too
    assert not hasattr(psd_sampler(cfg), "fines_number_fraction")
