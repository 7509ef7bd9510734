"""Diagnosis extensions of the engine: capillary bridges, contact ageing, rolling stiffness,
programmed wall motion (docs/engine.md, "Extensions for the diagnosis")."""

import math

import numpy as np
import pytest

from bedstruct import Box
from bedstruct.dem import ContactModel, Material, Plane, Simulation
from bedstruct.dem import _kernels as K
from bedstruct.errors import ConfigError
from dem_helpers import closed_box

E, NU, RHO, R = 1e7, 0.3, 2500.0, 1e-4
GAMMA, THETA = 0.072, math.radians(20.0)


def _pair(model, r1, r2, gap, *, skin=None, v=(0.0, 0.0)):
    """Two spheres on the x axis, surface gap ``gap`` (negative: overlap), no gravity."""
    sim = Simulation(closed_box(), model, gravity=(0, 0, 0), n_threads=1, skin=skin, v_max=0.1)
    c = 1e-3
    sim.add_particles([[c - r1 - 0.5 * gap, c, c], [c + r2 + 0.5 * gap, c, c]], [r1, r2],
                      velocities=[[v[0], 0, 0], [v[1], 0, 0]])
    return sim


def _willett(gap, r1, r2, vol, gamma=GAMMA, theta=THETA):
    """Independent evaluation: Willett et al. (2000) with R = 2 r1 r2 / (r1 + r2)."""
    rh = 2 * r1 * r2 / (r1 + r2)
    if gap > (1 + theta / 2) * vol ** (1 / 3):
        return 0.0
    s = max(gap, 0.0) / 2 * math.sqrt(rh / vol)
    return 2 * math.pi * rh * gamma * math.cos(theta) / (1 + 2.1 * s + 10 * s * s)


def _cap_model(**kw):
    return ContactModel(Material(E, NU, RHO), restitution=0.5, friction=0.5, capillary=True,
                        capillary_surface_tension=GAMMA, capillary_contact_angle=THETA, **kw)


def _attraction(sim):
    """Force on sphere 0 along +x (towards sphere 1), N."""
    f = sim._evaluate()[6]
    assert abs(f[0, 0] + f[1, 0]) <= 1e-12 * max(abs(f[0, 0]), 1e-30)  # action = reaction
    return f[np.argmin(sim.x[:, 0]), 0]


def test_capillary_pull_off_at_contact_is_2_pi_R_gamma_cos_theta():
    vol = 1e-15
    model = _cap_model(capillary_bridge_volume=vol)
    # spheres just apart (gap 1e-15 m): no Hertz force, bridge at its contact value
    sim = _pair(model, R, R, 1e-15)
    assert _attraction(sim) == pytest.approx(2 * math.pi * R * GAMMA * math.cos(THETA), rel=1e-6)
    # unequal spheres: R = 2 R* (Derjaguin)
    sim = _pair(model, R, 0.5 * R, 1e-15)
    rstar = R * 0.5 * R / (1.5 * R)
    assert _attraction(sim) == pytest.approx(4 * math.pi * rstar * GAMMA * math.cos(THETA),
                                             rel=1e-6)


def test_capillary_force_follows_willett_and_ruptures_at_sc():
    vol = 2e-15
    model = _cap_model(capillary_bridge_volume=vol)
    sc = (1 + THETA / 2) * vol ** (1 / 3)
    assert model.rupture_distance(0.5 * R) == pytest.approx(sc, rel=1e-12)
    for frac in (0.05, 0.2, 0.5, 0.9, 0.999):
        sim = _pair(model, R, 0.7 * R, frac * sc)
        assert _attraction(sim) == pytest.approx(_willett(frac * sc, R, 0.7 * R, vol), rel=1e-9)
        assert sim.n_pairs == 1  # neighbour cutoff extended by s_c
    # force decreases monotonically with the gap; zero beyond s_c
    fs = [_willett(g, R, R, vol) for g in np.linspace(0, sc, 20)]
    assert np.all(np.diff(fs) < 0)
    assert _attraction(_pair(model, R, 0.7 * R, 1.001 * sc)) == 0.0


