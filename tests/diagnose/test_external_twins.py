"""LIGGGHTS twins: the effect is configuration (the same decks as the config route, no
rewriting), the easo capillary law against a two-sphere LIGGGHTS run with the dialect's
liquid bridges, and (slow) one tiny twin end to end."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bedstruct.dem import seed_contact_model
from bedstruct.engines import LiggghtsDialect, LiquidBridges, easo_bridge_volume, find_liggghts
from bedstruct.errors import ConfigError
from bedstruct.diagnose.validation.liggghts_law import easo_capillary_force, willett_capillary_force
from bedstruct.diagnose.validation.liggghts_twins import (effects_label, liggghts_simulator,
                                               liggghts_twin_design, make_liggghts_twin)

needs_liggghts = pytest.mark.skipif(find_liggghts() is None,
                                    reason="liggghts is not installed (.ci/install-engines.sh)")

#: Option values of a liquid-bridge twin: 0.05 N/m, liquid fraction 2e-3 on the tiny
#: preset's median sphere (r = 52 um, fraction 3 t / r), LIGGGHTS angle theta^2/2 of 30 deg.
BRIDGES = {"contact.capillary": True, "contact.capillary_surface_tension": 0.05,
           "contact.capillary_film_thickness": 2e-3 * 52e-6 / 3,
           "contact.capillary_contact_angle": 0.5 * math.radians(30.0) ** 2}
#: What the retired deck rewriting made of the tiny preset's LIGGGHTS repose deck with
#: these bridges: six property lines after the last property line, and the pair style.
REWRITTEN_PROPERTIES = [
    "fix twc1 all property/global surfaceLiquidContentInitial scalar 0.002",
    "fix twc2 all property/global surfaceTension scalar 0.05",
    "fix twc3 all property/global fluidViscosity scalar 0.001",
    "fix twc4 all property/global contactAngle peratomtype 30 30",
    "fix twc5 all property/global minSeparationDistanceRatio scalar 1.01",
    "fix twc6 all property/global maxSeparationDistanceRatio scalar 1.1",
]
REWRITTEN_PAIR = ("pair_style gran model hertz tangential history cohesion easo/capillary/viscous "
                  "rolling_friction epsd2")


def _model_lines(deck):
    return [ln for ln in deck.splitlines() if "property/global" in ln or ln.startswith("pair_style")]


def test_a_twin_writes_the_same_deck_as_the_config_route(tmp_path):
    """The twin's simulator puts its effect into the configuration; the deck is the one the
    config route writes, and the one the deck rewriting made (literal lines)."""
    from bedstruct.workflows import load_config
    from bedstruct.workflows.external import run_repose_external
    design = liggghts_twin_design()
    sim = liggghts_simulator(design, BRIDGES, workdir=tmp_path / "twin")
    base = {"cohesion_energy_density": 3.6e7, "friction": 0.4, "rolling_friction": 0.05,
            "restitution": 0.1}
    cfg = sim.run_config(base, {}, 1)
    cfg["external"]["write_only"] = True
    twin = open(run_repose_external(cfg, out=tmp_path / "a").decks[0]).read()
    over = [f"contact.cohesion={cfg['contact']['cohesion']!r}", "engine=liggghts",
            "external.write_only=true", "contact.capillary=true",
            *(f"{k}={v!r}" for k, v in BRIDGES.items() if k != "contact.capillary")]
    direct = open(run_repose_external(load_config(preset="tiny", overrides=over),
                                      out=tmp_path / "b").decks[0]).read()
    assert _model_lines(twin) == _model_lines(direct)
    # the rewriting's output: the plain deck with the bridges' lines inserted, pair style replaced
    plain = open(run_repose_external(load_config(preset="tiny", overrides=over[:3]),
                                     out=tmp_path / "c").decks[0]).read()
    plain = plain.replace(str(tmp_path / "c"), str(tmp_path / "b")).splitlines()
    last = max(i for i, ln in enumerate(plain) if "property/global" in ln)
    want = plain[:last + 1] + REWRITTEN_PROPERTIES + plain[last + 1:]
    want = [REWRITTEN_PAIR if ln.startswith("pair_style") else ln for ln in want]
    got = direct.splitlines()
    assert [ln for ln in got if not ln.startswith("#")] == [ln for ln in want if not ln.startswith("#")]
    assert any("effect realised differently: liquid bridges" in ln for ln in got[:3])
    assert sum("easo" in ln for ln in got if "wall/gran" in ln) == 0    # walls keep their model


def test_a_twin_with_an_effect_liggghts_lacks_is_refused_before_any_run(tmp_path):
    with pytest.raises(ConfigError, match="'liggghts' cannot realise the effect 'contact_ageing'"):
        liggghts_simulator(liggghts_twin_design(), {"contact.ageing": True,
                                                    "contact.ageing_bond_ratio": 1.0})
    with pytest.raises(ConfigError, match="'blade_startup'.*--engine embedded"):
        make_liggghts_twin(liggghts_twin_design(), {"spread.ramp_time": 0.05}, base={},
                           out=tmp_path)
    with pytest.raises(ConfigError, match="unknown config key `contact.wall_friction_excess`"):
        liggghts_simulator(liggghts_twin_design(), {"contact.wall_friction_excess": 0.3})
    with pytest.raises(TypeError, match="mapping of option values"):
        make_liggghts_twin(liggghts_twin_design(), "capillary", base={}, out=tmp_path)
    assert effects_label({"contact.wall_friction": 0.7, "contact.capillary": True}) == \
        "contact.capillary=True, contact.wall_friction=0.7"


def test_a_twins_options_are_set_after_each_calls_base_parameters(tmp_path):
    """A twin's rolling friction is the whole coefficient of its runs: the call's base
    parameters do not overwrite it (the simulator's options come after them)."""
    sim = liggghts_simulator(liggghts_twin_design(), {"contact.rolling_friction": 0.25,
                                                      "contact.rolling_model": "epsd2"},
                             workdir=tmp_path)
    cfg = sim.run_config({"friction": 0.3, "rolling_friction": 0.05}, {}, 1)
    assert cfg["contact"]["rolling_friction"] == 0.25 and cfg["contact"]["friction"] == 0.3
    assert cfg["engine"] == "liggghts" and cfg["contact"]["rolling_model"] == "epsd2"


def test_easo_law_values():
    # bridge volume of equal spheres: (1 - sqrt(3)/2) of one particle's liquid
    v = easo_bridge_volume(2.0, 2.0, 0.01)
    assert v == pytest.approx((1 - math.sqrt(3) / 2) * 4 / 3 * math.pi * 8 * 0.01)
    f = easo_capillary_force([0.0, 1e-6, 1e-3], 50e-6, 50e-6, surface_tension=0.072,
                             liquid_volume_fraction=1e-3)
    assert f[0] > f[1] > 0 and f[2] == 0.0          # decays with the gap, breaks beyond rupture
    # Willett-type: at contact within 25 % of the Willett pull-off 2 pi R gamma cos(theta)
    w = willett_capillary_force(0.0, 50e-6, 50e-6, surface_tension=0.072,
                                volume=float(easo_bridge_volume(50e-6, 50e-6, 1e-3)),
                                contact_angle=0.0)
    assert 0.75 < f[0] / w < 1.25


TWO_SPHERES = """# bedstruct deck for liggghts: two spheres pulled apart
atom_style granular
atom_modify map array
boundary f f f
newton off
communicate single vel yes
units si
region box block -2e-4 4e-4 -2e-4 2e-4 -2e-4 2e-4 units box
create_box 2 box
neighbor 2e-5 bin
neigh_modify delay 0
create_atoms 1 single 0 0 0 units box
create_atoms 1 single 0.99e-4 0 0 units box
set atom 1 diameter 1e-4 density 8300
set atom 2 diameter 1e-4 density 8300
{model}
timestep 1e-8
group a1 id 1
group a2 id 2
fix mv1 a1 move linear 0 0 0
fix mv2 a2 move linear 0.1 0 0
dump d all custom 500 out.dump id x y z fx fy fz radius
run 16000
"""


#: The two spheres' contact model: Hertz, SJKR cohesion, no rolling friction.
TWO_SPHERE_PARAMS = seed_contact_model(youngs_modulus=1e7, poisson_ratio=0.3, restitution=0.1,
                                       friction=0.4, rolling_friction=0.0, cohesion=3000.0)


def _two_sphere_deck(bridges=None):
    lines, _ = LiggghtsDialect(liquid_bridges=bridges).model_lines(TWO_SPHERE_PARAMS, n_types=2)
    return TWO_SPHERES.format(model="\n".join(lines))


def _two_sphere_forces(tmp_path, deck):
    from bedstruct.engines import run_deck
    (tmp_path / "in.two").write_text(deck)
    run_deck(tmp_path / "in.two", engine="liggghts", np=1, timeout=120)
    from bedstruct.io import read_dump
    traj = read_dump(tmp_path / "out.dump")
    gaps, f1 = [], []
    for i in range(len(traj)):
        fr = traj[i]
        x = np.asarray(fr.positions)[:, 0]
        gaps.append(x[1] - x[0] - 1e-4)
        f1.append(float(np.asarray(fr.forces)[0, 0]))
    return np.array(gaps), np.array(f1)


@needs_liggghts
@pytest.mark.parametrize("theta_deg", [0.0, 40.0])
def test_two_sphere_capillary_force_matches_the_documented_law(tmp_path, theta_deg):
    """Two 50 um spheres touch (1 um overlap), then separate at 0.1 m/s: beyond contact the
    force on sphere 1 is the bridge alone, pulling it towards sphere 2 (+x), as Soulie's
    law (LIGGGHTS' manual, with 3.8's angle and volume conventions) says, until rupture."""
    gamma, frac, theta = 0.05, 2e-3, math.radians(theta_deg)
    deck = _two_sphere_deck(LiquidBridges(gamma, frac, contact_angle=theta, fluid_viscosity=1e-9,
                                          max_separation_ratio=1.2))
    assert "cohesion easo/capillary/viscous" in deck
    gaps, f1 = _two_sphere_forces(tmp_path, deck)
    law = easo_capillary_force(gaps, 50e-6, 50e-6, surface_tension=gamma,
                               liquid_volume_fraction=frac, contact_angle=theta,
                               max_separation_ratio=1.2)
    sep = gaps > 1e-7
    assert sep.sum() >= 10
    bridged = sep & (law > 0)
    assert bridged.sum() >= 5 and (sep & (law == 0)).sum() >= 2      # rupture is inside the run
    assert np.all(f1[bridged] > 0)                                   # attraction
    np.testing.assert_allclose(f1[bridged], law[bridged], rtol=2e-3)
    np.testing.assert_array_equal(f1[sep & (law == 0)], 0.0)         # broken beyond rupture
    # Willett-type magnitude: within 25 % of Willett's closed form near contact
    w = willett_capillary_force(gaps[bridged][0], 50e-6, 50e-6, surface_tension=gamma,
                                volume=float(easo_bridge_volume(50e-6, 50e-6, frac)),
                                contact_angle=theta)
    assert 0.75 < f1[bridged][0] / w < 1.25
    # without the bridges (SJKR only) there is no force once the spheres are apart
    _, f_base = _two_sphere_forces(tmp_path, _two_sphere_deck())
    np.testing.assert_array_equal(f_base[sep], 0.0)


@needs_liggghts
def test_liggghts_skips_bridges_below_the_easo_volume_cut_off(tmp_path):
    """The cut-off the LIGGGHTS dialect refuses thin films by (EASO_MIN_BRIDGE_VOLUME):
    two 50 um spheres with a liquid fraction 10 % above it are bridged as Soulie's law says;
    10 % below it LIGGGHTS gives the separating spheres no force at all."""
    from bedstruct.engines import EASO_MIN_BRIDGE_VOLUME
    gamma, r = 0.05, 50e-6
    cut = EASO_MIN_BRIDGE_VOLUME / float(easo_bridge_volume(r, r, 1.0))  # the fraction at the cut-off
    forces = {}
    for name, frac in (("above", 1.1 * cut), ("below", 0.9 * cut)):
        bridges = LiquidBridges(gamma, frac, contact_angle=0.0, fluid_viscosity=1e-9,
                                max_separation_ratio=1.2)
        (tmp_path / name).mkdir()
        forces[name] = _two_sphere_forces(tmp_path / name, _two_sphere_deck(bridges))
    gaps, f_above = forces["above"]
    law = easo_capillary_force(gaps, r, r, surface_tension=gamma, liquid_volume_fraction=1.1 * cut,
                               contact_angle=0.0, max_separation_ratio=1.2)
    bridged = (gaps > 1e-7) & (law > 0)
    assert bridged.sum() >= 3
    np.testing.assert_allclose(f_above[bridged], law[bridged], rtol=2e-3)
    gaps_b, f_below = forces["below"]
    np.testing.assert_array_equal(f_below[gaps_b > 1e-7], 0.0)
    assert not np.any(easo_capillary_force(gaps_b, r, r, surface_tension=gamma,
                                           liquid_volume_fraction=0.9 * cut))   # the law says so


@needs_liggghts
@pytest.mark.slow
def test_one_tiny_twin_end_to_end(tmp_path):
    import bedstruct.diagnose as dg
    from dataclasses import replace
    design = liggghts_twin_design()
    # without the layer-2 dynamic angle: with mu_r = 0.25 the tiny pile is often used up
    # before layer 2 (no heap to fit)
    design = replace(design, measurements=tuple(m for m in design if m.kind != "dynamic_angle_series"))
    base = {"cohesion_energy_density": 3.6e7, "friction": 0.4, "rolling_friction": 0.05,
            "restitution": 0.1}
    twin = make_liggghts_twin(design, {"contact.rolling_friction": 0.25,
                                       "contact.rolling_model": "epsd2"},
                              base=base, out=tmp_path,
                              seeds=(1000, 1001))
    ms = dg.load_measurements(twin.path)
    assert set(ms.names) == set(design.names)
    assert all(np.all(np.isfinite(m.values)) and np.all(m.uncertainty > 0) for m in ms)
    assert "rolling" not in twin.path.read_text()               # the truth is not in the file
    truth = json.loads(twin.truth_path.read_text())
    assert truth["effects"]["contact.rolling_friction"] == 0.25
    assert len(truth["raw"]["static_angle"]) == 2
    # bed heights of the tiny preset's layers (450 and 750 um below the tool) are sane
    assert 200e-6 < ms["bed_height_layer1"].values[0] < 600e-6


@needs_liggghts
@pytest.mark.slow
def test_wall_friction_moves_the_recoater_load_in_liggghts_as_in_the_engine(tmp_path):
    """Independent implementation: LIGGGHTS with its particle-wall friction lowered by 0.2
    (mu_w 0.2) against the embedded engine's wall friction at d_mu = -0.2, on the recoater
    load ratio of the tiny preset's second x1 layer (measured on 3 seeds each: LIGGGHTS
    0.179 -> 0.118, embedded 0.172 -> 0.127; run scatter about 0.01)."""
    import bedstruct.diagnose as dg
    from bedstruct.diagnose.engine_simulator import EngineSimulator
    design = dg.MeasurementSet((dg.measurement_from_dict(dict(
        name="tool_force_ratio_x1_layer2", kind="tool_force_ratio", value=0.0, uncertainty=0.005,
        conditions=dict(speed=0.0254, layer=2))),))
    base = {"cohesion_energy_density": 3.6e7, "friction": 0.4, "rolling_friction": 0.05,
            "restitution": 0.1}
    seeds = (0, 1)

    def mean_ratio(sim, effects):
        return float(np.mean([sim(dict(base), effects, s)["tool_force_ratio_x1_layer2"][0]
                              for s in seeds]))
    embedded = EngineSimulator(design, {"preset": "tiny", "n_threads": 1})
    e0, e1 = mean_ratio(embedded, {}), mean_ratio(embedded, {"wall_friction": -0.2})
    l0 = mean_ratio(liggghts_simulator(design, {}, workdir=tmp_path / "null"), {})
    l1 = mean_ratio(liggghts_simulator(design, {"contact.wall_friction": 0.4 - 0.2},
                                       workdir=tmp_path / "wf"), {})
    assert abs(l0 - e0) < 0.03                       # the two engines' base loads agree
    assert e1 - e0 < -0.025 and l1 - l0 < -0.025     # both respond, beyond the scatter
    assert 0.5 < (l1 - l0) / (e1 - e0) < 2.0         # by about as much


def test_twin_readings_follow_the_replicate_rule():
    """Mean of the noisy readings; uncertainty sqrt(s^2/n + u^2) (s from the readings), or
    sqrt(scatter^2 + u^2) with one seed."""
    from bedstruct.diagnose.validation.liggghts_twins import _twin_readings
    design = liggghts_twin_design().select(("calibrate", "validate"))
    m = design["packing_fraction_x1_center"]                 # u = 0.005
    raw = {k.name: np.full((3, k.n_components), 0.5) for k in design}
    raw[m.name] = np.array([[0.40], [0.50], [0.60]])
    vals, unc = _twin_readings(design, raw, rng=np.random.default_rng(1))
    rng = np.random.default_rng(1)                            # the same draws, in design order
    for k in design:
        r = raw[k.name] + k.uncertainty * rng.standard_normal(raw[k.name].shape)
        np.testing.assert_allclose(vals[k.name], r.mean(axis=0))
        np.testing.assert_allclose(unc[k.name], np.sqrt(r.var(axis=0, ddof=1) / 3 + k.uncertainty ** 2))
    assert 0.05 < unc[m.name][0] < 0.07                       # dominated by the 0.1 scatter / sqrt(3)
    one = {k.name: raw[k.name][:1] for k in design}
    _, unc1 = _twin_readings(design, one, rng=np.random.default_rng(2), scatter={m.name: 0.012})
    assert unc1[m.name][0] == pytest.approx(0.013)           # sqrt(0.012^2 + 0.005^2)
    assert unc1["static_angle"][0] == pytest.approx(1.0)     # no scatter given: reading error only


def test_unobservable_repetitions_are_repeated_then_kept_as_missing():
    from bedstruct.diagnose import Observations
    from bedstruct.diagnose.validation.liggghts_twins import _run_seeds, _twin_readings
    calls = []

    def sim(base, effects, seed):
        calls.append(seed)
        lost = seed in (1001, 1002, 1002 + 7919)          # no heap to fit in these runs
        return Observations({"dyn": [np.nan if lost else float(seed)], "bh": [1.0]})

    runs, used = _run_seeds(sim, {}, (1000, 1001, 1002), replace_failed=1)
    assert used == [1000, 1001 + 7919, 1002 + 7919]
    assert [float(r["dyn"][0]) for r in runs[:2]] == [1000.0, 1001.0 + 7919]
    assert np.isnan(runs[2]["dyn"][0])                     # still lost after the repeat: missing
    design = liggghts_twin_design().select(("calibrate", "validate"))
    m, other = design["dynamic_angle_x1"], design["bed_height_layer1"]
    raw = {k.name: np.full((3, k.n_components), 0.5) for k in design}
    raw[m.name] = np.array([[20.0, 30.0], [np.nan, np.nan], [24.0, 34.0]])
    vals, unc = _twin_readings(design, raw, rng=np.random.default_rng(3))
    assert np.all(np.isfinite(vals[m.name])) and abs(vals[m.name][0] - 22.0) < 4.0
    raw[m.name][:] = np.nan
    vals, _ = _twin_readings(design, raw, rng=np.random.default_rng(3))
    assert m.name not in vals and other.name in vals


@needs_liggghts
def test_two_sphere_bridges_from_the_config_have_the_config_angle_and_liquid(tmp_path):
    """contact.capillary on LIGGGHTS (LiquidBridges.from_film): a film t on spheres of the
    reference radius r gives the liquid fraction 3 t / r, and LIGGGHTS applies the config's
    contact angle (0.5 rad, far from the per-type value it is written as): Soulie's law at
    theta = 0.5 rad, not at the per-type angle, matches the run."""
    theta, r = 0.5, 50e-6
    b = LiquidBridges.from_film(surface_tension=0.05, contact_angle=theta,
                                film_thickness=2e-3 * r / 3, reference_radius=r,
                                fluid_viscosity=1e-9, max_separation_ratio=1.2)
    assert b.liquid_volume_fraction == pytest.approx(2e-3, rel=1e-12)
    gaps, f1 = _two_sphere_forces(tmp_path, _two_sphere_deck(b))

    def soulie(theta_eff):
        # Soulie's law written out at an effective angle (LIGGGHTS' manual), bridge volume of
        # equal spheres (1 - sqrt(3)/2) of one particle's liquid
        vol = (1 - math.sqrt(3) / 2) * 4 / 3 * math.pi * r ** 3 * 2e-3
        vs = vol / r ** 3
        a = -1.1 * vs ** -0.53
        bb = (-0.148 * math.log(vs) - 0.96) * theta_eff ** 2 - 0.0082 * math.log(vs) + 0.48
        c = 0.0018 * math.log(vs) + 0.078
        f = math.pi * 0.05 * r * (np.exp(a * np.maximum(gaps, 0) / r + bb) + c)
        rupture = min((1 + 0.5 * theta_eff) * vol ** (1 / 3), 0.2 * 2 * r)
        return np.where(gaps < rupture, f, 0.0)

    law = soulie(theta)
    bridged = (gaps > 1e-7) & (law > 0)
    assert bridged.sum() >= 5
    np.testing.assert_allclose(f1[bridged], law[bridged], rtol=2e-3)
    # the per-type angle (sqrt(2 theta) = 1 rad) taken as the effective one is off by 3 %
    # near contact, ten times the tolerance above
    wrong = soulie(b.contact_angle)
    assert np.max(np.abs(f1[bridged] / wrong[bridged] - 1)) > 0.02


@needs_liggghts
def test_liggghts_runs_the_epsd_rolling_model_with_its_dashpot(tmp_path):
    """contact.rolling_model = "epsd" on LIGGGHTS: its EPSD needs the viscous damping
    property the dialect writes (without it LIGGGHTS stops); a pair in contact then has
    a rolling torque only after it rolls, so the two-sphere run still separates cleanly."""
    from dataclasses import replace
    p = replace(TWO_SPHERE_PARAMS, rolling_friction=0.2, rolling_model="epsd")
    lines, _ = LiggghtsDialect().model_lines(p, n_types=2)
    assert any("coefficientRollingViscousDamping" in ln for ln in lines)
    gaps, f1 = _two_sphere_forces(tmp_path, TWO_SPHERES.format(model="\n".join(lines)))
    assert len(gaps) >= 20 and np.all(f1[gaps > 1e-7] == 0.0)
