"""The engine's fast paths give the same numbers as the plain ones (bit for bit)."""

import numpy as np
import pytest

from bedstruct import Box
from bedstruct.dem import ContactModel, Material, Plane, Simulation
from bedstruct.dem import _kernels as K

E, NU, RHO = 1e7, 0.3, 2500.0
R = 40e-6


def _bed(n_threads=2, seed=5):
    model = ContactModel(Material(E, NU, RHO), restitution=0.3, friction=0.5,
                         rolling_friction=0.1, rolling_model="epsd2", cohesion=1e4)
    box = Box([0, 0, 0], [1.2e-3, 1.2e-3, 3e-3], boundary="pp pp ff")
    sim = Simulation(box, model, walls=[Plane((0, 0, 0), (0, 0, 1))], n_threads=n_threads,
                     seed=seed)
    sim.insert_raindrop(120, R, region=((0, 0, 0), (1.2e-3, 1.2e-3, 1.5e-3)), velocity=(0.1, 0, -0.5))
    return sim


def test_fused_steps_equal_plain_steps():
    # run() fuses each step's last pass with the next step's first pass; a callback
    # (which must see whole steps) switches that off
    a = _bed()
    b = _bed()
    a.run(600)
    b.run(600, callback=lambda sim: None)
    assert a.n_rebuilds > 1
    for name in ("x", "v", "om", "f", "tq", "ht", "hr"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def _spread_bed(fused, seed=7):
    """A bed with a blade under a start-up ramp and a vibrating floor plate: rebuilds, new
    wall lists and wall programs inside a run."""
    from bedstruct.dem import Blade, Rectangle
    model = ContactModel(Material(E, NU, RHO), restitution=0.3, friction=0.5,
                         rolling_friction=0.1, rolling_model="epsd2", cohesion=1e4)
    box = Box([0, 0, -1e-4], [1.2e-3, 0.6e-3, 3e-3], boundary="ff pp ff")
    walls = [Plane((0, 0, 0), (0, 0, 1), name="floor"),
             Rectangle((0.6e-3, 0.3e-3, 5e-5), (0, 0, 1), (1, 0, 0), (0.3e-3, 0.3e-3),
                       name="plate"),
             Blade(gap=150e-6, speed=0.0, x0=0.1e-3)]
    sim = Simulation(box, model, walls=walls, n_threads=2, seed=seed)
    sim.fused_loop = fused
    sim.insert_raindrop(150, R, region=((0.2e-3, 0, 0), (1.2e-3, 0.6e-3, 1e-3)),
                        velocity=(0.0, 0, -0.5))
    return sim


def test_step_loop_in_numba_equals_steps_in_python(tmp_path):
    # run() makes the steps between two looks at the state in one numba loop; the same
    # runs stepped one by one in Python give the same bits: rebuilds, new wall lists,
    # wall programs (ramp and vibration), wall-load sums, dumps and checkpoints
    out = {}
    for fused in (True, False):
        sim = _spread_bed(fused)
        sim.run(700)
        sim.set_wall_program("blade", velocity=(0.4, 0, 0), ramp_time=2e-4)
        sim.set_wall_program("plate", velocity=(0, 0, 0), vibration_amplitude=2e-6,
                             vibration_frequency=3000.0)
        sim.start_wall_load_average()
        rd = tmp_path / f"run{int(fused)}"
        stats = sim.run(900, dump_every=250, run_dir=rd, checkpoint_every=400)
        load = sim.wall_load_average()
        out[fused] = (sim, stats, load, (rd / "checkpoint.npz").read_bytes())
    (a, sa, la, ca), (b, sb, lb, cb) = out[True], out[False]
    assert sa.n_rebuilds > 5 and sa.n_rebuilds == sb.n_rebuilds
    assert a.n_particles == b.n_particles > 50
    for name in ("x", "v", "om", "f", "tq", "ht", "hr", "whist", "wslot", "_W"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.time == b.time and a.step == b.step
    for w in la:
        np.testing.assert_array_equal(la[w], lb[w], err_msg=w)
    assert np.any(la["blade"] != 0.0) and np.any(la["plate"] != 0.0)
    za, zb = np.load(tmp_path / "run1" / "checkpoint.npz"), np.load(tmp_path / "run0" / "checkpoint.npz")
    for k in za.files:
        if k != "meta":
            np.testing.assert_array_equal(za[k], zb[k], err_msg=k)
    dumps = sorted(p.name for p in (tmp_path / "run1").iterdir())
    assert dumps == sorted(p.name for p in (tmp_path / "run0").iterdir())
    for name in dumps:
        if name.endswith((".dump", ".local", ".csv")):
            assert (tmp_path / "run1" / name).read_bytes() == (tmp_path / "run0" / name).read_bytes()


def _program_by_formula(prog, time):
    """set_wall_program's formula, written with numpy."""
    s = time - prog["t0"]
    v = np.asarray(prog["velocity"])
    tau = prog["ramp_time"]
    e = np.exp(-s / tau) if tau > 0 else 1.0
    x = np.asarray(prog["origin"]) + v * ((s - tau * (1.0 - e)) if tau > 0 else s)
    u = v * (1.0 - e) if tau > 0 else v.copy()
    om = 2.0 * np.pi * prog["frequency"]
    d = np.asarray(prog["direction"])
    return (x + prog["amplitude"] * np.sin(om * s) * d,
            u + prog["amplitude"] * om * np.cos(om * s) * d)


def test_wall_programs_follow_their_formula():
    # the programmed walls' rows, written by the kernel every step, against the documented
    # formula (to round-off) and against their own time derivative (velocity = dx/dt)
    sim = _spread_bed(True)
    sim.set_wall_program("blade", velocity=(0.4, 0.01, 0), ramp_time=2e-4,
                         vibration_amplitude=1e-6, vibration_frequency=700.0,
                         vibration_direction=(0, 1, 1))
    sim.set_wall_program("plate", velocity=(0, 0, 0), vibration_amplitude=2e-6,
                         vibration_frequency=3000.0)
    for t in (0.0, 1.3e-5, 3.7e-4, 2.1e-3):
        sim._apply_programs(t)
        for name, prog in sim._programs.items():
            row = sim._W[sim.wall_names.index(name)]
            x, u = _program_by_formula(prog, t)
            np.testing.assert_allclose(row[1:4], x, rtol=1e-14, atol=1e-18)
            np.testing.assert_allclose(row[10:13], u, rtol=1e-12, atol=1e-15)
            assert row[13] == t
            h = 1e-9
            xp, _ = sim.wall_program_state(prog, t + h)
            xm, _ = sim.wall_program_state(prog, t - h)
            np.testing.assert_allclose((xp - xm) / (2 * h), row[10:13], rtol=1e-5, atol=1e-8)
    blade = sim._programs["blade"]
    x0, u0 = sim.wall_program_state(blade, blade["t0"])
    np.testing.assert_array_equal(x0, blade["origin"])  # starts where it was,
    np.testing.assert_allclose(u0, 1e-6 * 2 * np.pi * 700.0 * np.asarray(blade["direction"]),
                               rtol=1e-12)          # the ramp at rest, the vibration at its peak


def _pair_call(sim, pi, pj, psh, ht, hr, bounds, fb, tb, fn, ft, blocked=True):
    m = sim.model
    K.pair_forces((sim.x, sim.v, sim.om, sim.rad, sim.mass, sim.inv_i, sim.ptype), (pi, pj, psh),
                  sim._L, (ht, hr), bounds, fb, tb, sim._pair_tab, m.rolling_code, m.limit_force,
                  float(m.rolling_damping), sim.dt, True, fn, ft, sim._cap if m.capillary else None,
                  None, sim._kr_fac, blocked=blocked)


def _lattice(n_threads=3, side=8, **kw):
    """A jammed lattice: about half the bonds overlap, random velocities and spins."""
    model = ContactModel(Material(E, NU, RHO), restitution=0.3, friction=0.5,
                         **{"rolling_friction": 0.1, "rolling_model": "epsd2", "cohesion": 1e4,
                            **kw})
    box = Box([0, 0, 0], [side * 125e-6] * 3, boundary="pp pp ff")
    sim = Simulation(box, model, n_threads=n_threads, gravity=(0, 0, 0))
    rng = np.random.default_rng(0)
    g = (np.arange(side) + 0.5) * 2 * R * 0.999
    pos = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    pos += rng.normal(0, 0.01 * R, pos.shape)
    sim.add_particles(pos, R, velocities=rng.normal(0, 0.01, pos.shape),
                      omegas=rng.normal(0, 100.0, pos.shape))
    sim.run(1)
    return sim


@pytest.mark.parametrize("blocked", [True, False], ids=["blocked", "single-loop"])
def test_pair_kernel_blocks_equal_pair_by_pair(blocked):
    # the kernel works in blocks of pairs split into touching and other pairs;
    # every pair must get the force it gets alone, and pairs apart lose their history
    sim = _lattice()
    m = sim.n_pairs
    assert m > 3 * 64 + 5  # several blocks per chunk and a partial last block
    rng = np.random.default_rng(1)
    ht0 = sim.ht + rng.normal(0, 1e-7, (m, 3))
    hr0 = sim.hr + rng.normal(0, 1e-12, (m, 3))
    n = sim.n_particles
    d = sim.x[sim.pi] - sim.x[sim.pj] - sim.psh * sim._L
    touch = np.einsum("ij,ij->i", d, d) < (sim.rad[sim.pi] + sim.rad[sim.pj]) ** 2
    assert 0 < touch.sum() < m
    ht, hr = ht0.copy(), hr0.copy()
    fb, tb = np.zeros((3, n, 3)), np.zeros((3, n, 3))
    fn, ft = np.zeros(m), np.zeros((m, 3))
    _pair_call(sim, sim.pi, sim.pj, sim.psh, ht, hr, sim._chunks(m), fb, tb, fn, ft, blocked)
    assert np.all(ht[~touch] == 0.0) and np.all(hr[~touch] == 0.0)
    assert np.all(fn[~touch] == 0.0)
    one = np.array([0, 1])
    for k in np.flatnonzero(touch)[:: max(1, touch.sum() // 40)]:
        h1, r1 = ht0[k:k + 1].copy(), hr0[k:k + 1].copy()
        f1, t1 = np.zeros((1, n, 3)), np.zeros((1, n, 3))
        fn1, ft1 = np.zeros(1), np.zeros((1, 3))
        _pair_call(sim, sim.pi[k:k + 1], sim.pj[k:k + 1], sim.psh[k:k + 1], h1, r1, one, f1, t1,
                   fn1, ft1, blocked)
        assert fn1[0] == fn[k] and np.array_equal(ft1[0], ft[k])
        assert np.array_equal(h1[0], ht[k]) and np.array_equal(r1[0], hr[k])
    # Newton's third law over all chunks
    np.testing.assert_allclose(fb.sum(axis=(0, 1)), 0.0, atol=1e-12 * np.abs(fb).max())


_ROLLING = {"none": dict(rolling_model="none", cohesion=0.0),
            "cdt": dict(rolling_model="cdt"), "epsd": dict(rolling_model="epsd"),
            "epsd2": dict(rolling_model="epsd2"),
            "epsd-krf3": dict(rolling_model="epsd", rolling_stiffness_factor=3.0)}


def _both_passes(sim):
    """One pair pass from the same state, blocked and single loop: {blocked: arrays}."""
    out = {}
    m, n = sim.n_pairs, sim.n_particles
    rng = np.random.default_rng(1)
    ht0 = sim.ht + rng.normal(0, 1e-7, (m, 3))  # springs and rolling torques under way
    hr0 = sim.hr + rng.normal(0, 1e-12, (m, 3))
    for blocked in (True, False):
        ht, hr = ht0.copy(), hr0.copy()
        fb, tb = np.zeros((3, n, 3)), np.zeros((3, n, 3))
        fn, ft = np.zeros(m), np.zeros((m, 3))
        _pair_call(sim, sim.pi, sim.pj, sim.psh, ht, hr, sim._chunks(m), fb, tb, fn, ft, blocked)
        out[blocked] = dict(fn=fn, ft=ft, ht=ht, hr=hr, f=fb, tq=tb)
    return out


@pytest.mark.parametrize("case", [c if c == "epsd2" else pytest.param(c, marks=pytest.mark.slow)
                                  for c in sorted(_ROLLING)])   # each model compiles its own pass
def test_blocked_pair_pass_equals_single_loop_bit_for_bit(case):
    # the two passes compute one contact law, rounded as written, and add forces in pair
    # order: the gather-compute-scatter pass changes no bit
    out = _both_passes(_lattice(**_ROLLING[case]))
    for name, ref in out[False].items():
        assert np.abs(ref).max() > 0.0 or name == "hr", name   # the arrays say something
        np.testing.assert_array_equal(out[True][name], ref, err_msg=name)


def test_blocked_pair_pass_rounds_as_written(monkeypatch):
    # the blocked pass's vectorised loop gives the bits of its own source run by the Python
    # interpreter (every operation rounded as written, in IEEE double)
    from bedstruct.dem import _kernels_contact as KC
    from bedstruct.dem import _kernels_pairs_blocked as KP
    sim = _lattice(side=5, rolling_model="epsd")
    m, n = sim.n_pairs, sim.n_particles
    assert m > 3 * KP._BLOCK_B
    rng = np.random.default_rng(2)
    ht0 = sim.ht + rng.normal(0, 1e-7, (m, 3))
    hr0 = sim.hr + rng.normal(0, 1e-12, (m, 3))
    bounds = sim._chunks(m)
    res = []
    for python in (False, True):
        ht, hr = ht0.copy(), hr0.copy()
        fb, tb = np.zeros((3, n, 3)), np.zeros((3, n, 3))
        fn, ft = np.zeros(m), np.zeros((m, 3))
        if not python:
            _pair_call(sim, sim.pi, sim.pj, sim.psh, ht, hr, bounds, fb, tb, fn, ft)
        else:
            monkeypatch.setattr(KP, "pair_contact", KC.pair_contact_law(
                **{n: f.py_func for n, f in KC.PAIR_PIECES.items()}))
            monkeypatch.setattr(KP, "_open_pair", KP._open_pair.py_func)
            mo = sim.model
            for t in range(len(bounds) - 1):
                KP._pair_chunk_blocked.py_func(
                    t, (sim.x, sim.v, sim.om, sim.rad, sim.mass, sim.inv_i, sim.ptype),
                    (sim.pi, sim.pj, sim.psh), sim._L, (ht, hr), bounds, fb, tb, sim._pair_tab,
                    mo.rolling_code, mo.limit_force, float(mo.rolling_damping), sim.dt, True, fn,
                    ft, None)
        res.append((fn, ft, ht, hr, fb, tb))
    for a, b, name in zip(*res, ("fn", "ft", "ht", "hr", "f", "tq")):
        assert np.array_equal(a, b), name


@pytest.mark.parametrize("fused_loop", [True, False], ids=["numba-loop", "python-steps"])
def test_run_interrupted_between_fused_steps_resumes_exactly(tmp_path, fused_loop):
    a = _bed()
    a.run(300)
    b = _bed()
    b.fused_loop = fused_loop

    class Stop(Exception):
        pass

    plain_step, plain_loop = b._one_step, b._run_fused

    def one_step(kick_next=False):  # an interrupt (e.g. Ctrl-C) right after a fused step
        plain_step(kick_next)
        if b.step >= 150 and b._kicked:
            raise Stop

    def run_fused(nmax, fuse_last):  # or right after the numba loop handed back
        done = plain_loop(nmax, fuse_last)
        if b.step >= 150 and b._kicked:
            raise Stop
        return done

    b._one_step, b._run_fused = one_step, run_fused
    try:
        b.run(300)
    except Stop:
        pass
    assert b._kicked and 150 <= b.step < 300
    c = Simulation.from_checkpoint(b.save_checkpoint(tmp_path / "mid.npz"))
    c.run(300 - b.step)
    np.testing.assert_array_equal(c.x, a.x)
    np.testing.assert_array_equal(c.v, a.v)


def test_checkpoint_between_fused_steps_keeps_a_due_rebuild(tmp_path):
    # interrupted right after a fused step whose drift made a rebuild due: the resumed run
    # must still rebuild before that step's pair pass (the displacements come back with it)
    a = _bed()
    a.run(300)
    b = _bed()
    b.fused_loop = False

    class Stop(Exception):
        pass

    plain = b._one_step

    def one_step(kick_next=False):
        plain(kick_next)
        if b._kicked and b._disp.max() > (0.5 * b.skin) ** 2:
            raise Stop

    b._one_step = one_step
    try:
        b.run(300)
    except Stop:
        pass
    assert b._kicked and 0 < b.step < 300
    c = Simulation.from_checkpoint(b.save_checkpoint(tmp_path / "due.npz"))
    rebuilds = c.n_rebuilds
    c.run(300 - b.step)
    assert c.n_rebuilds > rebuilds
    np.testing.assert_array_equal(c.x, a.x)
    np.testing.assert_array_equal(c.v, a.v)


def test_rebuild_kernels_equal_their_numpy_forms():
    # wrap_and_flag replaced a numpy wrap, removal mask and finiteness check; candidate_lists
    # replaced a cumsum/nonzero compaction: both must give the same arrays
    rng = np.random.default_rng(3)
    lo, hi = np.array([0.0, -1.0, 0.0]), np.array([2.0, 1.0, 1.0])
    L = hi - lo
    periodic = np.array([True, True, False])
    x = rng.uniform(-3.0, 4.0, (400, 3))
    x[7, 1] = np.nan
    x[11, 2] = np.inf
    images = rng.integers(-2, 3, (400, 3))
    xw, iw, out = x.copy(), images.copy(), np.zeros(400, dtype=bool)
    n_out, n_bad = K.wrap_and_flag(xw, iw, lo, hi, L, periodic, out)

    finite = np.all(np.isfinite(x), axis=1)
    xr, ir = x.copy(), images.copy()
    for a in (0, 1):
        k = np.floor((xr[finite, a] - lo[a]) / L[a]).astype(np.int64)
        xr[finite, a] -= k * L[a]
        ir[finite, a] += k
    gone = ~finite | (x[:, 2] < lo[2]) | (x[:, 2] >= hi[2])
    np.testing.assert_array_equal(out, gone)
    assert (n_out, n_bad) == (int(gone.sum()), 2)
    np.testing.assert_array_equal(xw[finite], xr[finite])   # bit for bit
    np.testing.assert_array_equal(iw[finite], ir[finite])
    assert np.all((xw[finite, :2] >= lo[:2]) & (xw[finite, :2] < hi[:2]))

    near = rng.random((50, 6)) < 0.3
    start, cand = K.candidate_lists(near)
    np.testing.assert_array_equal(start, np.concatenate([[0], np.cumsum(near.sum(axis=1))]))
    np.testing.assert_array_equal(cand, np.nonzero(near)[1])


def _aged_bed(ids=None):
    model = ContactModel(Material(E, NU, RHO), restitution=0.3, friction=0.5,
                         rolling_friction=0.1, rolling_model="epsd2", cohesion=1e4,
                         contact_ageing=True, ageing_bond_ratio=1.0, ageing_time_constant=1e-4,
                         ageing_reference_rest_time=1e-3, ageing_break_slip=1e-7)
    box = Box([0, 0, 0], [1.2e-3, 1.2e-3, 3e-3], boundary="pp pp ff")
    sim = Simulation(box, model, walls=[Plane((0, 0, 0), (0, 0, 1))], n_threads=1, seed=5)
    rng = np.random.default_rng(11)
    pos = np.column_stack([rng.uniform(0, 1.2e-3, 200), rng.uniform(0, 1.2e-3, 200),
                           rng.uniform(0.05e-3, 2.9e-3, 200)])
    keep = [0]
    for k in range(1, 200):
        if np.min(np.linalg.norm(pos[keep] - pos[k], axis=1)) > 2.05 * R:
            keep.append(k)
    sim.add_particles(pos[keep], np.full(len(keep), R),
                      velocities=np.tile([0.05, 0.0, -0.3], (len(keep), 1)),
                      ids=None if ids is None else ids(len(keep)))
    return sim


def test_history_remap_by_partner_equals_the_binary_search():
    """Dense ids take the partner lookup at rebuilds, ids too sparse for a table by id the
    binary search in sorted keys: the same history (tangential, rolling and ageing) is carried,
    so the two runs stay equal bit for bit through hundreds of rebuilds."""
    dense = _aged_bed()
    sparse = _aged_bed(ids=lambda n: 1_000_000 + 7919 * np.arange(n))
    for sim in (dense, sparse):
        sim.run(6000)
    assert dense.n_rebuilds > 100 and dense.n_rebuilds == sparse.n_rebuilds
    assert np.any(dense.hx[:, 0] > 0)                     # ageing bonds were carried
    a, b = np.argsort(dense.ids), np.argsort(sparse.ids)
    np.testing.assert_array_equal(dense.x[a], sparse.x[b])
    np.testing.assert_array_equal(dense.om[a], sparse.om[b])


def test_busy_machine_runs_the_chunks_on_one_thread(monkeypatch):
    # a run that finds the cores busy runs its chunks on one thread: same chunks, same bits
    import numba

    from bedstruct.dem import simulation
    if simulation._numba_max_threads() < 2:
        pytest.skip("numba may use one thread only here")
    used = {}
    res = {}
    for busy in (False, True):
        monkeypatch.setattr(simulation, "_cores_busy", lambda threads, busy=busy: busy)
        sim = _bed()
        sim.serial_below = 0
        sim.run(200, callback=lambda s: used.setdefault(busy, numba.get_num_threads()))
        res[busy] = sim
    assert used == {False: 2, True: 1}
    for name in ("x", "v", "om", "f", "tq", "ht", "hr"):
        np.testing.assert_array_equal(getattr(res[True], name), getattr(res[False], name),
                                      err_msg=name)
    # without yield_when_busy the threads run whatever the load
    sim = _bed()
    sim.serial_below = 0
    sim.yield_when_busy = False
    sim.run(2, callback=lambda s: used.setdefault("off", numba.get_num_threads()))
    assert used["off"] == 2


def test_cores_busy_subtracts_own_use(monkeypatch):
    from bedstruct.dem import simulation
    monkeypatch.setattr(simulation.os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    clock = {"wall": 100.0, "cpu": 10.0}
    monkeypatch.setattr(simulation._time, "perf_counter", lambda: clock["wall"])
    monkeypatch.setattr(simulation._time, "process_time", lambda: clock["cpu"])
    monkeypatch.setattr(simulation, "_LOAD_PROBE", [None, None, 0.0])
    load = {"1min": 1.3}
    monkeypatch.setattr(simulation.os, "getloadavg", lambda: (load["1min"], 0.0, 0.0))
    # first look: this process counts as one running thread; 0.3 for the others leaves
    # two cores to two threads
    assert not simulation._cores_busy(2)
    load["1min"] = 3.0  # within half a second the estimate is kept
    clock["wall"] += 0.1
    assert not simulation._cores_busy(2)
    # 1.9 s later, this process used 2 cores (its two threads): 3 - 2 = 1 for the others
    clock["wall"] += 1.9
    clock["cpu"] += 2.0 * 2.0
    assert simulation._cores_busy(2)
    assert not simulation._cores_busy(1)
    # idle for 10 s: a load of 1.2 is all the others'
    load["1min"] = 1.2
    clock["wall"] += 10.0
    assert simulation._cores_busy(2) and not simulation._cores_busy(1)
    load["1min"] = 0.2
    clock["wall"] += 10.0
    assert not simulation._cores_busy(2)


def _pair_list_by_definition(x, rad, cells, start, nc, periodic, L, cutoff):
    """The half-stencil pair list in its documented order, written plainly: for each i, the
    13 forward neighbour cells in ``HALF_STENCIL`` order, then its own cell (j > i), each
    cell's particles in index order."""
    out = []
    for i in range(x.shape[0]):
        c = int(cells[i])
        cx, cy, cz = c % nc[0], (c // nc[0]) % nc[1], c // (nc[0] * nc[1])
        ranges = []
        for st in K.HALF_STENCIL:
            o, sh, ok = [cx + st[0], cy + st[1], cz + st[2]], [0, 0, 0], True
            for a in range(3):
                if o[a] < 0 or o[a] >= nc[a]:
                    if not periodic[a]:
                        ok = False
                    sh[a] = -1 if o[a] < 0 else 1
                    o[a] -= sh[a] * nc[a]
            if ok:
                cc = (o[2] * nc[1] + o[1]) * nc[0] + o[0]
                ranges.append((range(start[cc], start[cc + 1]), sh))
        ranges.append((range(i + 1, start[c + 1]), [0, 0, 0]))
        for js, sh in ranges:
            for j in js:
                d = x[i] - np.asarray(sh) * L - x[j]
                if d @ d < (rad[i] + cutoff + rad[j]) ** 2:
                    out.append((i, j, *sh))
    return np.array(out, dtype=np.int64).reshape(-1, 5)


@pytest.mark.parametrize("periodic", [(True, True, False), (False, True, True)])
def test_pair_list_follows_its_documented_order(periodic):
    # the build scans a cell's neighbour cells as rows (cells whose particles follow each
    # other in the sorted order): the same pairs in the same order as cell by cell
    rng = np.random.default_rng(8)
    L = np.array([1.0, 0.8, 0.6])
    nc = np.array([5, 4, 3], dtype=np.int64)
    x = rng.uniform(0, 1, (600, 3)) * L
    rad = rng.uniform(0.02, 0.05, 600)
    cells = np.empty(600, dtype=np.int64)
    K.cell_indices(x, np.zeros(3), L / nc, nc, cells)
    perm, start = K.counting_sort(cells, int(nc.prod()))
    x, rad, cells = x[perm], rad[perm], cells[perm]
    per = np.array(periodic)
    want = _pair_list_by_definition(x, rad, cells, start, nc, per, L, 0.01)
    for chunks, hint in ((1, 0), (3, 0), (3, len(want)), (2, 10)):   # 10: room too short
        bounds = np.linspace(0, 600, chunks + 1).astype(np.int64)
        pi, pj, psh = K.pair_list(x, rad, cells, start, nc, per, L, 0.01, bounds, hint)
        got = np.column_stack([pi, pj, psh]).astype(np.int64)
        np.testing.assert_array_equal(got, want)
    assert len(want) > 500 and np.any(want[:, 2:] != 0)


def test_rebuild_that_drops_particles_carries_the_others_history():
    sim = _lattice(n_threads=2, contact_ageing=True, ageing_bond_ratio=1.0,
                   ageing_time_constant=1e-6, ageing_reference_rest_time=1e-5,
                   ageing_break_slip=1e-7)
    sim.run(100)

    def by_key(s):
        a, b = s.ids[s.pi], s.ids[s.pj]
        sign = np.where(a < b, 1.0, -1.0)[:, None]
        keys = np.minimum(a, b) * 2**31 + np.maximum(a, b)
        return {int(k): (h * sg, r * sg, q) for k, h, r, q, sg in
                zip(keys, sim.ht, sim.hr, sim.hx, sign) if np.any(h) or np.any(r) or np.any(q)}
    before = by_key(sim)
    held = np.flatnonzero(np.any(sim.ht != 0, axis=1))
    gone = {int(sim.ids[sim.pi[held[0]]]), int(sim.ids[sim.pj[held[-1]]])}
    assert len(held) > 100 and np.any(sim.hx != 0)
    for i in np.flatnonzero(np.isin(sim.ids, list(gone))):
        sim.x[i, 2] = -1.0                       # below the fixed floor face: leaves
    n = sim.n_particles
    sim._rebuild()
    assert sim.n_particles == n - len(gone) and not gone & set(sim.ids.tolist())
    after = by_key(sim)
    kept = {k: v for k, v in before.items() if not {k >> 31, k & (2**31 - 1)} & gone}
    assert kept and set(after) == set(kept)
    for k, (h, r, q) in kept.items():
        np.testing.assert_array_equal(after[k][0], h)
        np.testing.assert_array_equal(after[k][1], r)
        np.testing.assert_array_equal(after[k][2], q)


def test_setting_n_threads_on_a_running_simulation_rechunks_it(tmp_path):
    # every per-chunk buffer follows the new number of chunks at once (a neighbour
    # rebuild): the simulation goes on as one loaded from its checkpoint would
    a = _bed(n_threads=1)
    a.run(300)
    a.n_threads = 2
    assert a._fbuf.shape[0] == 2 and a._wbuf.shape[0] == 2 and len(a._qbounds) == 3
    a.save_checkpoint(tmp_path / "c.npz")
    b = Simulation.from_checkpoint(tmp_path / "c.npz")
    a.run(400)
    b.run(400)
    for name in ("x", "v", "om", "ht", "hr"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    from bedstruct.errors import ConfigError
    with pytest.raises(ConfigError, match="n_threads"):
        a.n_threads = 0


def test_a_pair_apart_clears_its_history_and_keeps_a_zero_as_it_is():
    # the history of a pair apart is written back without a branch on its values: a
    # history that is not zero becomes +0, one that is zero keeps its bits (a sign flip
    # at a rebuild can leave -0.0), so the pass writes what the branching form wrote
    from bedstruct.dem._kernels_contact import _open_pair
    from bedstruct._numba import njit

    @njit
    def open_rows(ht, hr, fn, ft):
        for k in range(ht.shape[0]):
            _open_pair(k, ht, hr, True, fn, ft)

    ht = np.array([[-0.0, 0.0, -0.0], [0.0, 1e-9, 0.0], [-2.0, -0.0, 3.0]])
    hr = np.array([[0.0, 0.0, 0.0], [-0.0, -0.0, -0.0], [0.0, 0.0, -1e-12]])
    want_t = np.array([[-0.0, 0.0, -0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    want_r = np.array([[0.0, 0.0, 0.0], [-0.0, -0.0, -0.0], [0.0, 0.0, 0.0]])
    ft = np.ones((3, 3))
    open_rows(ht, hr, np.ones(3), ft)
    assert ht.tobytes() == want_t.tobytes() and hr.tobytes() == want_r.tobytes()
    assert not ft.any()


def test_wall_candidates_skip_a_prism_only_where_it_is_out_of_reach():
    # a prism (the blade) is measured only near its bounding box: the candidates equal
    # those of measuring every sphere, spheres at the box's edges and inside included
    from bedstruct._numba import njit
    from bedstruct.dem import Blade
    from bedstruct.dem._kernels_walls import any_wall_geometry

    @njit
    def near_by_measuring(x, rad, W, tri, time, skin):
        out = np.zeros((x.shape[0], W.shape[0]), dtype=np.bool_)
        for i in range(x.shape[0]):
            for w in range(W.shape[0]):
                hit, dist = any_wall_geometry(W, w, tri, x[i, 0], x[i, 1], x[i, 2], time)[:2]
                out[i, w] = hit and dist < rad[i] + skin and dist > -rad[i] - skin
        return out

    sim = Simulation(Box([0, 0, 0], [4e-3, 1e-3, 8e-3], boundary="ff pp ff"),
                     ContactModel(Material(E, NU, RHO)),
                     walls=[Plane((0, 0, 0), (0, 0, 1)),
                            Blade(gap=100e-6, speed=0.05, x0=1e-3, height=2e-3)], n_threads=1)
    W, tri = sim._W, sim._tri
    rng = np.random.default_rng(4)
    n = 20000
    x = np.column_stack([rng.uniform(-1e-3, 3e-3, n), rng.uniform(0, 1e-3, n),
                         rng.uniform(-1e-3, 3e-3, n)])
    rad = rng.uniform(20e-6, 40e-6, n)
    skin = 6e-6
    # spheres just inside and just outside reach of the box's faces (blade: x0 +- 0.25 mm,
    # from its lowest edge up to 2 mm)
    k = np.arange(4000)
    face = np.array([1e-3 - 0.25e-3, 1e-3 + 0.25e-3])[k % 2] + np.where(k % 2, 1, -1) * (
        rad[:4000] + skin) * (1 + rng.uniform(-3e-6, 3e-6, 4000))
    x[:4000, 0] = face
    x[:4000, 2] = rng.uniform(0, 2.2e-3, 4000)
    near = np.zeros((n, W.shape[0]), dtype=np.bool_)
    wslot = -np.ones((n, 4), dtype=np.int32)
    whist = np.zeros((n, 4, 6))
    for time in (0.0, 3e-3):
        K.wall_candidates(x, rad, W, tri, time, skin, np.array([0, n]), near, wslot, whist)
        want = near_by_measuring(x, rad, W, tri, time, skin)
        np.testing.assert_array_equal(near, want)
        assert 100 < want[:, 1].sum() < n - 100
