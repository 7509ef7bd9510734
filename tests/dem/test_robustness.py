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
