"""LIGGGHTS twins: deck transformations (text), the easo capillary law against a two-sphere
LIGGGHTS run, the wrapper executable, and (slow) one tiny twin end to end."""

from __future__ import annotations

import json
import math
import subprocess

import numpy as np
import pytest

from bedstruct.engines import find_liggghts
from bedstruct.diagnose.liggghts_effects import (
    TWIN_MARK, apply_effect, capillary_effect, easo_bridge_volume, easo_capillary_force,
    null_effect, rolling_friction_effect, wall_friction_effect, willett_capillary_force,
    with_capillary_bridges, with_rolling_friction, with_wall_friction)
from bedstruct.diagnose.external_twins import (
    liggghts_simulator, liggghts_twin_design, make_liggghts_twin, write_liggghts_wrapper)

needs_liggghts = pytest.mark.skipif(find_liggghts() is None,
                                    reason="liggghts is not installed (.ci/install-engines.sh)")

BASE = "\n".join([
    "# bedstruct deck for liggghts: test",
    "fix m1 all property/global youngsModulus peratomtype 1000000 1000000",
    "fix m4 all property/global coefficientFriction peratomtypepair 2 0.4 0.4 0.4 0.4",
    "fix m5 all property/global coefficientRollingFriction peratomtypepair 2 0.05 0.06 0.06 0.07",
    "fix m6 all property/global cohesionEnergyDensity peratomtypepair 2 3000 0 0 3000",
    "pair_style gran model hertz tangential history cohesion sjkr rolling_friction epsd2",
    "pair_coeff * *",
    "fix wmesh all wall/gran model hertz tangential history cohesion sjkr rolling_friction epsd2 "
    "mesh n_meshes 1 meshes plate",
    "run 10",
])


def _line(deck, start):
    return [ln for ln in deck.splitlines() if ln.startswith(start)]


def test_rolling_friction_sets_particle_entries_only():
    out = with_rolling_friction(BASE, 0.25)
    (ln,) = _line(out, "fix m5 ")
    assert ln.split()[-4:] == ["0.25", "0.25", "0.25", "0.07"]   # 1-1, 1-2, 2-1 set; 2-2 kept
    out = with_rolling_friction(BASE, 0.25, walls=False)
    assert _line(out, "fix m5 ")[0].split()[-4:] == ["0.25", "0.06", "0.06", "0.07"]
    # everything else is untouched
    assert [a for a in BASE.splitlines() if not a.startswith("fix m5")] == \
        [a for a in out.splitlines() if not a.startswith("fix m5")]


def test_rolling_friction_added_where_the_base_has_none():
    base = BASE.replace(" rolling_friction epsd2", "").replace(
        "fix m5 all property/global coefficientRollingFriction peratomtypepair 2 0.05 0.06 0.06 0.07\n", "")
    out = with_rolling_friction(base, 0.2)
    (pair,) = _line(out, "pair_style")
    assert pair.endswith("cohesion sjkr rolling_friction epsd2")
    (wall,) = _line(out, "fix wmesh")
    assert "cohesion sjkr rolling_friction epsd2 mesh n_meshes" in wall
    (prop,) = [ln for ln in out.splitlines() if "coefficientRollingFriction" in ln]
    assert prop.split()[-5:] == ["2", "0.2", "0.2", "0.2", "0"]
    lines = out.splitlines()
    assert lines.index(prop) < lines.index(pair)   # properties before the pair style


def test_capillary_replaces_pair_cohesion_and_adds_properties():
    out = with_capillary_bridges(BASE, surface_tension=0.05, liquid_volume_fraction=2e-3,
                                 contact_angle=math.radians(30.0))
    (pair,) = _line(out, "pair_style")
    assert pair == ("pair_style gran model hertz tangential history cohesion "
                    "easo/capillary/viscous rolling_friction epsd2")
    assert _line(out, "fix wmesh") == _line(BASE, "fix wmesh")        # walls keep SJKR
    props = {ln.split()[4]: ln.split()[5:] for ln in out.splitlines() if "property/global" in ln}
    assert props["surfaceTension"] == ["scalar", "0.05"]
    assert props["surfaceLiquidContentInitial"] == ["scalar", "0.002"]
    assert props["contactAngle"] == ["peratomtype", "30", "30"]      # degrees, one per type
    assert props["maxSeparationDistanceRatio"] == ["scalar", "1.1"]
    assert "cohesionEnergyDensity" in props                          # still needed by the walls


def test_wall_friction_replaces_the_particle_wall_entries_only():
    out = with_wall_friction(BASE, 0.75)
    (prop,) = [ln for ln in out.splitlines() if "coefficientFriction " in ln]
    assert prop.split()[-5:] == ["2", "0.4", "0.75", "0.75", "0.4"]
    changed = [a for a, b in zip(BASE.splitlines(), out.splitlines()) if a != b]
    assert len(changed) == 1 and "coefficientFriction " in changed[0]
    assert apply_effect(BASE, wall_friction_effect(0.75)).splitlines()[0] == \
        f"{TWIN_MARK} wall_friction 0.75"
    with pytest.raises(ValueError, match="no 'property/global coefficientFriction"):
        with_wall_friction("\n".join(ln for ln in BASE.splitlines()
                                     if "coefficientFriction " not in ln), 0.75)
    with pytest.raises(ValueError, match="wall_friction must be >= 0"):
        wall_friction_effect(-0.1)


