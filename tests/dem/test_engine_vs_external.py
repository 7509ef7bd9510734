"""Independent engines: one bed settled by bedstruct, LIGGGHTS and LAMMPS.

The same initial state (300 polydisperse spheres, radii 15-30 um, on a loose
lattice in a 0.4 x 0.4 mm periodic box over a plate, written as a LAMMPS data
file) settles under gravity in each engine with identical parameters (the
seed's soft model: E = 1e7 Pa, e = 0.1, mu = 0.4, mu_r = 0.05 epsd2) and time
step. The driver is ``benchmarks/compare_engines.py``.

Trajectories of a granular bed are chaotic, so the engines are compared through
statistics with tolerances set from the spread of replicates (initial
velocities perturbed by +-1e-4 m/s; 3 replicates on each engine and model, measured
twice with ``python benchmarks/compare_engines.py --quick``, see docs/validation.md).
One run is compared with one run, so the tolerance must cover the difference of two
draws (about 1.4x the spread of one):

=====================  ======================  ==========================
statistic              replicate range (max)   tolerance here
=====================  ======================  ==========================
mean coordination      0.13                    0.3
packing (window)       0.025                   0.04
t(KE < 1e-2 peak)      1.7 ms of 14 ms (12 %)  25 %
=====================  ======================  ==========================

Before the first contacts dominate (free fall up to the kinetic-energy peak)
the runs are deterministic and must agree closely: bedstruct and LIGGGHTS
implement the same laws, LAMMPS differs by its constant rolling stiffness.
"""

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from bedstruct.engines import find_lammps, find_liggghts

_SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "compare_engines.py"
_spec = importlib.util.spec_from_file_location("bedstruct_compare_engines", _SCRIPT)
ce = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = ce
_spec.loader.exec_module(ce)

N_PARTICLES, WIDTH = 300, 0.4e-3
STEPS, EVERY = 62000, 200          # 22 ms at dt = 3.5e-7 s: KE < 1e-2 of its peak after ~15 ms
TOL_CN, TOL_PHI, TOL_T = 0.3, 0.04, 0.25
COHESION = ce.COHESION             # 3e4 J/m^3 at E = 1e7 Pa

need_liggghts = pytest.mark.skipif(find_liggghts() is None,
                                   reason="LIGGGHTS not installed (.ci/install-engines.sh)")
need_lammps = pytest.mark.skipif(find_lammps() is None,
                                 reason="LAMMPS not installed (.ci/install-engines.sh)")

_cache = {}


def _run(engine, cohesion, tmp_path_factory):
    key = (engine, cohesion)
    if key not in _cache:
        case = ce.make_case(N_PARTICLES, width=WIDTH)
        p = ce.params(cohesion)
        dt = ce.time_step(p)
        if engine == "bedstruct":
            res = ce.run_bedstruct(case, p, dt=dt, steps=STEPS, every=EVERY)
        else:
            wd = tmp_path_factory.mktemp(f"{engine}_k{cohesion:g}")
            res = ce.run_external(engine, case, p, dt=dt, steps=STEPS, every=EVERY, workdir=wd)
        _cache[key] = (res, ce.statistics(res, case))
    return _cache[key]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    return lambda engine, cohesion=0.0: _run(engine, cohesion, tmp_path_factory)


def _compare(a, b, *, tol_cn=TOL_CN, tol_phi=TOL_PHI, tol_t=TOL_T):
    sa, sb = a[1], b[1]
    assert math.isfinite(sa["t_1e2"]) and math.isfinite(sb["t_1e2"]), (sa, sb)
    assert abs(sa["cn"] - sb["cn"]) <= tol_cn, (sa["cn"], sb["cn"])
    assert abs(sa["packing"] - sb["packing"]) <= tol_phi, (sa["packing"], sb["packing"])
    assert abs(sa["t_1e2"] - sb["t_1e2"]) <= tol_t * sb["t_1e2"], (sa["t_1e2"], sb["t_1e2"])
    # the whole decay curve, in log space: median distance in decades
    assert ce.log_curve_distance(a[0], b[0]) < 0.15


