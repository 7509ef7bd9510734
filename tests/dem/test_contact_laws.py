"""Analytic checks of the contact laws (Hertz, restitution, friction, rolling, SJKR)."""

import math

import numpy as np
import pytest

from bedstruct import Box
from bedstruct.core import lens_radius
from bedstruct.dem import ContactModel, Material, Plane, Simulation, hertz_time
from bedstruct.dem import _kernels as K
from dem_helpers import closed_box, two_sphere_sim

E, NU, RHO, R = 1e7, 0.3, 2500.0, 1e-4


def _impact(e, v0, dt):
    model = ContactModel(Material(E, NU, RHO), restitution=e, friction=0.0)
    sim = two_sphere_sim(model, R=R, v0=v0, dt=dt)
    touching = []
    sim.run(time=3e-4, callback=lambda s: touching.append(s.n_pairs and
                                                            abs(s.x[1, 0] - s.x[0, 0]) < 2 * R))
    vrel = abs(sim.v[1, 0] - sim.v[0, 0])
    return sum(touching) * sim.dt, vrel / (2 * v0)


def test_hertz_impact_duration_and_restitution():
    v0 = 0.5
    m = 4 / 3 * math.pi * R ** 3 * RHO
    estar = E / (2 * (1 - NU ** 2))
    t_analytic = 2.868 * ((m / 2) ** 2 / (R / 2 * estar ** 2 * 2 * v0)) ** 0.2
    assert t_analytic == pytest.approx(hertz_time(R, Material(E, NU, RHO), 2 * v0), rel=1e-12)
    dt = t_analytic / 100
    tc, e_el = _impact(1.0, v0, dt)
    assert tc == pytest.approx(t_analytic, rel=0.01)
    assert e_el == pytest.approx(1.0, abs=1e-3)
    for e in (0.3, 0.7):
        _, e_meas = _impact(e, v0, dt)
        assert e_meas == pytest.approx(e, rel=0.01)


def test_sphere_wall_restitution_and_duration():
    e, v0 = 0.6, 0.3
    model = ContactModel(Material(E, NU, RHO), restitution=e, friction=0.0)
    m = 4 / 3 * math.pi * R ** 3 * RHO
    ystar = 1 / (2 * (1 - NU ** 2) / E)
    t_h = 2.868 * (m ** 2 / (R * ystar ** 2 * v0)) ** 0.2
    sim = Simulation(closed_box(), model, walls=[Plane((0, 0, 0), (0, 0, 1), name="floor")],
                     gravity=(0, 0, 0), dt=t_h / 100, n_threads=1, v_max=v0)
    sim.add_particles([[1e-3, 1e-3, 1.01 * R]], [R], velocities=[[0, 0, -v0]])
    sim.run(time=2e-4)
    assert sim.v[0, 2] / v0 == pytest.approx(e, rel=0.01)
    assert abs(sim.v[0, 0]) < 1e-12


def test_energy_conserved_without_damping():
    rng = np.random.default_rng(3)
    model = ContactModel(Material(E, NU, RHO), restitution=1.0, friction=0.0)
    box = Box([0, 0, 0], [2e-3, 2e-3, 2e-3], boundary="pp pp pp")
    sim = Simulation(box, model, gravity=(0, 0, 0), n_threads=2, v_max=1.0)
    sim.insert_raindrop(150, R * (0.8 + 0.4 * rng.random(150)), types=1)
    sim.v[:] = rng.normal(0, 0.3, sim.v.shape)
    ystar = 1 / (2 * (1 - NU ** 2) / E)

    def energy(s):
        c = s.contacts()
        reff = c.radii_i * c.radii_j / (c.radii_i + c.radii_j)
        pe = np.sum(8 / 15 * ystar * np.sqrt(reff) * np.clip(c.overlap, 0, None) ** 2.5)
        return s.kinetic_energy() + pe

    e0 = energy(sim)
    rec = []
    sim.run(2000, callback=lambda s: rec.append(energy(s)) if s.step % 20 == 0 else None)
    drift = np.abs(np.array(rec) / e0 - 1).max()
    assert drift < 1e-3


