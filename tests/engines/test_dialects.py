"""The dialects: each engine's spelling of the same scenarios, and what they refuse.

The expected decks and lines below were written by the deck generators before they were
organised by engine; a change of any byte of them is a change of behaviour. No engine
is needed: decks are text.
"""

from __future__ import annotations

import numpy as np
import math

import pytest

from bedstruct.dem import ContactModel, Material, seed_contact_model
from bedstruct.engines import (EFFECT_KEYS, BladeGeometry, Dialect, LammpsDialect,
                               LiquidBridges, LiggghtsDialect, ReposeGeometry, ReposeSchedule,
                               RollerGeometry, SpreadLayersPlan, bed_deck, dialect,
                               effect_realisations, impact_deck, liggghts_model_commands,
                               repose_deck, spread_layers_deck, write_sphere_data)
from bedstruct.errors import ConfigError

IMPACT_LAMMPS = """\
# bedstruct deck for lammps: head-on impact on a sphere
atom_style sphere
atom_modify map array
boundary f f f
newton off
comm_modify vel yes
units si
region reg block -0.0008 0.0008 -0.0008 0.0008 -0.0008 0.0008 units box
create_box 1 reg
neighbor 2e-06 bin
neigh_modify delay 0
pair_style granular
pair_coeff * * hertz/material 10000000 0.1 0.3 damping coeff_restitution tangential mindlin NULL 1.0 0.4 rolling sds 2.861789738 0.0 0.05
timestep 1e-09
create_atoms 1 single -2.1e-05 0 0 units box
create_atoms 1 single 2.1e-05 0 0 units box
set atom 1 diameter 4e-05
set atom 2 diameter 4e-05
set atom * density 8300
velocity all set 0 0 0 units box
set atom 1 vx 0.5
set atom 2 vx -0.5
variable dist equal x[2]-x[1]
variable vx1 equal vx[1]
variable vx2 equal vx[2]
fix integr all nve/sphere
thermo_style custom step time v_dist v_vx1 v_vx2 ke
thermo 3
thermo_modify norm no format float %.12g
run 21771
"""

IMPACT_LIGGGHTS_WALL = """\
# bedstruct deck for liggghts: head-on impact on a wall
atom_style granular
atom_modify map array
boundary f f f
newton off
communicate single vel yes
units si
region reg block -0.0008 0.0008 -0.0008 0.0008 -2e-05 0.0008 units box
create_box 2 reg
neighbor 2e-06 bin
neigh_modify delay 0
fix m1 all property/global youngsModulus peratomtype 10000000 200000000
fix m2 all property/global poissonsRatio peratomtype 0.3 0.3
fix m3 all property/global coefficientRestitution peratomtypepair 2 0.1 0.5 0.5 0.1
fix m4 all property/global coefficientFriction peratomtypepair 2 0.4 0.6 0.6 0.4
fix m5 all property/global coefficientRollingFriction peratomtypepair 2 0.05 0.1 0.1 0.05
pair_style gran model hertz tangential history rolling_friction epsd2
pair_coeff * *
timestep 1e-09
fix wbottom all wall/gran model hertz tangential history rolling_friction epsd2 primitive type 2 zplane 0
create_atoms 1 single 0 0 2.1e-05 units box
set atom 1 diameter 4e-05
set atom * density 8300
velocity all set 0 0 0 units box
set atom 1 vz -1
variable dist equal z[1]
variable vx1 equal vz[1]
variable vx2 equal 0.0
fix integr all nve/sphere
thermo_style custom step time v_dist v_vx1 v_vx2 ke
thermo 3
thermo_modify norm no
run 18551
"""

WALLS = seed_contact_model(wall_friction=0.6, wall_material=Material(2e8, 0.3),
                           wall_restitution=0.5, wall_rolling_friction=0.1, wall_cohesion=1e4)


def _fields(model):
    """The init fields of ``model`` but its materials."""
    from dataclasses import fields
    return {f.name: getattr(model, f.name) for f in fields(model)
            if f.init and f.name not in ("materials", "_tables")}


def lines(deck, prefix):
    return [ln for ln in deck.splitlines() if ln.startswith(prefix)]