def test_bed_settles_in_every_run(runs):
    res, s = runs("bedstruct")
    assert s["n"] == N_PARTICLES
    assert s["ke_end"] < 1e-2 * s["peak"] and s["t_1e2"] < 0.8 * STEPS * ce.time_step(ce.params())
    assert 3.5 < s["cn"] < 5.0 and 0.5 < s["packing"] < 0.6   # a loose random packing


@need_liggghts
def test_free_fall_and_first_impacts_identical_to_liggghts(runs):
    a, b = runs("bedstruct")[0], runs("liggghts")[0]
    n = int(np.argmax(b.ke)) + 1           # up to the kinetic-energy peak
    np.testing.assert_allclose(a.ke[1:n], b.ke[1:n], rtol=0.02)
    assert abs(a.t_peak - b.t_peak) <= EVERY * ce.time_step(ce.params())


@need_liggghts
def test_settling_statistics_match_liggghts_without_cohesion(runs):
    _compare(runs("bedstruct"), runs("liggghts"))


@need_lammps
def test_settling_statistics_match_lammps_without_cohesion(runs):
    a, b = runs("bedstruct"), runs("lammps")
    n = int(np.argmax(b[0].ke)) + 1
    # LAMMPS' SDS rolling stiffness is frozen at a reference contact: a few % differences
    np.testing.assert_allclose(a[0].ke[1:n // 2], b[0].ke[1:n // 2], rtol=0.05)
    _compare(a, b)


@need_liggghts
@pytest.mark.xfail(strict=True, reason=(
    "bedstruct implements LIGGGHTS' default (`tangential_reduce off`: SJKR is not in the Coulomb "
    "and rolling limits); with `tangential_reduce on` LIGGGHTS settles to a denser cohesive bed, "
    "so the two must differ — this guards against the limits silently including cohesion again"))
def test_cohesive_settling_differs_from_liggghts_with_tangential_reduce(runs):
    _compare(runs("bedstruct", COHESION), runs("liggghts_tr", COHESION))


@need_liggghts
def test_cohesive_settling_matches_liggghts_default(runs):
    _compare(runs("bedstruct", COHESION), runs("liggghts", COHESION))


@need_liggghts
def test_liggghts_replicate_spread_is_within_tolerance(runs, tmp_path_factory):
    # the tolerances are meaningful only if one engine reproduces itself within them
    case = ce.make_case(N_PARTICLES, width=WIDTH, perturbation=1e-4, perturb_seed=1)
    p = ce.params(0.0)
    res = ce.run_external("liggghts", case, p, dt=ce.time_step(p), steps=STEPS, every=EVERY,
                          workdir=tmp_path_factory.mktemp("liggghts_rep1"))
    _compare((res, ce.statistics(res, case)), runs("liggghts"))


def _tilted_sphere(engine, cohesion, tmp_path):
    """x displacement (m) of one sphere resting on the plate, gravity tilted 30 deg, after 6 ms."""
    from bedstruct import Box
    from bedstruct.dem import Plane, Simulation
    from bedstruct.engines import bed_deck, run_deck, write_sphere_data
    from bedstruct.io import read_data
    R, th, g, dt, steps = 25e-6, math.radians(30), 9.81, 3e-7, 20000
    p = ce.params(cohesion)
    pos, lo, hi = [[2e-4, 2e-4, R - 2e-8]], [0, 0, 0], [4e-4, 4e-4, 4e-4]
    if engine == "bedstruct":
        sim = Simulation(Box(lo, hi, boundary="pp pp ff"), p,
                         walls=[Plane((0, 0, 0), (0, 0, 1))], dt=dt, n_threads=1,
                         gravity=(g * math.sin(th), 0, -g * math.cos(th)))
        sim.add_particles(pos, [R])
        sim.run(steps)
        return sim.frame().positions[0, 0] - pos[0][0]
    data = write_sphere_data(tmp_path / "one.data", pos, [R], box_lo=lo, box_hi=hi, n_types=2)
    deck = bed_deck(data, p, engine=engine, steps=steps, dt=dt, thermo_every=steps,
                    write_data="end.data").replace(
        "vector 0.0 0.0 -1.0", f"vector {math.sin(th):.9f} 0.0 {-math.cos(th):.9f}")
    (tmp_path / "one.in").write_text(deck)
    run_deck(tmp_path / "one.in", cwd=tmp_path)
    return read_data(tmp_path / "end.data").positions[0, 0] - pos[0][0]


@need_liggghts
def test_sphere_rolling_down_tilted_gravity_matches_liggghts_without_cohesion(tmp_path):
    # epsd2 caps the torque at mu_r R |F_n| < the gravity torque: it rolls ~58 um in 6 ms
    a = _tilted_sphere("bedstruct", 0.0, tmp_path)
    b = _tilted_sphere("liggghts", 0.0, tmp_path)
    assert b > 1e-5
    assert a == pytest.approx(b, rel=1e-3)


@need_liggghts
@pytest.mark.parametrize("cohesion, held", [(3e4, True), (1e4, False)])
def test_cohesive_sphere_on_tilted_plate_matches_liggghts(tmp_path, cohesion, held):
    # cohesion resists rolling: at 3e4 J/m^3 the sphere is held (it moves only the tangential
    # spring's ~1 nm), at 1e4 it still rolls, less far than the ~58 um without cohesion
    a = _tilted_sphere("bedstruct", cohesion, tmp_path)
    b = _tilted_sphere("liggghts", cohesion, tmp_path)
    if held:
        assert 0 < b < 1e-8
        assert a == pytest.approx(b, rel=1e-3)
    else:
        assert 2e-5 < b < 5.5e-5
        assert a == pytest.approx(b, rel=1e-5)


def _sliding_sphere(engine, tmp_path, steps=200):
    """(vx, omega_y) of a sphere launched at 0.05 m/s without spin along the plate, after ``steps``."""
    from bedstruct import Box
    from bedstruct.dem import Plane, Simulation
    from bedstruct.engines import bed_deck, run_deck, write_sphere_data
    from bedstruct.io import read_data
    R, dt = 25e-6, 3e-7
    p = ce.params(0.0)
    pos, lo, hi, vel = [[2e-4, 2e-4, R - 3e-9]], [0, 0, 0], [4e-4, 4e-4, 4e-4], [[0.05, 0, 0]]
    if engine == "bedstruct":
        sim = Simulation(Box(lo, hi, boundary="pp pp ff"), p,
                         walls=[Plane((0, 0, 0), (0, 0, 1))], dt=dt, n_threads=1)
        sim.add_particles(pos, [R], velocities=vel)
        sim.run(steps)
        f = sim.frame()
    else:
        data = write_sphere_data(tmp_path / f"s_{engine}.data", pos, [R], box_lo=lo, box_hi=hi,
                                 n_types=2, velocities=vel)
        deck = bed_deck(data, p, engine=engine, steps=steps, dt=dt, thermo_every=steps,
                        write_data=f"s_{engine}_end.data")
        (tmp_path / f"s_{engine}.in").write_text(deck)
        run_deck(tmp_path / f"s_{engine}.in", cwd=tmp_path)
        f = read_data(tmp_path / f"s_{engine}_end.data")
    return f.velocities[0, 0], f.omegas[0, 1]


@need_liggghts
@need_lammps
def test_sliding_sphere_explains_the_lammps_difference(tmp_path):
    # The deterministic difference between LAMMPS and LIGGGHTS with friction: LIGGGHTS
    # (tangential_model_history.h) compares only the spring k_t xi with mu |F_n| and adds the
    # dashpot -gamma_t v_t below the cap, so the total can exceed mu |F_n|; bedstruct does the
    # same (bitwise equal here). LAMMPS' mindlin caps spring + dashpot together. Here it shows
    # at the run's first force evaluation (history not yet advanced, xi = 0: the dashpot at
    # 0.05 m/s, ~1000 mu m g, acts for half a step); LAMMPS decelerates at exactly mu g.
    t = 200 * 3e-7
    v_b, w_b = _sliding_sphere("bedstruct", tmp_path)
    v_l, w_l = _sliding_sphere("liggghts", tmp_path)
    v_m, w_m = _sliding_sphere("lammps", tmp_path)
    assert v_b == pytest.approx(v_l, rel=1e-9) and w_b == pytest.approx(w_l, rel=1e-6)
    assert 0.05 - v_m == pytest.approx(0.4 * 9.81 * t, rel=0.01)       # Coulomb: mu g t
    assert 0.05 - v_l > 3 * (0.05 - v_m)                                # LIGGGHTS: 3.3x more
