"""Engine robustness: time-step settings, blow-ups, units of the dumps, resumed output,
and external engine runs ended by SIGTERM."""

import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from bedstruct import Box, UnsafeTimestepError
from bedstruct.dem import ContactModel, Material, Plane, Simulation
from bedstruct.errors import ConfigError

MODEL = ContactModel(Material(1e6, 0.3, 8300.0), restitution=0.5, friction=0.4,
                     rolling_friction=0.05)


def _bed(n=150, seed=1, **kw):
    box = Box([0, 0, 0], [1e-3, 1e-3, 2e-3], boundary="pp pp ff")
    sim = Simulation(box, MODEL, walls=[Plane((0, 0, 0), (0, 0, 1), name="floor")], n_threads=1,
                     seed=seed, **kw)
    sim.insert_raindrop(n, {10: 80e-6, 50: 100e-6, 90: 120e-6},
                        region=((0, 0, 0), (1e-3, 1e-3, 2e-3)))
    return sim


# ------------------------------------------------------------------ time step settings
@pytest.mark.parametrize("safety", [0.31, 2.0, 5.0])
def test_default_step_above_the_rayleigh_limit_is_refused(safety):
    # it ran at 2 t_R, lost particles silently, and a repose run gave an angle of nan
    with pytest.raises(UnsafeTimestepError, match="safety"):
        _bed(safety=safety, v_max=1e-6)


@pytest.mark.parametrize("kw, key", [({"safety": 0.0}, "safety"), ({"safety": -0.1}, "safety"),
                                     ({"safety": float("nan")}, "safety"),
                                     ({"v_max": 0.0}, "v_max"), ({"v_max": -1.0}, "v_max"),
                                     ({"max_rayleigh_fraction": 0.0}, "max_rayleigh_fraction")])
def test_time_step_settings_are_checked(kw, key):
    with pytest.raises(ConfigError, match=f"`{key}`"):
        _bed(**kw)


def test_default_time_step_needs_a_positive_v_max():
    with pytest.raises(ConfigError, match="v_max"):
        Simulation.default_time_step(MODEL, 1e-4, 0.0)   # was a ZeroDivisionError


def test_a_forced_large_safety_still_runs_with_a_warning(caplog):
    sim = _bed(n=20, safety=0.5, force=True)
    sim.run(5)
    assert sim.dt == pytest.approx(min(0.5 * sim.t_rayleigh, 0.1 * sim.t_hertz))
    assert "accepted because force=True" in caplog.text


# ------------------------------------------------------------------ blow-ups
def _poison(sim, k=3):
    sim.run(10)
    sim.x[:k, 2] = np.nan


def test_nonfinite_particles_raise_and_are_not_removals():
    from bedstruct.dem import NumericalInstabilityError
    sim = _bed()
    _poison(sim)
    with pytest.raises(NumericalInstabilityError, match="non-finite.*blew up"):
        sim.run(200)
    assert sim.n_lost_nonfinite == 3 and sim.n_removed == 0


def test_nonfinite_particles_dropped_on_request_are_counted_apart(caplog):
    from bedstruct.errors import BedstructWarning
    sim = _bed(nonfinite="drop")
    n0 = sim.n_particles
    _poison(sim)
    with pytest.warns(BedstructWarning, match="non-finite"):
        stats = sim.run(200)
    assert sim.n_lost_nonfinite == 3 and stats.n_lost_nonfinite == 3
    assert sim.n_removed == 0 and stats.n_removed == 0      # not "left the domain"
    assert sim.n_particles == n0 - 3 and np.isfinite(sim.x).all()
    assert "blew up" in caplog.text


def test_nonfinite_count_survives_a_checkpoint(tmp_path):
    sim = _bed(nonfinite="drop")
    _poison(sim, 2)
    with pytest.warns(Warning):
        sim.run(100)
    res = Simulation.from_checkpoint(sim.save_checkpoint(tmp_path / "c.npz"))
    assert res.n_lost_nonfinite == 2 and res.nonfinite == "drop"


def test_bad_nonfinite_option():
    with pytest.raises(ConfigError, match="nonfinite"):
        _bed(nonfinite="ignore")