def test_apply_effect_marks_and_null_changes_nothing():
    out = apply_effect(BASE, null_effect())
    assert out.splitlines()[0] == f"{TWIN_MARK} none"
    assert out.splitlines()[1:] == BASE.splitlines()
    assert apply_effect(BASE, rolling_friction_effect(0.3)).splitlines()[0].endswith("0.3")
    with pytest.raises(ValueError, match="not a bedstruct LIGGGHTS deck"):
        apply_effect("units si\n", null_effect())
    with pytest.raises(ValueError, match="rolling_friction must be > 0"):
        rolling_friction_effect(0.0)


def test_wrapper_rewrites_once_keeps_the_original_and_runs_the_engine(tmp_path):
    fake = tmp_path / "fake-liggghts"
    fake.write_text("#!/bin/sh\necho ran \"$@\" > ran.txt\n")
    fake.chmod(0o755)
    exe = write_liggghts_wrapper(tmp_path / "bin", rolling_friction_effect(0.4), liggghts=str(fake))
    deck = tmp_path / "in.repose"
    deck.write_text(BASE + "\n")
    for _ in range(2):  # a second call must not stack the effect
        subprocess.run([str(exe), "-in", str(deck), "-log", "in.log"], cwd=tmp_path, check=True)
    text = deck.read_text()
    assert text.count(TWIN_MARK) == 1 and "0.4 0.4 0.4 0.07" in text
    assert (tmp_path / "in.repose.base").read_text() == BASE + "\n"
    assert (tmp_path / "ran.txt").read_text().split()[1:3] == ["-in", str(deck)]
    assert (tmp_path / "bin" / "last-in.repose").read_text() == text
    assert json.loads((tmp_path / "bin" / "twin-effect.json").read_text())["effect"]["kind"] == \
        "rolling_friction"


def test_workflow_decks_transform(tmp_path):
    """The decks the public external workflow writes take every transformation."""
    from bedstruct.workflows import load_config
    from bedstruct.workflows.external import run_repose_external
    cfg = load_config(preset="tiny", overrides=["engine=liggghts", "external.write_only=true"])
    res = run_repose_external(cfg, out=tmp_path)
    deck = open(res.decks[0]).read()
    for eff in (null_effect(), rolling_friction_effect(0.2), capillary_effect(),
                wall_friction_effect(0.8)):
        out = apply_effect(deck, eff)
        assert out.splitlines()[1:] != deck.splitlines() or eff.kind == "none"
        assert out.count("pair_style gran") == 1
    cap = apply_effect(deck, capillary_effect())
    assert "cohesion easo/capillary/viscous" in _line(cap, "pair_style")[0]
    assert all("easo" not in ln for ln in cap.splitlines() if "wall/gran" in ln)


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
fix m1 all property/global youngsModulus peratomtype 1e7 1e7
fix m2 all property/global poissonsRatio peratomtype 0.3 0.3
fix m3 all property/global coefficientRestitution peratomtypepair 2 0.1 0.1 0.1 0.1
fix m4 all property/global coefficientFriction peratomtypepair 2 0.4 0.4 0.4 0.4
fix m6 all property/global cohesionEnergyDensity peratomtypepair 2 3000 3000 3000 3000
pair_style gran model hertz tangential history cohesion sjkr
pair_coeff * *
timestep 1e-8
group a1 id 1
group a2 id 2
fix mv1 a1 move linear 0 0 0
fix mv2 a2 move linear 0.1 0 0
dump d all custom 500 out.dump id x y z fx fy fz radius
run 16000
"""


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
    deck = with_capillary_bridges(TWO_SPHERES, surface_tension=gamma, liquid_volume_fraction=frac,
                                  contact_angle=theta, fluid_viscosity=1e-9,
                                  max_separation_ratio=1.2)
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
    # the untransformed deck (SJKR only) has no force once the spheres are apart
    _, f_base = _two_sphere_forces(tmp_path, TWO_SPHERES)
    np.testing.assert_array_equal(f_base[sep], 0.0)


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
    twin = make_liggghts_twin(design, rolling_friction_effect(0.25), base=base, out=tmp_path,
                              seeds=(1000, 1001))
    ms = dg.load_measurements(twin.path)
    assert set(ms.names) == set(design.names)
    assert all(np.all(np.isfinite(m.values)) and np.all(m.uncertainty > 0) for m in ms)
    assert "0.25" not in twin.path.read_text()                  # the truth is not in the file
    truth = json.loads(twin.truth_path.read_text())
    assert truth["effect"]["rolling_friction"] == 0.25 and len(truth["raw"]["static_angle"]) == 2
    kept = (tmp_path / "bin" / "last-in.repose").read_text()
    assert kept.startswith(TWIN_MARK) and "coefficientRollingFriction peratomtypepair 2 0.25" in kept
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
    l0 = mean_ratio(liggghts_simulator(design, null_effect(), workdir=tmp_path / "null"), {})
    l1 = mean_ratio(liggghts_simulator(design, wall_friction_effect(0.2), workdir=tmp_path / "wf"),
                    {})
    assert abs(l0 - e0) < 0.03                       # the two engines' base loads agree
    assert e1 - e0 < -0.025 and l1 - l0 < -0.025     # both respond, beyond the scatter
    assert 0.5 < (l1 - l0) / (e1 - e0) < 2.0         # by about as much


def test_twin_readings_follow_the_replicate_rule():
    """Mean of the noisy readings; uncertainty sqrt(s^2/n + u^2) (s from the readings), or
    sqrt(scatter^2 + u^2) with one seed."""
    from bedstruct.diagnose.external_twins import _twin_readings
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
    from bedstruct.diagnose.external_twins import _run_seeds, _twin_readings
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
