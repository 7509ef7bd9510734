"""Run folders: killed runs resume from their checkpoints (the result is an uninterrupted
run's, bit for bit, and so are the files), folders of another configuration are refused
unless overwritten, and a stale results.json never sits beside a new configuration."""

import json

import numpy as np
import pytest

from bedstruct.dem import Simulation
from bedstruct.errors import ConfigError
from bedstruct.io import read_dump
from bedstruct.workflows import load_config, run_repose, run_spread

from _runfiles import run_files, without_times

SPREAD = ["spread.gaps=[4.5e-4, 3e-4]", "spread.n_frames=3", "spread.pile_particles=300",
          "spread.pile_time=0.004", "spread.plate_length=1.2e-3", "spread.pile_length=0.6e-3",
          "output.checkpoint_every=1500"]
REPOSE = ["repose.replicates=2", "repose.fill_time=0.01", "repose.drain_time=0.01",
          "output.checkpoint_every=1000"]


class Killed(BaseException):
    """Stands for a kill: nothing in the workflows catches it."""


def kill_when(monkeypatch, cond):
    """Raise Killed after the first Simulation.run call after which ``cond(sim)`` holds."""
    orig = Simulation.run

    def run(self, *a, **kw):
        stats = orig(self, *a, **kw)
        if cond(self):
            raise Killed(self.step)
        return stats
    monkeypatch.setattr(Simulation, "run", run)


def _files(root):
    return run_files(root)


@pytest.fixture(scope="module")
def spread_ref(tmp_path_factory):
    cfg = load_config(preset="tiny", overrides=SPREAD)
    out = tmp_path_factory.mktemp("ref")
    return cfg, run_spread(cfg, out=out), out


def test_killed_spread_resumes_to_the_uninterrupted_result(spread_ref, tmp_path, monkeypatch):
    cfg, ref, ref_out = spread_ref
    out = tmp_path / "run"
    prog, pile_prog = out / "progress.npz", out / "pile" / "progress.npz"
    # killed while the pile settles (after its first checkpoint), inside layer 1's stroke,
    # and inside layer 2: each time the same command goes on from the latest checkpoint
    kills = [lambda s: "floor" in s.wall_names and pile_prog.is_file(),
             lambda s: "tool" in s.wall_names and s.step > 4000 and prog.is_file(),
             lambda s: "tool" in s.wall_names and s.step > 16000]
    for cond in kills:
        with monkeypatch.context() as m:
            kill_when(m, cond)
            with pytest.raises(Killed):
                run_spread(cfg, out=out)
        # an unfinished run: marked so, and no results
        assert json.loads((out / "run.json").read_text())["status"] == "running"
        assert not (out / "results.json").exists()
    assert prog.is_file()
    res = run_spread(cfg, out=out)
    assert without_times(res.to_dict()) == without_times(ref.to_dict())
    assert _files(out) == _files(ref_out)            # frames, contacts, walls, beds: equal
    assert not prog.exists() and not pile_prog.exists()
    assert json.loads((out / "run.json").read_text())["status"] == "complete"
    assert without_times(json.loads((out / "results.json").read_text())) == \
        without_times(json.loads((ref_out / "results.json").read_text()))


def test_finished_spread_is_reused_not_run_again(spread_ref, monkeypatch):
    cfg, ref, out = spread_ref
    kill_when(monkeypatch, lambda s: True)   # any simulation step would fail the test
    res = run_spread(cfg, out=out)
    assert res == ref or without_times(res.to_dict()) == without_times(ref.to_dict())
    assert json.loads((out / "run.json").read_text())["status"] == "complete"


def test_engine_dumps_of_a_run_carry_si_units(spread_ref):
    _, _, out = spread_ref
    for path in (out / "layer01" / "frames.dump.gz", out / "layer01" / "bed.dump.gz",
                 out / "layer02" / "final.dump.gz", out / "pile" / "pile.dump.gz"):
        assert all(f.units.style == "si" for f in read_dump(path)), path