# ------------------------------------------------------------------ run directory output
def test_engine_dumps_carry_si_units(tmp_path):
    from bedstruct.io import read_dump
    sim = _bed(n=40)
    sim.run(20, dump_every=10, run_dir=tmp_path / "run")
    frames = read_dump(tmp_path / "run" / "dump.liggghts")
    assert len(frames) == 2 and all(f.units.style == "si" for f in frames)


def _outputs(d):
    return {name: (d / name).read_bytes() for name in ("dump.liggghts", "contacts.local",
                                                         "walls.jsonl")}


def test_resumed_run_directory_equals_an_uninterrupted_one(tmp_path):
    # an interrupted run resumed from its checkpoint wrote the frames past the checkpoint
    # twice (dump timesteps 100, 200, 300, 300, 400)
    from bedstruct.io import read_dump
    ref = _bed()
    ref.run(400, run_dir=tmp_path / "ref", dump_every=100)

    class Stop(Exception):
        pass

    def stop(s):
        if s.step == 350:
            raise Stop

    sim = _bed()
    with pytest.raises(Stop):
        sim.run(400, run_dir=tmp_path / "int", dump_every=100, checkpoint_every=200, callback=stop)
    res = Simulation.from_checkpoint(tmp_path / "int" / "checkpoint.npz")
    assert res.step == 200
    res.run(400 - res.step, run_dir=tmp_path / "int", dump_every=100, checkpoint_every=200)
    assert [f.timestep for f in read_dump(tmp_path / "int" / "dump.liggghts")] == [100, 200, 300,
                                                                                   400]
    assert _outputs(tmp_path / "int") == _outputs(tmp_path / "ref")


def test_a_resumed_simulation_writing_elsewhere_truncates_nothing(tmp_path):
    sim = _bed(n=40)
    sim.run(20, run_dir=tmp_path / "a", dump_every=10, checkpoint_every=10)
    other = tmp_path / "b"
    sim.run(20, run_dir=other, dump_every=10)
    before = _outputs(other)
    res = Simulation.from_checkpoint(tmp_path / "a" / "checkpoint.npz")
    res.run(10, run_dir=other, dump_every=10)
    after = _outputs(other)
    assert all(after[k].startswith(before[k]) and len(after[k]) > len(before[k]) for k in before)


def test_wall_load_average_survives_a_checkpoint(tmp_path):
    ref = _bed()
    ref.run(50)
    ref.start_wall_load_average()
    ref.run(100)
    sim = _bed()
    sim.run(50)
    sim.start_wall_load_average()
    sim.run(40)
    res = Simulation.from_checkpoint(sim.save_checkpoint(tmp_path / "c.npz"))
    assert [w.force.tolist() for w in res.wall_states()] == \
        [w.force.tolist() for w in sim.wall_states()]
    res.run(60)
    assert np.array_equal(res.wall_load_average()["floor"], ref.wall_load_average()["floor"])


def test_checkpoint_keeps_extra_data(tmp_path):
    sim = _bed(n=10)
    sim.run(3)
    res = Simulation.from_checkpoint(sim.save_checkpoint(tmp_path / "c.npz",
                                                         extra={"stage": {"seg": 4}}))
    assert res.checkpoint_extra == {"stage": {"seg": 4}}