@pytest.mark.parametrize("mu,stick", [(0.30, True), (0.20, False)])
def test_incline_stick_slide(mu, stick):
    """A non-rotating sphere on an incline of tan(theta) = 0.25 sticks iff mu > tan(theta)."""
    theta = math.atan(0.25)
    g = 9.81
    model = ContactModel(Material(E, NU, RHO), restitution=0.2, friction=mu)
    sim = Simulation(Box([0, 0, 0], [4e-3, 2e-3, 2e-3], boundary="ff ff ff"), model,
                     walls=[Plane((0, 0, 0), (0, 0, 1), name="incline")],
                     gravity=(g * math.sin(theta), 0, -g * math.cos(theta)), n_threads=1)
    sim.add_particles([[1e-3, 1e-3, R * 0.999]], [R])
    sim.inv_i[:] = 0.0  # freeze rotation: a block-like slider
    sim.run(time=2e-3)
    x0, v0, t0 = sim.x[0, 0], sim.v[0, 0], sim.time
    sim.run(time=4e-3)
    dx = sim.x[0, 0] - x0
    if stick:
        assert abs(dx) < 1e-3 * R
    else:
        a = g * (math.sin(theta) - mu * math.cos(theta))
        T = sim.time - t0
        assert dx == pytest.approx(v0 * T + 0.5 * a * T * T, rel=0.02)


def test_rolling_vs_slipping_threshold():
    """A free sphere rolls without slip on an incline iff mu >= (2/7) tan(theta)."""
    theta = math.atan(0.7)  # (2/7) tan = 0.2
    g = 9.81
    res = {}
    for mu in (0.25, 0.15):
        model = ContactModel(Material(E, NU, RHO), restitution=0.2, friction=mu)
        sim = Simulation(Box([0, 0, 0], [1e-2, 2e-3, 2e-3], boundary="ff ff ff"), model,
                         walls=[Plane((0, 0, 0), (0, 0, 1))],
                         gravity=(g * math.sin(theta), 0, -g * math.cos(theta)), n_threads=1)
        sim.add_particles([[1e-3, 1e-3, R * 0.999]], [R])
        sim.run(time=3e-3)
        res[mu] = (sim.v[0, 0], sim.om[0, 1] * R)
    v, wr = res[0.25]
    assert wr == pytest.approx(v, rel=0.01)  # rolling: v = omega R
    v, wr = res[0.15]
    assert wr < 0.9 * v  # slipping


@pytest.mark.parametrize("rolling_model", ["epsd2", "cdt"])
def test_rolling_resistance_deceleration(rolling_model):
    """A sphere rolling on a plane decelerates at (5/7) mu_r g."""
    g, mur = 9.81, 0.1
    model = ContactModel(Material(E, NU, RHO), restitution=0.2, friction=0.8, rolling_friction=mur,
                         rolling_model=rolling_model)
    sim = Simulation(Box([0, 0, 0], [2e-2, 2e-3, 2e-3], boundary="ff ff ff"), model,
                     walls=[Plane((0, 0, 0), (0, 0, 1))], gravity=(0, 0, -g), n_threads=1)
    sim.add_particles([[1e-3, 1e-3, R * 0.999]], [R])
    sim.run(time=1e-3)  # settle vertically
    sim.v[0, 0] = 0.02
    sim.om[0, 1] = 0.02 / R
    sim.run(time=2e-3)
    v1, t1 = sim.v[0, 0], sim.time
    sim.run(time=4e-3)
    a = (sim.v[0, 0] - v1) / (sim.time - t1)
    assert a == pytest.approx(-5 / 7 * mur * g, rel=0.03)