def test_another_configuration_is_refused_and_overwrite_replaces_it(tmp_path, monkeypatch):
    # the audit's case: a finished seed-1 run, then a seed-2 run killed in the same folder
    # left config.toml saying seed 2 beside seed 1's results.json and layers
    cfg = load_config(preset="tiny", overrides=SPREAD + ["spread.gaps=[4.5e-4]"])
    out = tmp_path / "run"
    run_spread(cfg, out=out)
    before = _files(out)
    other = load_config(preset="tiny", overrides=SPREAD + ["spread.gaps=[4.5e-4]", "seed=2"])
    with pytest.raises(ConfigError, match=r"`seed`: 1 in the folder, 2 now.*--overwrite"):
        run_spread(other, out=out)
    assert _files(out) == before and (out / "results.json").is_file()
    with monkeypatch.context() as m:
        kill_when(m, lambda s: "tool" in s.wall_names)
        with pytest.raises(Killed):
            run_spread(other, out=out, overwrite=True)
    assert not (out / "results.json").exists()
    marker = json.loads((out / "run.json").read_text())
    assert marker["status"] == "running" and marker["config"]["seed"] == 2
    assert "seed = 2" in (out / "config.toml").read_text()
    assert not (out / "layer01" / "bed.dump.gz").exists()   # seed 1's layer is gone
    res = run_spread(other, out=out)
    assert json.loads((out / "results.json").read_text())["layers"][0]["n_bed"] == \
        res.layers[0].n_bed


def test_checkpoint_settings_may_change_on_resume(tmp_path, monkeypatch):
    cfg = load_config(preset="tiny", overrides=SPREAD + ["spread.gaps=[4.5e-4]"])
    out = tmp_path / "run"
    with monkeypatch.context() as m:
        kill_when(m, lambda s: "tool" in s.wall_names and (out / "progress.npz").is_file())
        with pytest.raises(Killed):
            run_spread(cfg, out=out)
    more = load_config(preset="tiny", overrides=SPREAD + ["spread.gaps=[4.5e-4]",
                                                          "output.checkpoint=true",
                                                          "output.checkpoint_every=700"])
    run_spread(more, out=out)
    assert (out / "layer01" / "checkpoint.npz").is_file()


def test_an_external_engine_run_may_resume_with_another_timeout(tmp_path):
    # an engine run that timed out is resumed with more time; a marker written before the
    # timeout was free to change (it names it) is resumed too
    from bedstruct.workflows import RunLayout
    cfg = load_config(preset="tiny", overrides=["engine=liggghts", "external.timeout=60"])
    RunLayout(tmp_path, cfg, workflow="spread").release()
    marker = json.loads((tmp_path / "run.json").read_text())
    assert "timeout" not in marker["config"]["external"]
    marker["config"]["external"]["timeout"] = 60.0
    (tmp_path / "run.json").write_text(json.dumps(marker))
    more = load_config(preset="tiny", overrides=["engine=liggghts", "external.timeout=0"])
    assert RunLayout(tmp_path, more, workflow="spread").resumed
    with pytest.raises(ConfigError, match="`external.np`"):
        RunLayout(tmp_path, load_config(preset="tiny", overrides=["engine=liggghts",
                                                                  "external.np=2"]),
                  workflow="spread")


def test_a_folder_whose_run_has_an_effects_section_is_refused_naming_the_options(tmp_path):
    """A run folder written with the [effects] section: its marker is refused, each of its
    effect keys named with the option that holds it (nothing is translated)."""
    from bedstruct.workflows import RunLayout
    cfg = load_config(preset="tiny")
    RunLayout(tmp_path, cfg, workflow="repose").release()
    marker = json.loads((tmp_path / "run.json").read_text())
    marker["config"]["effects"] = {"wall_friction_excess": 0.0, "blade_ramp_time": 0.0}
    (tmp_path / "run.json").write_text(json.dumps(marker))
    with pytest.raises(ConfigError, match=r"run.json: the folder's run has config section "
                       r"`effects`.*effects.wall_friction_excess -> contact.wall_friction.*"
                       r"effects.blade_ramp_time -> spread.ramp_time.*--overwrite"):
        RunLayout(tmp_path, cfg, workflow="repose")