@pytest.fixture
def bed(tmp_path):
    rng = np.random.default_rng(1)
    pos = rng.uniform(0, 4e-4, (30, 3))
    rad = rng.uniform(1e-5, 3e-5, 30)
    return write_sphere_data(tmp_path / "bed.data", pos, rad, box_lo=[0, 0, 0],
                             box_hi=[4e-4, 4e-4, 8e-4], n_types=2)


def test_impact_decks_are_those_written_before_the_dialects():
    assert impact_deck(seed_contact_model(), engine="lammps", dt=1e-9, gap=0.05,
                       thermo_every=3) == IMPACT_LAMMPS
    assert impact_deck(WALLS, engine=LiggghtsDialect(), target="wall", dt=1e-9, gap=0.05,
                       thermo_every=3) == IMPACT_LIGGGHTS_WALL


def test_dialect_by_name_or_object():
    assert isinstance(dialect("liggghts"), LiggghtsDialect)
    d = dialect("lammps", cohesion_model="jkr", reference_radius=2e-5)
    assert (d.cohesion_model, d.reference_radius) == ("jkr", 2e-5)
    assert dialect(d) is d
    assert dialect("liggghts", cohesion_model="dmt") == LiggghtsDialect()  # not its option
    with pytest.raises(ConfigError, match="'liggghts' or 'lammps'"):
        dialect("embedded")
    assert issubclass(LammpsDialect, Dialect) and issubclass(LiggghtsDialect, Dialect)


def test_bed_deck_key_lines(bed):
    lig = bed_deck(bed, WALLS, engine="liggghts", steps=10, dt=1e-7, write_data="out.data",
                   contacts="c.dump")
    assert lines(lig, "pair_style") == [
        "pair_style gran model hertz tangential history cohesion sjkr rolling_friction epsd2"]
    assert lines(lig, "fix wbottom") == [
        "fix wbottom all wall/gran model hertz tangential history cohesion sjkr rolling_friction "
        "epsd2 primitive type 2 zplane 0"]
    assert lines(lig, "fix m6") == [
        "fix m6 all property/global cohesionEnergyDensity peratomtypepair 2 0 10000 10000 0"]
    assert lig.endswith("run 10\nwrite_data out.data\n")
    assert lines(lig, "dump dloc") == ["dump dloc all local 10 c.dump "
                                       + " ".join(f"c_cpl[{i}]" for i in range(1, 15))]
    lmp = bed_deck(bed, seed_contact_model(rolling_friction=0.0), engine="lammps", steps=10, dt=1e-7,
                   write_data="out.data", fabric=True)
    assert lines(lmp, "fix wbottom") == [
        "fix wbottom all wall/gran granular hertz/material 10000000 0.1 0.3 damping "
        "coeff_restitution tangential mindlin NULL 1.0 0.4 zplane 0 NULL"]
    assert lines(lmp, "compute fab") == ["compute fab all fabric radius contact force/normal"]
    assert lmp.endswith("run 10\nwrite_data out.data nocoeff\n")


def test_repose_deck_key_lines(bed, tmp_path):
    g = ReposeGeometry(4e-4, 4e-4, 4e-4, periodic_width=False, ledge_fraction=0.6,
                       plate_speed=0.5, slide=4e-4, wall_thickness=5e-5)
    s = ReposeSchedule.from_times(1e-7, fill=1e-5, slide=8e-4, drain=1e-5, n_frames=3)
    lig = repose_deck(bed, seed_contact_model(youngs_modulus=1e6), engine="liggghts", geometry=g,
                      schedule=s, stl_folder=tmp_path)
    assert lines(lig, "soft_particles") == ["soft_particles yes"]
    assert lines(lig, "fix wmesh") == [
        "fix wmesh all wall/gran model hertz tangential history rolling_friction epsd2 mesh "
        "n_meshes 3 meshes plate sides ledge"]
    i = lig.splitlines().index("fix mvplate all move/mesh mesh plate linear -0.5 0 0")
    assert lig.splitlines()[i:i + 4] == ["fix mvplate all move/mesh mesh plate linear -0.5 0 0",
                                         f"run {s.slide_steps}", "unfix mvplate",
                                         f"run {s.drain_steps}"]
    lmp = repose_deck(bed, engine="lammps", geometry=g, schedule=s)
    assert [ln.split()[1] for ln in lines(lmp, "region")] == [
        "plate", "wxlo", "wxhi", "wylo", "wyhi", "ledge"]
    assert lines(lmp, "variable px") == [
        "variable px equal -5e-08*((step-100)*(step>100)-(step-8100)*(step>8100))"]
    assert "soft_particles yes" not in lmp and "move/mesh" not in lmp