def test_sjkr_pulloff_equals_k_times_lens_area():
    k = 5e4
    delta = 0.02 * R
    forces = {}
    for coh in (0.0, k):
        model = ContactModel(Material(E, NU, RHO), restitution=0.5, friction=0.5, cohesion=coh)
        sim = Simulation(closed_box(), model, gravity=(0, 0, 0), n_threads=1)
        c = 1e-3
        sim.add_particles([[c - R + delta / 2, c, c], [c + R * 0.7 - delta / 2, c, c]], [R, 0.7 * R])
        con = sim.contacts()
        assert con.n_contacts == 1
        forces[coh] = con.force_normal[0, 0]  # force on i (left sphere) along x
    a = float(lens_radius(R, 0.7 * R, 1.7 * R - delta))
    # cohesion pulls i towards j (+x): the difference is k * pi a^2
    assert forces[k] - forces[0.0] == pytest.approx(k * math.pi * a * a, rel=1e-9)
    # wall version: A = pi (R^2 - d^2)
    model = ContactModel(Material(E, NU, RHO), restitution=0.5, friction=0.5, cohesion=k)
    sim = Simulation(closed_box(), model, walls=[Plane((0, 0, 0), (0, 0, 1))], gravity=(0, 0, 0),
                     n_threads=1)
    d = R - delta
    sim.add_particles([[1e-3, 1e-3, d]], [R])
    sim._setup()
    fz = sim.f[0, 2]
    kn_delta = 4 / 3 * (1 / (2 * (1 - NU ** 2) / E)) * math.sqrt(R * delta) * delta
    assert fz == pytest.approx(kn_delta - k * math.pi * (R * R - d * d), rel=1e-9)


def test_contact_law_helpers_pure_python():
    kn, kt, gn, gt = K.hertz_coefficients.py_func(1e-6, 1e-4, 1e-9, 5e6, 2e6, -0.2)
    assert kn == pytest.approx(4 / 3 * 5e6 * math.sqrt(1e-10))
    assert kt == pytest.approx(8 * 2e6 * math.sqrt(1e-10))
    # Coulomb cap: a large displacement gives |Ft| = mu |Fn|
    s1, s2, s3, f1, f2, f3 = K.tangential_history.py_func(1.0, 0, 0, 0, 0, 0, 0, 0, 1, 10.0, 0.0,
                                                          0.5, 2.0, 1e-6)
    assert math.hypot(f1, f2) == pytest.approx(1.0)
    assert s1 == pytest.approx(0.1)
    # history is projected into the tangent plane
    s1, s2, s3, *_ = K.tangential_history.py_func(0.0, 0, 1e-9, 0, 0, 0, 0, 0, 1, 10.0, 0.0, 0.5,
                                                  2.0, 1e-6)
    assert s3 == 0.0


def test_pair_damping_equals_hertz_coefficients_damping():
    # the pair kernel's damping from the per-type-pair table equals the direct formula
    # the wall contact uses (to round-off), with and without tangential damping
    from bedstruct.dem import ContactModel, Material
    for tdamp in (True, False):
        model = ContactModel(Material(E, NU, RHO), restitution=0.4, tangential_damping=tdamp)
        t = model.tables()
        tab = K.pair_table(t.youngs, t.shear, t.beta, t.friction, t.rolling_friction,
                           t.cohesion, tdamp)
        delta, reff, meff = 2e-7, 5e-5, 3e-9
        kn, kt, gn, gt = K.hertz_coefficients.py_func(delta, reff, meff, t.youngs[0, 0],
                                                      t.shear[0, 0], t.beta[0, 0])
        sq = math.sqrt(reff * delta)
        assert K.hertz_stiffness.py_func(sq, t.youngs[0, 0], t.shear[0, 0]) == (
            pytest.approx(kn, rel=1e-15), pytest.approx(kt, rel=1e-15))
        gn2, gt2 = K.pair_damping.py_func(sq, meff, tab[2, 0, 0], tab[3, 0, 0])
        assert gn2 == pytest.approx(gn, rel=1e-14)
        assert gt2 == (pytest.approx(gt, rel=1e-14) if tdamp else 0.0)


def test_normal_force_and_shear_torques_pure_python():
    assert K.normal_force.py_func(10.0, 1e-3, 2.0, 0.1, False) == pytest.approx(-0.19)
    assert K.normal_force.py_func(10.0, 1e-3, 2.0, 0.1, True) == 0.0
    # Ft along x on a contact normal along z: torque -r (z x x) = -r y on both spheres
    t = K.shear_torques.py_func(0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 2.0, 3.0)
    assert t == (-0.0, -2.0, -0.0, -0.0, -3.0, -0.0)