def test_capillary_cutoff_beyond_the_skin():
    vol, skin = 1e-14, 1e-6  # s_c ~ 25 um, much more than the skin
    model = _cap_model(capillary_bridge_volume=vol)
    sc = model.rupture_distance(0.5 * R)
    assert sc > 10 * skin
    sim = _pair(model, R, R, 0.8 * sc, skin=skin)
    assert _attraction(sim) == pytest.approx(_willett(0.8 * sc, R, R, vol), rel=1e-9)
    assert sim.n_pairs == 1
    # without the extension the pair is not even listed
    base = ContactModel(Material(E, NU, RHO), restitution=0.5, friction=0.5)
    dry = _pair(base, R, R, 0.8 * sc, skin=skin)
    assert _attraction(dry) == 0.0 and dry.n_pairs == 0
    # the bridge pulls the pair in and stays listed through the rebuilds on the way
    sim.run(time=2e-4)
    gap = sim.x[1, 0] - sim.x[0, 0] - 2 * R
    assert 0 < gap < 0.5 * sc
    assert _attraction(sim) == pytest.approx(_willett(gap, R, R, vol), rel=1e-9)


def test_capillary_needs_a_volume():
    with pytest.raises(ConfigError, match="capillary_film_thickness"):
        ContactModel(Material(E, NU, RHO), capillary=True)
    with pytest.raises(ConfigError, match="capillary_contact_angle"):
        ContactModel(Material(E, NU, RHO), capillary=True, capillary_film_thickness=1e-9,
                     capillary_contact_angle=2.0)


def _ageing_model(ratio=1.5, cohesion=1e5, restitution=0.5, **kw):
    return ContactModel(Material(E, NU, RHO), restitution=restitution, friction=0.5,
                        cohesion=cohesion,
                        contact_ageing=True, ageing_bond_ratio=ratio, ageing_time_constant=1e-4,
                        ageing_reference_rest_time=1e-3, ageing_break_slip=1e-7, **kw)


def test_ageing_bond_grows_logarithmically_with_rest_time():
    base = ContactModel(Material(E, NU, RHO), restitution=0.5, friction=0.5, cohesion=1e5)
    model = _ageing_model()
    d = -2e-7  # overlap 0.2 um
    f0 = _attraction(_pair(base, R, R, d))
    r = 2 * R + d
    area = math.pi * lens_area_radius2(r, R, R)
    for tw in (0.0, 1e-4, 1e-3, 5e-3):
        sim = _pair(model, R, R, d)
        sim._setup()
        sim.hx[:, 0] = tw
        bond = 1.5 * 1e5 * area * math.log1p(tw / 1e-4) / math.log1p(1e-3 / 1e-4)
        assert _attraction(sim) - f0 == pytest.approx(bond, rel=1e-9, abs=1e-15)
    # at t_w = t_ref the bond equals ratio x the SJKR force k pi a^2, measured as the
    # difference the cohesion makes to the pair's force
    dry = ContactModel(Material(E, NU, RHO), restitution=0.5, friction=0.5)
    sjkr = f0 - _attraction(_pair(dry, R, R, d))
    assert sjkr == pytest.approx(1e5 * area, rel=1e-9)
    sim = _pair(model, R, R, d)
    sim._setup()
    sim.hx[:, 0] = 1e-3
    assert _attraction(sim) - f0 == pytest.approx(1.5 * sjkr, rel=1e-9)


def lens_area_radius2(r, ri, rj):
    return -((r - ri - rj) * (r + ri - rj) * (r - ri + rj) * (r + ri + rj)) / (4 * r * r)


def _drive(sim, speed, steps):
    """Move sphere 0 past sphere 1 along y at ``speed``, rotations held at zero (no rolling)."""
    for _ in range(steps):
        sim.v[0, 1], sim.v[1, 1] = speed, 0.0
        sim.om[:] = 0.0
        sim.run(steps=1)


def test_ageing_rest_time_slip_break_and_reform():
    model = _ageing_model(restitution=0.1)
    sim = _pair(model, R, R, -4e-7)  # near the SJKR equilibrium overlap, settles
    sim.run(steps=2000)
    age = sim.hx[0, 0]
    assert age == pytest.approx(2000 * sim.dt, rel=1e-9)  # contact age = time in contact
    assert sim.hx[0, 2] == 0.0 and sim.hx[0, 1] < 1e-7  # at rest: tiny slip, bond intact
    # rebuilds and checkpoints carry the ageing history
    sim._rebuild()
    assert sim.hx[0, 0] == pytest.approx(age)
    # slide: a driven tangential velocity (no rolling) breaks the bond ...
    _drive(sim, 0.2, 50)
    assert sim.hx[0, 2] == 1.0
    age_broken = sim.hx[0, 0]
    # ... for good while the contact lasts: the age no longer grows, no bond force
    sim.v[:] = 0.0
    sim.om[:] = 0.0
    sim.run(steps=50)
    assert sim.hx[0, 2] == 1.0 and sim.hx[0, 0] == age_broken
    # separate: history cleared; a new contact starts a new bond
    sim.v[0, 0] = -0.5
    sim.v[1, 0] = 0.5
    sim.run(steps=200)
    assert sim.x[1, 0] - sim.x[0, 0] > 2 * R
    assert np.all(sim.hx == 0.0)