@pytest.fixture
def repose_bed(tmp_path):
    """Spheres over x in [0, L] of a repose box reaching from -L - m to L + m (L = 4e-4)."""
    rng = np.random.default_rng(2)
    pos = rng.uniform(0, 4e-4, (30, 3))
    rad = rng.uniform(1e-5, 3e-5, 30)
    return write_sphere_data(tmp_path / "repose.data", pos, rad, box_lo=[-5e-4, 0, -1e-4],
                             box_hi=[5e-4, 4e-4, 8e-4], n_types=2)


_BALANCE = ["balance 1.0 shift x 20 1.02", "fix lbal all balance 1000 1.05 shift x 10 1.02"]


def _extra(one, many):
    """The lines of deck ``many`` that deck ``one`` lacks, and those it lacks of ``one``."""
    a, b = one.splitlines(), many.splitlines()
    return [ln for ln in b if ln not in a], [ln for ln in a if ln not in b]


def test_repose_decks_for_several_ranks_share_the_powder(repose_bed, tmp_path):
    g = ReposeGeometry(4e-4, 4e-4, 4e-4, ledge_fraction=0.6, plate_speed=0.5, slide=4e-4,
                       wall_thickness=5e-5)
    s = ReposeSchedule.from_times(1e-7, fill=1e-5, slide=8e-4, drain=1e-5, n_frames=3)
    kw = dict(geometry=g, schedule=s, stl_folder=tmp_path)
    for engine in ("lammps", "liggghts"):
        one = repose_deck(repose_bed, engine=engine, **kw)
        # one rank: the deck of before (x slabs, nothing balanced)
        assert repose_deck(repose_bed, engine=engine, np=1, **kw) == one
        assert lines(one, "processors") == ["processors * 1 1"]
        assert not lines(one, "balance") and not lines(one, "fix lbal") and "change_box" not in one
        two = repose_deck(repose_bed, engine=engine, np=2, **kw).splitlines()
        if engine == "lammps":
            # LAMMPS balances: static after the pair style (contact history first), then
            # dynamic through every run; nothing else changes
            assert _extra(one, "\n".join(two)) == (_BALANCE, [])
            i = two.index(_BALANCE[0])
            assert two[i - 2].startswith("timestep") and two[i - 1].startswith("fix gravi")
            assert two[i + 1] == _BALANCE[1] and two[i + 2].startswith("variable px")
            assert lines(repose_deck(repose_bed, engine=engine, np=3, **kw), "balance") == [
                _BALANCE[0]]
        else:
            # LIGGGHTS has no balance: the box, widened to be symmetric about the powder's
            # middle L/2 = 2e-4, is cut there; the deck is otherwise the same
            assert _extra(one, "\n".join(two)) == (
                ["change_box all x final -0.0005 0.0009 units box"], [])
            assert two[two.index("change_box all x final -0.0005 0.0009 units box") - 1
                       ].startswith("read_data")
            three = repose_deck(repose_bed, engine=engine, np=3, **kw)
            assert _extra(one, three) == (["processors 1 * 1"], ["processors * 1 1"])
            four = repose_deck(repose_bed, engine=engine, np=4, **kw)
            assert lines(four, "processors") == ["processors 2 * 1"]
            assert lines(four, "change_box") == lines("\n".join(two), "change_box")
    for bad in (0, 1.5, True):
        with pytest.raises(ValueError, match="MPI ranks"):
            repose_deck(repose_bed, engine="lammps", np=bad, **kw)