# ------------------------------------------------------------------ external engines: SIGTERM
def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/status") as fh:
            state = [ln for ln in fh if ln.startswith("State:")][0]
        return "Z" not in state.split()[1]
    except (FileNotFoundError, IndexError):
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="process groups, /proc")
def test_sigterm_ends_the_engine_run_too(tmp_path):
    # SIGTERM to `bedstruct run ... --engine liggghts` left LIGGGHTS running (orphaned)
    fake = tmp_path / "liggghts"
    pids = tmp_path / "pids"
    fake.write_text(textwrap.dedent(f"""\
        #!/bin/sh
        sleep 300 &
        echo $$ $! > {pids}
        wait
        """))
    fake.chmod(0o755)
    deck = tmp_path / "in.deck"
    deck.write_text("# bedstruct deck for liggghts\n")
    driver = tmp_path / "driver.py"
    driver.write_text(textwrap.dedent(f"""\
        from bedstruct.engines import EngineInfo, run_deck
        run_deck({str(deck)!r}, engine=EngineInfo("liggghts", {str(fake)!r}))
        """))
    proc = subprocess.Popen([sys.executable, str(driver)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    t0 = time.time()
    while not (pids.is_file() and len(pids.read_text().split()) == 2):
        assert time.time() - t0 < 60 and proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    engine_pids = [int(p) for p in pids.read_text().split()]
    assert all(_alive(p) for p in engine_pids)
    proc.send_signal(signal.SIGTERM)
    proc.communicate(timeout=30)
    assert proc.returncode in (-signal.SIGTERM, 128 + signal.SIGTERM)
    t0 = time.time()
    while any(_alive(p) for p in engine_pids) and time.time() - t0 < 10:
        time.sleep(0.05)
    assert not any(_alive(p) for p in engine_pids), "the engine outlived bedstruct"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="process groups, /proc")
def test_engine_timeout_ends_the_whole_process_group(tmp_path):
    from bedstruct.engines import EngineInfo, EngineRunError, run_deck
    fake = tmp_path / "liggghts"
    pids = tmp_path / "pids"
    fake.write_text(f"#!/bin/sh\nsleep 300 &\necho $! > {pids}\nwait\n")
    fake.chmod(0o755)
    deck = tmp_path / "in.deck"
    deck.write_text("# bedstruct deck for liggghts\n")
    with pytest.raises(EngineRunError, match="timed out"):
        run_deck(deck, engine=EngineInfo("liggghts", str(fake)), timeout=1.0)
    child = int(pids.read_text())
    t0 = time.time()
    while _alive(child) and time.time() - t0 < 10:
        time.sleep(0.05)
    assert not _alive(child)


@pytest.mark.parametrize("kw, key", [({"skin": -5e-6}, "skin"), ({"skin": float("nan")}, "skin"),
                                     ({"min_radius": 0.0}, "min_radius"),
                                     ({"min_radius": -1e-5}, "min_radius"),
                                     ({"min_radius": float("inf")}, "min_radius")])
def test_skin_and_min_radius_are_checked(kw, key):
    # a negative skin let two spheres meeting head-on pass through each other; NaN crashed
    with pytest.raises(ConfigError, match=f"`{key}`"):
        Simulation(Box([0, 0, 0], [1e-3, 1e-3, 1e-3], boundary="ff ff ff"), MODEL, **kw)


def _small_pair(sim, r=5e-6):
    """Two spheres of radius r closing at 0.1 m/s in the middle of a 4 mm box."""
    c = 2e-3
    sim.add_particles([[c - 1.2 * r, c, c], [c + 1.2 * r, c, c]], r,
                      velocities=[[0.05, 0, 0], [-0.05, 0, 0]])


def _free(**kw):
    return Simulation(Box([0, 0, 0], [4e-3, 4e-3, 4e-3], boundary="ff ff ff"), MODEL,
                      gravity=(0, 0, 0), n_threads=1, **kw)


def test_spheres_smaller_than_the_planned_step_are_refused():
    # the step was planned for r = 200 um at the first run; 5 um spheres added later were
    # stepped at 6 Rayleigh times and gained energy
    sim = _free()
    sim.add_particles([[0.5e-3, 0.5e-3, 0.5e-3]], 200e-6)
    sim.run(5)
    _small_pair(sim)
    with pytest.raises(UnsafeTimestepError, match="smallest sphere present"):
        sim.run(5)
    sim = _free(min_radius=200e-6)      # a min_radius above the spheres present
    _small_pair(sim)
    with pytest.raises(UnsafeTimestepError, match="planned for r = 0.0002"):
        sim.run(5)


def test_spheres_within_the_planned_step_limits_run():
    sim = _free(min_radius=5e-6, v_max=0.05)
    sim.add_particles([[0.5e-3, 0.5e-3, 0.5e-3]], 200e-6)
    sim.run(5)
    _small_pair(sim, r=4e-6)            # smaller than planned, the step still within limits
    sim.run(5)
    assert sim.dt < sim.max_rayleigh_fraction * MODEL.rayleigh_time(4e-6)
    assert sim.dt < 0.1 * MODEL.hertz_time(4e-6, 0.05)


def test_a_forced_step_warns_once_for_smaller_spheres(caplog):
    sim = _free(force=True)
    sim.add_particles([[0.5e-3, 0.5e-3, 0.5e-3]], 200e-6)
    sim.run(2)
    _small_pair(sim)
    sim.run(2)
    sim.run(2)
    assert caplog.text.count("planned for r = 0.0002 m") == 1


def test_a_wall_faster_than_v_max_is_checked_at_its_speed(caplog):
    # the step was planned for impacts at v_max = 0.1 m/s; a floor thrown up at 50 m/s
    # hits the sphere within fewer than 10 steps of its Hertz time
    model = ContactModel(Material(1e7, 0.3, 2500.0))

    def sim_with_floor(speed, **kw):
        sim = Simulation(Box([0, 0, 0], [2e-3] * 3), model, walls=[Plane((0, 0, 0), (0, 0, 1),
                         name="floor")], v_max=0.1, n_threads=1, **kw)
        sim.add_particles([[1e-3, 1e-3, 1e-3]], [1e-4])
        sim.run(1)
        sim.set_wall_motion("floor", velocity=(0.0, 0.0, speed))
        return sim
    with pytest.raises(UnsafeTimestepError, match=r"a wall moves at 50 m/s.*v_max >= the"):
        sim_with_floor(50.0).run(1)
    assert sim_with_floor(50.0).dt > 0.1 * model.hertz_time(1e-4, 50.0)
    sim = sim_with_floor(5.0)             # faster than v_max, the step still within limits
    sim.run(2)
    assert sim.dt < 0.1 * model.hertz_time(1e-4, 5.0)
    sim = sim_with_floor(50.0, force=True)
    sim.run(1)
    sim.run(1)
    assert caplog.text.count("a wall moves at 50 m/s") == 1


@pytest.mark.parametrize("ids", [[1, 2 ** 31 + 5], [2 ** 31, 3]])
def test_ids_that_would_share_a_history_key_are_refused(ids):
    # pairs (1, 2^31 + 5) and (2, 5) had the same key: one took the other's history
    sim = _free()
    with pytest.raises(ValueError, match="below 2\\^31"):
        sim.add_particles([[1e-3, 1e-3, 1e-3], [3e-3, 3e-3, 3e-3]], 50e-6, ids=ids)
    sim.add_particles([[1e-3, 1e-3, 1e-3], [3e-3, 3e-3, 3e-3]], 50e-6, ids=[1, 2 ** 31 - 1])


def test_wall_overflow_counts_every_step_of_a_run_and_survives_a_checkpoint(tmp_path):
    # a sphere pressed by four planes has one wall contact without a history slot at each
    # step; a fast sphere far away forces neighbour rebuilds, which reset the count before
    r = 50e-6
    d = r - 2e-6
    walls = [Plane((0, 0, -d), (0, 0, 1), name="p1"), Plane((-d, 0, 0), (1, 0, 0), name="p2"),
             Plane((0, -d, 0), (0, 1, 0), name="p3"), Plane((d, 0, 0), (-1, 0, 0), name="p4")]
    sim = Simulation(Box([-2e-3] * 3, [2e-3] * 3, boundary="ff ff ff"), MODEL, walls=walls,
                     gravity=(0, 0, 0), n_threads=1)
    sim.add_particles([[0, 0, 0], [1.5e-3, 1.5e-3, 1.5e-3]], r, velocities=[[0, 0, 0], [0, 0, -1.0]])
    sim.run(100)
    assert sim.n_rebuilds > 2
    assert sim.wall_overflow >= 100
    sim.run(100)
    assert sim.wall_overflow >= 200
    before = sim.wall_overflow
    sim.save_checkpoint(tmp_path / "c.npz")
    assert Simulation.from_checkpoint(tmp_path / "c.npz").wall_overflow == before