def test_legacy_folder_of_another_configuration_is_refused(tmp_path):
    from bedstruct.workflows import config_to_toml
    (tmp_path / "config.toml").write_text(config_to_toml(load_config(preset="tiny")))
    (tmp_path / "results.json").write_text("{}")
    with pytest.raises(ConfigError, match="`contact.friction`"):
        run_repose(load_config(preset="tiny", overrides=["contact.friction=0.6"]), out=tmp_path)


def test_killed_repose_reuses_finished_replicates(tmp_path, monkeypatch):
    import bedstruct.workflows.repose as repose
    cfg = load_config(preset="tiny", overrides=REPOSE)
    ref = run_repose(cfg, out=tmp_path / "ref")
    out = tmp_path / "run"
    with monkeypatch.context() as m:  # killed inside the second replicate, after a checkpoint
        kill_when(m, lambda s: (out / "rep01" / "progress.npz").is_file())
        with pytest.raises(Killed):
            run_repose(cfg, out=out)
    assert (out / "rep00" / "result.json").is_file()
    assert not (out / "rep01" / "result.json").exists()
    assert not (out / "results.json").exists()
    seeds = []
    orig = repose.repose_replicate

    def counting(cfg, *, seed, **kw):
        seeds.append(seed)
        return orig(cfg, seed=seed, **kw)
    monkeypatch.setattr(repose, "repose_replicate", counting)
    res = run_repose(cfg, out=out)
    assert seeds == [int(cfg["seed"]) + 1]           # the finished replicate is not run again
    assert without_times(res.to_dict()) == without_times(ref.to_dict())
    assert _files(out) == _files(tmp_path / "ref")
    assert not (out / "rep01" / "progress.npz").exists()


def test_repose_counts_particles_lost_while_the_box_fills(tmp_path, monkeypatch):
    # n_inserted was the number present after filling: particles lost during the fill
    # were missing from it, and inserted != remaining + fallen
    orig = Simulation.insert_raindrop

    def leaky(self, n, psd, **kw):
        placed = orig(self, n, psd, **kw)
        self.x[-5:, 2] = self.box.lo[2] - 1e-3   # five of them leave through the floor
        return placed
    monkeypatch.setattr(Simulation, "insert_raindrop", leaky)
    cfg = load_config(preset="tiny", overrides=["repose.replicates=1", "repose.fill_time=0.01",
                                                "repose.drain_time=0.01"])
    rep = run_repose(cfg).replicates[0]
    assert rep.n_inserted == rep.n_remaining + rep.n_fallen + rep.n_lost_nonfinite
    assert rep.n_fallen >= 5


def test_killed_calibration_reuses_its_points(tmp_path, monkeypatch):
    import bedstruct.workflows.repose as repose
    from bedstruct.workflows import ReposeReplicate, calibrate_cohesion

    calls = []

    def fake(cfg, *, seed, cohesion, layout=None, stage=""):
        calls.append((cohesion, seed))
        if len(calls) == limit[0]:
            raise Killed
        a = 20.0 + 4e-3 * cohesion + 0.3 * (seed % 2)
        return ReposeReplicate(seed=seed, cohesion=cohesion, angle_deg=a, angle_std_deg=0.5,
                               left_deg=a, right_deg=a, n_inserted=10, n_remaining=10,
                               n_fallen=0, pile_height=1e-3, wall_time=0.0, stage=stage)
    monkeypatch.setattr(repose, "repose_replicate", fake)
    cfg = load_config(preset="tiny", overrides=["calibrate.cohesion_bracket=[1000.0, 2000.0]",
                                                "calibrate.target_deg=30.5",
                                                "calibrate.max_iter=4"])
    limit = [0]
    ref = calibrate_cohesion(cfg, out=tmp_path / "ref")
    n_ref = len(calls)
    calls.clear()
    limit[0] = 5                                    # killed in the third point
    with pytest.raises(Killed):
        calibrate_cohesion(cfg, out=tmp_path / "run")
    assert len(json.loads((tmp_path / "run" / "points.json").read_text())["points"]) == 2
    calls.clear()
    limit[0] = 0
    res = calibrate_cohesion(cfg, out=tmp_path / "run")
    assert len(calls) == n_ref - 4                  # the four finished replicates were reused
    assert res.to_dict() == ref.to_dict()
    assert json.loads((tmp_path / "run" / "run.json").read_text())["status"] == "complete"
    with pytest.raises(ConfigError, match="target_deg"):
        calibrate_cohesion(cfg, out=tmp_path / "run", target_deg=30.0)