def test_spread_decks_for_several_ranks(bed, tmp_path):
    plan = _plan(BladeGeometry(x0=1e-4, z_bottom=0.0, speed=0.1, height=2e-4))
    lmp = spread_layers_deck(bed, engine="lammps", plan=plan)
    lmp2 = spread_layers_deck(bed, engine="lammps", plan=plan, np=2)
    assert not lines(lmp, "balance") and _extra(lmp, lmp2) == (_BALANCE, [])
    # the pile moves along x with the tool: LAMMPS moves the cuts with it; LIGGGHTS's box
    # already spans the platform and has no balancing: the same deck on any number of ranks
    lig = spread_layers_deck(bed, engine="liggghts", plan=plan, stl_folder=tmp_path)
    for n in (2, 3):
        assert spread_layers_deck(bed, engine="liggghts", plan=plan, stl_folder=tmp_path,
                                  np=n) == lig


def _plan(tool, n_layers=2):
    ids = tuple((1 + 10 * k, 10 * (k + 1)) for k in range(n_layers))
    return SpreadLayersPlan(3e-3, 4e-4, (5e-5,) * n_layers, tool, ids,
                            tuple([0.0] + [1e-3 * k for k in range(1, n_layers)]), (2e-4, 8e-4),
                            1e-6, x_end=3.2e-3, n_frames=4, chamber_depth=2e-4,
                            landing_intervals=4, landing_margin=3e-5, pile_lift=1e-5,
                            clear=6e-5, wall_thickness=5e-5)


def test_spread_deck_same_sequence_on_both_engines(bed, tmp_path):
    roller = RollerGeometry(x0=1e-4, z_bottom=0.0, radius=8e-5, speed=0.1, omega=50.0)
    plan = _plan(roller)
    lig = spread_layers_deck(bed, engine="liggghts", plan=plan, stl_folder=tmp_path)
    lmp = spread_layers_deck(bed, engine="lammps", plan=plan)
    # the scenario's sequence is the engine's: the same runs, prints and displacements
    for prefix in ("run ", "print ", "displace_atoms", "variable off", "group ", "undump"):
        assert lines(lig, prefix) == lines(lmp, prefix), prefix
    # the same dumps (files and steps); their contact columns are the engine's
    assert ([ln.split()[:6] for ln in lines(lig, "dump ")]
            == [ln.split()[:6] for ln in lines(lmp, "dump ")])
    assert lines(lig, "fix rottool") == [
        "fix rottool all move/mesh mesh tool rotate origin 0.0001 0.0002 8e-05 axis 0 1 0 "
        "period 0.1256637061"] * 2   # one stroke per layer
    assert lines(lig, "fix tool ") == [
        f"fix tool all mesh/surface/stress file {(tmp_path / 'tool.stl').resolve()} type 2 "
        "curvature_tolerant yes"]
    assert lines(lmp, "region tool") == [
        "region tool cylinder y 0.0001 8e-05 8e-05 INF INF side out move v_bx NULL v_bz rotate "
        "v_th 0.0001 0.0002 8e-05 0 1 0 units box"]
    assert lines(lmp, "fix wtool") and lines(lmp, "fix wtool")[0].endswith("region tool contacts")
    assert lines(lig, "fix tload01") == [
        "fix tload01 all ave/time 1 1 1 f_tool[1] f_tool[2] f_tool[3] ave running"]
    assert lines(lmp, "variable tfx01") == ["variable tfx01 equal -f_tload01[1]"]