def test_ageing_bond_breaks_by_sliding_not_by_elastic_shear():
    """Elastic tangential shear is recovered: only what the Coulomb limit cuts off counts."""
    def shear(friction, steps):
        model = ContactModel(Material(E, NU, RHO), restitution=0.1, friction=friction, cohesion=1e5,
                             contact_ageing=True, ageing_bond_ratio=1.5, ageing_time_constant=1e-4,
                             ageing_reference_rest_time=1e-3, ageing_break_slip=1e-7)
        sim = _pair(model, R, R, -4e-7)
        sim.run(steps=2000)
        path = 0.0
        for sign in (1, -1) * 10:  # shake tangentially: 20 strokes of the same length
            _drive(sim, sign * 1e-2, steps)
            path += 1e-2 * steps * sim.dt
        return sim, path
    stiff, path = shear(1e3, 5)      # far below the Coulomb limit: elastic shear only
    assert path > 10 * 1e-7          # the contact moved 10x the break slip back and forth ...
    assert stiff.hx[0, 2] == 0.0 and stiff.hx[0, 1] < 1e-12   # ... without sliding (roundoff only)
    slid, _ = shear(0.05, 50)        # beyond it: the contact slides and the bond breaks
    assert slid.hx[0, 2] == 1.0


def test_ageing_history_survives_checkpoint(tmp_path):
    model = _ageing_model()
    sim = _pair(model, R, R, -2e-7)
    sim.run(steps=100)
    sim.save_checkpoint(tmp_path / "c.npz")
    res = Simulation.from_checkpoint(tmp_path / "c.npz")
    assert res.model.contact_ageing and res.model.ageing_bond_ratio == 1.5
    np.testing.assert_array_equal(res.hx, sim.hx)
    sim.run(steps=50)
    res.run(steps=50)
    np.testing.assert_array_equal(res.x, sim.x)
    np.testing.assert_array_equal(res.hx, sim.hx)


def test_extensions_off_reproduce_the_base_model_bitwise():
    def run(model):
        box = Box([0, 0, 0], [1.2e-3, 1.2e-3, 3e-3], boundary="pp pp ff")
        sim = Simulation(box, model, walls=[Plane((0, 0, 0), (0, 0, 1))], n_threads=2, seed=3)
        sim.insert_raindrop(60, R, region=((0, 0, 0), (1.2e-3, 1.2e-3, 1.5e-3)))
        sim.run(steps=400)
        return sim.frame()
    kw = dict(restitution=0.3, friction=0.5, rolling_friction=0.1, cohesion=1e4)
    a = run(ContactModel(Material(E, NU, RHO), **kw))
    b = run(ContactModel(Material(E, NU, RHO), capillary=False, capillary_film_thickness=0.0,
                         contact_ageing=False, ageing_bond_ratio=0.0, **kw))
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.velocities, b.velocities)
    # magnitude 0 of the ageing extension (switched on, ratio 0) changes nothing physical
    c = run(ContactModel(Material(E, NU, RHO), contact_ageing=True, ageing_bond_ratio=0.0, **kw))
    np.testing.assert_allclose(c.positions, a.positions, rtol=0, atol=1e-12)


def test_epsd_rolling_stiffness_factor():
    kn, reff, mur, dt, w = 50.0, 5e-5, 0.2, 1e-7, 3.0
    for fac in (2.25, 5.0):
        out = K.rolling_torque(K.ROLL_EPSD, 0.0, 0.0, 0.0, 0.0, w, 0.0, 1.0, 0.0, 0.0, kn, 0.0,
                               1e-7, reff, 1.0, mur, dt, 0.0, 0.0, fac)
        assert out[1] == pytest.approx(fac * kn * mur ** 2 * reff ** 2 * w * dt, rel=1e-12)