def test_results_json_is_written_atomically_last(tmp_path, monkeypatch):
    from bedstruct.workflows import RunLayout
    cfg = load_config(preset="tiny")
    lay = RunLayout(tmp_path, cfg, workflow="repose")
    assert json.loads((tmp_path / "run.json").read_text())["status"] == "running"
    lay.write_results({"x": float("nan")})
    assert json.loads((tmp_path / "results.json").read_text()) == {"x": None}
    assert json.loads((tmp_path / "run.json").read_text())["status"] == "complete"
    assert not list(tmp_path.glob(".*.tmp"))
    np.testing.assert_equal(RunLayout(tmp_path, cfg, workflow="repose").complete, True)


def test_a_config_toml_bedstruct_did_not_write_is_never_replaced(tmp_path):
    (tmp_path / "config.toml").write_text('[tool.something]\nx = 1\n')
    for overwrite in (False, True):
        with pytest.raises(ConfigError, match="not written by bedstruct"):
            run_repose(load_config(preset="tiny"), out=tmp_path, overwrite=overwrite)
    assert (tmp_path / "config.toml").read_text() == '[tool.something]\nx = 1\n'


def test_a_folder_another_process_writes_is_refused_until_it_ends(tmp_path):
    # two processes resuming or overwriting one run folder would interleave their stages;
    # the second is refused while the first holds the folder, also when the first is killed
    import signal
    import subprocess
    import sys
    from bedstruct.errors import RunFolderInUseError
    from bedstruct.workflows._rundir import RunLayout
    cfg = load_config(preset="tiny")
    out = tmp_path / "run"
    holder = subprocess.Popen(
        [sys.executable, "-c",
         "import sys, time; from bedstruct.workflows import load_config; "
         "from bedstruct.workflows._rundir import RunLayout; "
         f"l = RunLayout({str(out)!r}, load_config(preset='tiny'), workflow='repose'); "
         "print('held', flush=True); time.sleep(120)"],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(RunFolderInUseError, match=rf"{out}.*in use.*pid {holder.pid}"):
            RunLayout(out, cfg, workflow="repose")
        with pytest.raises(RunFolderInUseError):
            RunLayout(out, cfg, workflow="repose", overwrite=True)  # nothing is cleared
        assert json.loads((out / "run.json").read_text())["status"] == "running"
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait()
    first = RunLayout(out, cfg, workflow="repose")  # the kernel dropped the killed one's lock
    assert first.resumed
    again = RunLayout(out, cfg, workflow="repose")  # one process may reopen its own folder
    assert again.resumed
    first.write_results({"done": True})
    again.write_results({"done": True})
    assert not (out / ".bedstruct.lock").exists()  # a finished run leaves no lock file
    probe = subprocess.run(
        [sys.executable, "-c",
         "from bedstruct.workflows import load_config; "
         "from bedstruct.workflows._rundir import RunLayout; "
         f"RunLayout({str(out)!r}, load_config(preset='tiny'), workflow='repose')"],
        capture_output=True, text=True)
    assert probe.returncode == 0, probe.stderr  # released once the results are written