def test_refusals_name_what_the_engine_cannot_realise(bed):
    with pytest.raises(ConfigError, match="liggghts cannot realise `fabric`"):
        bed_deck(bed, engine="liggghts", steps=1, dt=1e-7, fabric=True)
    with pytest.raises(ConfigError, match="lammps cannot realise `fabric`.*DMT/JKR"):
        bed_deck(bed, seed_contact_model(cohesion=1e4), engine="lammps", steps=1,
                 dt=1e-7, fabric=True, cohesion_model="dmt")
    with pytest.raises(ValueError, match="LAMMPS has no SJKR"):
        bed_deck(bed, seed_contact_model(cohesion=1e4), engine="lammps", steps=1,
                 dt=1e-7)
    for name in ("liggghts", "lammps"):
        d = dialect(name)
        d.check_effects({"contact": {"capillary": False}, "spread": {"ramp_time": 0.0}},
                        spreading=True)
        with pytest.raises(ConfigError, match=f"engine '{name}'.*contact.ageing"):
            d.check_effects({"contact": {"ageing": True}})
        with pytest.raises(ConfigError, match="spread.ramp_time"):
            d.check_effects({"spread": {"ramp_time": 1e-3}}, spreading=True)
        d.check_effects({"spread": {"ramp_time": 1e-3}}, spreading=False)  # repose has no blade


def test_cohesion_options_per_engine():
    p = seed_contact_model(cohesion=1e4, wall_cohesion=2e4)
    assert dialect("liggghts").cohesion_options(p, "none") == (p, None)
    assert dialect("lammps").cohesion_options(p, "jkr") == (p, "jkr")
    dropped, cm = dialect("lammps").cohesion_options(p, "none")
    assert cm is None and dropped.tables().cohesion.max() == 0.0
    assert dropped == ContactModel(p.materials, **{**_fields(p), "cohesion": 0.0,
                                                   "wall_cohesion": 0.0})
    blade = BladeGeometry(x0=0.0, z_bottom=0.0, speed=0.1, bevel_deg=10.0)
    assert dialect("liggghts").approximations(tool=blade) == []
    assert "unbevelled" in dialect("lammps").approximations(tool=blade)[0]


#: The bridges' lines the retired rewriting of finished decks inserted after the last
#: property line, for LiquidBridges(0.072, 2e-3, contact_angle=0.3, fluid_viscosity=2e-3).
_BRIDGE_LINES = [
    "fix twc1 all property/global surfaceLiquidContentInitial scalar 0.002",
    "fix twc2 all property/global surfaceTension scalar 0.072",
    "fix twc3 all property/global fluidViscosity scalar 0.002",
    "fix twc4 all property/global contactAngle peratomtype 17.18873385 17.18873385",
    "fix twc5 all property/global minSeparationDistanceRatio scalar 1.01",
    "fix twc6 all property/global maxSeparationDistanceRatio scalar 1.1",
]


@pytest.mark.parametrize("params, pair", [
    (seed_contact_model(), "pair_style gran model hertz tangential history cohesion "
                           "easo/capillary/viscous rolling_friction epsd2"),
    (seed_contact_model(cohesion=1e4, rolling_friction=0.0),
     "pair_style gran model hertz tangential history cohesion easo/capillary/viscous")])
def test_liquid_bridges_are_a_liggghts_option(bed, tmp_path, params, pair):
    # the same deck as the rewriting of a finished deck made (literal lines), written directly
    bridges = LiquidBridges(0.072, 2e-3, contact_angle=0.3, fluid_viscosity=2e-3)
    g = ReposeGeometry(4e-4, 4e-4, 4e-4, slide=4e-4, plate_speed=0.5)
    s = ReposeSchedule.from_times(1e-7, fill=1e-5, slide=8e-4, drain=1e-5, n_frames=3)
    plain = repose_deck(bed, params, engine="liggghts", geometry=g, schedule=s,
                        stl_folder=tmp_path).splitlines()
    direct = repose_deck(bed, params, engine=LiggghtsDialect(liquid_bridges=bridges), geometry=g,
                         schedule=s, stl_folder=tmp_path)
    last = max(i for i, ln in enumerate(plain) if "property/global" in ln)
    want = plain[:last + 1] + _BRIDGE_LINES + plain[last + 1:]
    want = [pair if ln.startswith("pair_style") else ln for ln in want]
    got = direct.splitlines()
    assert got[0] == want[0] and got[1].startswith("# effect realised differently: liquid bridges")
    assert got[2:] == want[1:]
    assert "easo" not in " ".join(lines(direct, "fix wmesh"))   # the walls keep their model


def _capillary_effects(**kw):
    return {"contact": {"capillary": True, "capillary_surface_tension": 0.072,
                        "capillary_contact_angle": 0.045, "capillary_film_thickness": 2e-8, **kw}}