def test_wall_program_ramp_and_vibration_time_law():
    model = ContactModel(Material(E, NU, RHO), restitution=0.5, friction=0.5)
    sim = Simulation(closed_box(), model, walls=[Plane((0, 0, 0), (0, 0, 1), name="floor"),
                                                 Plane((1e-4, 0, 0), (1, 0, 0), name="blade")],
                     gravity=(0, 0, 0), n_threads=1, dt=1e-6, force=True)
    sim.add_particles([[1e-3, 1e-3, 1e-3]], [R])
    v, tau, amp, f = 0.05, 2e-4, 2e-6, 1000.0
    sim.set_wall_program("blade", velocity=(v, 0, 0), ramp_time=tau, vibration_amplitude=amp,
                         vibration_frequency=f)
    for _ in range(4):
        sim.run(steps=137)
        t = sim.time
        st = {w.name: w for w in sim.wall_states()}["blade"]
        x_exp = 1e-4 + v * (t - tau * (1 - math.exp(-t / tau)))
        z_exp = amp * math.sin(2 * math.pi * f * t)
        assert st.origin[0] == pytest.approx(x_exp, rel=1e-9)
        assert st.origin[2] == pytest.approx(z_exp, rel=1e-9, abs=1e-18)
        assert st.velocity[0] == pytest.approx(v * (1 - math.exp(-t / tau)), rel=1e-9)
        assert st.velocity[2] == pytest.approx(2 * math.pi * f * amp * math.cos(2 * math.pi * f * t),
                                               rel=1e-9, abs=1e-15)
    # ramp 0 and no vibration: the constant-velocity law
    sim.set_wall_program("blade", velocity=(v, 0, 0))
    x0, t0 = sim.wall_states()[1].origin[0], sim.time
    sim.run(steps=100)
    assert sim.wall_states()[1].origin[0] == pytest.approx(x0 + v * (sim.time - t0), rel=1e-12)
    with pytest.raises(ConfigError):
        sim.set_wall_program("blade", velocity=(v, 0, 0), ramp_time=-1.0)


def test_age_contacts_is_a_rest_of_that_length_for_a_packing_at_rest():
    """A resting pair aged by t_w holds the bond of the logarithmic law at t_w (against the
    same formula as above); broken bonds, open pairs and models without ageing are untouched;
    and fast-forwarding equals simulating the rest of a settled pair."""
    model = _ageing_model()
    d = -2e-7
    r = 2 * R + d
    area = math.pi * lens_area_radius2(r, R, R)
    f0 = _attraction(_pair(ContactModel(Material(E, NU, RHO), restitution=0.5, friction=0.5,
                                        cohesion=1e5), R, R, d))
    sim = _pair(model, R, R, d)
    assert sim.age_contacts(5e-3) == 1
    bond = 1.5 * 1e5 * area * math.log1p(5e-3 / 1e-4) / math.log1p(1e-3 / 1e-4)
    assert _attraction(sim) - f0 == pytest.approx(bond, rel=1e-9)
    # a broken bond stays broken and does not age
    sim.hx[:, 2] = 1.0
    before = sim.hx.copy()
    assert sim.age_contacts(1.0) == 0 and np.array_equal(sim.hx, before)
    # an open pair (within the skin, not touching) does not age
    apart = _pair(model, R, R, 1e-7, skin=1e-5)
    assert apart.age_contacts(1.0) == 0 and apart.n_pairs == 1
    # no ageing: nothing to do
    dry = _pair(ContactModel(Material(E, NU, RHO), restitution=0.5, friction=0.5), R, R, d)
    assert dry.age_contacts(1.0) == 0
    with pytest.raises(ConfigError, match="rest time"):
        sim.age_contacts(-1.0)
    # simulated rest of a settled pair == the same rest fast-forwarded
    a = _pair(_ageing_model(restitution=0.1), R, R, -4e-7)
    a.run(steps=2000)
    b = _pair(_ageing_model(restitution=0.1), R, R, -4e-7)
    b.run(steps=2000)
    a.run(steps=3000)
    b.age_contacts(3000 * b.dt)
    assert b.hx[0, 0] == pytest.approx(a.hx[0, 0], rel=1e-9)
    # the stronger bond pulls the pair into a slightly larger overlap: after relaxing,
    # both sit at the same equilibrium
    a.run(steps=4000)
    b.run(steps=4000)
    overlap_a = 2 * R - (a.x[1, 0] - a.x[0, 0])
    overlap_b = 2 * R - (b.x[1, 0] - b.x[0, 0])
    assert b.hx[0, 2] == 0.0 and overlap_b == pytest.approx(overlap_a, rel=1e-3)
    young = _pair(_ageing_model(restitution=0.1), R, R, -4e-7)
    young.run(steps=6000)
    assert overlap_b > (2 * R - (young.x[1, 0] - young.x[0, 0])) * (1 + 1e-3)