def test_liggghts_realises_the_capillary_effect_from_the_film():
    d = dialect("liggghts").with_effects(_capillary_effects(), reference_radius=30e-6)
    b = d.liquid_bridges
    # a film t on a sphere of radius r: 4 pi r^2 t of liquid, the fraction 3 t / r
    assert b.liquid_volume_fraction == pytest.approx(3 * 2e-8 / 30e-6, rel=1e-12)
    # LIGGGHTS 3.8 applies theta_i theta_j / 2: each type gets sqrt(2 theta)
    assert 0.5 * b.contact_angle ** 2 == pytest.approx(0.045, rel=1e-12)
    assert b.surface_tension == 0.072
    assert dialect("liggghts").with_effects({"contact": {"capillary": False}}).liquid_bridges is None
    with pytest.raises(ValueError, match="reference_radius"):
        dialect("liggghts").with_effects(_capillary_effects())
    with pytest.raises(ValueError, match="film_thickness"):
        dialect("liggghts").with_effects(_capillary_effects(capillary_film_thickness=0.0),
                                         reference_radius=30e-6)
    assert "replace the particles' SJKR" in d.approximations()[0]


def test_liggghts_refuses_bridges_below_its_easo_volume_cut_off():
    """LIGGGHTS 3.8's easo model skips a bridge with 1000 V < 1e-14 (m^3): no force at all,
    the SJKR cohesion gone; such a film is refused, with the thinnest film it acts on."""
    r = 26e-6
    v_p = 4 / 3 * math.pi * r ** 3
    t_min = 1e-17 / ((1 - math.sqrt(0.75)) * v_p) * r / 3   # the film at the cut-off
    dialect("liggghts").with_effects(_capillary_effects(capillary_film_thickness=1.01 * t_min),
                                     reference_radius=r)
    with pytest.raises(ConfigError, match=r"cannot realise these liquid bridges.*1e-17 m\^3.*"
                                          r"at least 8\.\d+e-09 m.*--engine embedded"):
        dialect("liggghts").with_effects(_capillary_effects(capillary_film_thickness=0.99 * t_min),
                                         reference_radius=r)
    # the check of a configuration (what engine_realises asks) reads the PSD's median radius
    cfg = {**_capillary_effects(capillary_film_thickness=1.5e-14),
           "psd": {"d50": 2 * r, "scale": 1.0}}
    with pytest.raises(ConfigError, match="cannot realise these liquid bridges"):
        dialect("liggghts").check_effects(cfg)
    dialect("liggghts").check_effects({**cfg, "contact": _capillary_effects()["contact"]})


def test_effects_an_engine_cannot_realise_are_refused_by_name():
    with pytest.raises(ConfigError, match=r"engine 'lammps' cannot realise the effect "
                                          r"'capillary_bridges' \(contact.capillary\).*"
                                          r"--engine liggghts"):
        dialect("lammps").with_effects(_capillary_effects(), reference_radius=30e-6)
    for eng in ("liggghts", "lammps"):
        with pytest.raises(ConfigError, match=f"'{eng}' cannot realise the effect "
                                              "'contact_ageing'.*--engine embedded"):
            dialect(eng).check_effects({"contact": {"ageing": True}})
        # the tool's start-up exists only where there is a tool
        dialect(eng).check_effects({"spread": {"ramp_time": 0.1}})
        with pytest.raises(ConfigError, match="'blade_startup' \\(spread.ramp_time, "
                                              "spread.vibration_amplitude\\)"):
            dialect(eng).check_effects({"spread": {"vibration_amplitude": 2e-6}}, spreading=True)
        # ordinary contact parameters and inputs are realised
        dialect(eng).check_effects({"contact": {"wall_friction": 0.3, "rolling_friction": 0.15,
                                                "rolling_model": "epsd2"},
                                    "psd": {"fines_mass_fraction": 0.05}}, spreading=True)
    # EPSD: LAMMPS has no rolling dashpot; LIGGGHTS' stiffness prefactor is fixed
    rolling = {"contact": {"rolling_friction": 0.15, "rolling_model": "epsd"}}
    with pytest.raises(ConfigError, match="'lammps' cannot realise contact.rolling_model = "
                                          "'epsd'.*'non_sphericity'.*epsd2"):
        dialect("lammps").check_effects(rolling)
    dialect("liggghts").check_effects(rolling)
    stiff = {"contact": {**rolling["contact"], "rolling_stiffness_factor": 3.0}}
    with pytest.raises(ConfigError, match="contact.rolling_stiffness_factor = 3.0.*2.25"):
        dialect("liggghts").check_effects(stiff)
    # without rolling friction the rolling model writes nothing
    dialect("lammps").check_effects({"contact": {"rolling_friction": 0.0, "rolling_model": "epsd"}})


def test_liggghts_epsd_writes_its_rolling_dashpot():
    p = seed_contact_model(rolling_model="epsd", rolling_friction=0.2, rolling_damping=0.3)
    model, _ = liggghts_model_commands(p, n_types=2)
    assert "fix m7 all property/global coefficientRollingViscousDamping peratomtypepair 2 "\
        "0.3 0.3 0.3 0.3" in model
    assert model[-2].endswith("rolling_friction epsd")
    # the EPSD2 and CDT models have no dashpot
    model2, _ = liggghts_model_commands(seed_contact_model(rolling_model="epsd2"), n_types=2)
    assert not any("ViscousDamping" in ln for ln in model2)


def test_the_realisation_tables_cover_every_engine_and_effect():
    table = effect_realisations()
    assert set(table) == set(EFFECT_KEYS)
    for effect, row in table.items():
        assert set(row) == {"embedded", "liggghts", "lammps"}
        assert row["embedded"].realised
        for eng, r in row.items():
            assert bool(r.how) != bool(r.refused), (effect, eng)   # one of the two, stated
            if not r.realised:
                assert "--engine" in r.refused, (effect, eng)     # names the alternative


def test_an_option_an_engine_lacks_is_refused_by_name(bed):
    bridges = LiquidBridges(0.072, 1e-3)
    with pytest.raises(ConfigError, match="lammps cannot realise `liquid_bridges`"):
        dialect("lammps", liquid_bridges=bridges)
    with pytest.raises(ConfigError, match="lammps cannot realise `liquid_bridges`"):
        dialect(LammpsDialect(), liquid_bridges=bridges)
    # a dialect object keeps its options where a writer's are left at None
    coh = seed_contact_model(cohesion=1e4)
    by_object = bed_deck(bed, coh, engine=LammpsDialect(cohesion_model="dmt"), steps=1, dt=1e-7)
    by_name = bed_deck(bed, coh, engine="lammps", cohesion_model="dmt", steps=1, dt=1e-7)
    assert by_object == by_name and "dmt" in lines(by_name, "pair_coeff")[0]


def test_a_contact_model_with_embedded_only_effects_is_refused_by_each_dialect(bed, tmp_path):
    wet = seed_contact_model(capillary=True, capillary_film_thickness=1e-7)
    with pytest.raises(ConfigError, match="engine 'lammps' cannot realise the ContactModel's "
                                          "`capillary` .*--engine liggghts"):
        bed_deck(bed, wet, engine="lammps", steps=1, dt=1e-7)
    # LIGGGHTS writes bridges as its own model, which the dialect must be given
    with pytest.raises(ConfigError, match="'liggghts'.*`capillary`.*LiquidBridges"):
        bed_deck(bed, wet, engine="liggghts", steps=1, dt=1e-7)
    bridges = LiggghtsDialect(liquid_bridges=LiquidBridges(0.072, 1e-3))
    assert "easo/capillary/viscous" in lines(bed_deck(bed, wet, engine=bridges, steps=1,
                                                      dt=1e-7), "pair_style")[0]
    aged = seed_contact_model(contact_ageing=True, ageing_bond_ratio=0.5)
    for name in ("liggghts", "lammps"):
        with pytest.raises(ConfigError, match=f"'{name}'.*`contact_ageing`.*--engine embedded"):
            bed_deck(bed, aged, engine=name, steps=1, dt=1e-7)


def test_the_decks_take_one_particle_type_and_what_they_write(bed):
    two = ContactModel((Material(1e7, 0.3), Material(2e7, 0.3)), restitution=0.1)
    for name in ("liggghts", "lammps"):
        with pytest.raises(ConfigError, match=f"{name} decks take one particle type; the "
                                              "ContactModel has 2"):
            bed_deck(bed, two, engine=name, steps=1, dt=1e-7)
        with pytest.raises(ConfigError, match="`tangential_damping`"):
            bed_deck(bed, seed_contact_model(tangential_damping=False), engine=name, steps=1,
                     dt=1e-7)
        with pytest.raises(ConfigError, match="`limit_force`"):
            impact_deck(seed_contact_model(limit_force=True), engine=name)
        with pytest.raises(ConfigError, match="`restitution` and `wall_restitution` > 0"):
            impact_deck(seed_contact_model(wall_restitution=0.0), engine=name, target="wall")
        with pytest.raises(TypeError, match="must be a bedstruct.dem ContactModel"):
            bed_deck(bed, {"restitution": 0.5}, engine=name, steps=1, dt=1e-7)
        with pytest.raises(ValueError, match="`gravity` must be a magnitude >= 0"):
            bed_deck(bed, engine=name, steps=1, dt=1e-7, gravity=-9.81)
    # per-type-pair tables of one type are one value each
    tab = ContactModel(Material(1e7, 0.3, 8300.0), restitution=[[0.1]], friction=np.array([[0.4]]),
                       rolling_friction=0.05)
    assert bed_deck(bed, tab, engine="lammps", steps=1, dt=1e-7) == \
        bed_deck(bed, engine="lammps", steps=1, dt=1e-7)


def test_the_rolling_model_is_an_option_of_the_contact_model():
    from dataclasses import replace

    from bedstruct.engines import lammps_granular_coeffs, liggghts_model_commands

    model = seed_contact_model(rolling_model="epsd")
    lines_, _ = liggghts_model_commands(replace(model, rolling_model="cdt"))
    assert "pair_style gran model hertz tangential history rolling_friction cdt" in lines_
    assert any(line.startswith("fix m5 all property/global coefficientRollingFriction")
               for line in lines_)
    # "none" writes no rolling friction, whatever its coefficient
    assert liggghts_model_commands(replace(model, rolling_model="none"))[0][-2] == \
        "pair_style gran model hertz tangential history"
    # epsd2 is the seed's, and LAMMPS states no other model
    assert "rolling_friction epsd2" in liggghts_model_commands(seed_contact_model())[0][-2]
    assert "rolling sds" in lammps_granular_coeffs(seed_contact_model())
    with pytest.raises(ConfigError, match="epsd2 only.*'cdt'"):
        lammps_granular_coeffs(replace(model, rolling_model="cdt"))
    # LIGGGHTS' EPSD stiffness is its own: another factor is refused, not ignored
    with pytest.raises(ConfigError, match="`rolling_stiffness_factor` = 3.0.*2.25"):
        dialect("liggghts").deck_model(replace(model, rolling_stiffness_factor=3.0))
    dialect("liggghts").deck_model(replace(model, rolling_stiffness_factor=3.0,
                                           rolling_friction=0.0))


def test_the_docs_table_states_what_each_engine_realises():
    """docs/diagnose.md, "How each engine realises an effect": one row per effect, each cell
    starting with what the engine's table says (realised, or refused)."""
    from pathlib import Path
    text = (Path(__file__).resolve().parents[2] / "docs" / "diagnose.md").read_text()
    section = text.split("### How each engine realises an effect", 1)[1].split("\n## ", 1)[0]
    rows = [ln for ln in section.splitlines() if ln.startswith("| `")]
    table = effect_realisations()
    assert len(rows) == len(table)
    for ln in rows:
        cells = [c.strip() for c in ln.strip("|").split("|")]
        effect = cells[0].strip("`")
        for eng, cell in zip(("embedded", "liggghts", "lammps"), cells[1:]):
            assert cell.startswith("realised") == table[effect][eng].realised, (effect, eng, cell)
