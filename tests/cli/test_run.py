import json

import pytest

from bedstruct.cli import main


def test_help(capsys):
    with pytest.raises(SystemExit) as e:
        main(["run", "--help"])
    assert e.value.code == 0
    assert "repose" in capsys.readouterr().out


def test_needs_config_or_preset(tmp_path, capsys):
    assert main(["run", "repose", "--out", str(tmp_path)]) == 2   # a usage error
    assert "--preset" in capsys.readouterr().err


def test_bad_override_names_the_key(tmp_path, capsys):
    assert main(["run", "spread", "--preset", "tiny", "--set", "spread.speed=fast",
                 "--out", str(tmp_path)]) == 1
    assert "spread.speed" in capsys.readouterr().err


@pytest.mark.parametrize("engine", ["liggghts", "lammps"])
def test_external_roller_deck_is_written(tmp_path, capsys, engine):
    # --write-only needs no engine installed: one deck for all layers, with a spinning roller
    assert main(["run", "spread", "--preset", "tiny", "--engine", engine, "--set", "spread.tool=roller",
                 "--write-only", "--out", str(tmp_path)]) == 0
    assert "deck written" in capsys.readouterr().out
    deck = (tmp_path / "in.spread").read_text()
    assert "rotate" in deck
    if engine == "liggghts":
        assert (tmp_path / "tool.stl").exists()
        assert "move/mesh" in deck
    else:
        assert "cylinder" in deck


def test_repose_json(tmp_path, capsys):
    rc = main(["run", "repose", "--preset", "tiny", "--set", "repose.drain_time=0.02",
               "--out", str(tmp_path), "--json"])
    assert rc == 0
    captured = capsys.readouterr()
    # with --json stdout is the JSON alone; the result in words and the page go to stderr
    (line,) = captured.out.strip().splitlines()
    d = json.loads(line)
    err = captured.err.strip().splitlines()
    assert err[-1] == f"summary: {tmp_path}/summary.html"
    page = (tmp_path / "summary.html").read_text()
    assert "bed pictured" in page and "rep00/pile.dump.gz" in page and "Side view" in page
    assert 5 < d["angle_deg"] < 60 and d["angle_std_deg"] > 0
    # the +- says what it is: with one pile (tiny) the flank fit's uncertainty, not a scatter
    said = [ln for ln in err if "angle of repose" in ln][0]
    assert len(d["replicates"]) == 1 and "one pile" in said and "not a scatter" in said
    assert json.loads((tmp_path / "results.json").read_text())["angle_deg"] == pytest.approx(d["angle_deg"])


def test_spread_summary_never_prints_nan(tmp_path, capsys):
    # the tiny platform is too short for a heap with a free toe: the summary must say so
    rc = main(["run", "spread", "--preset", "tiny", "--set", "spread.gaps=[4.5e-4]",
               "--out", str(tmp_path), "--json"])
    assert rc == 0
    captured = capsys.readouterr()
    line = [ln for ln in captured.err.splitlines() if ln.startswith("layer 1:")][0]
    assert "nan" not in line.lower()
    assert "not measurable" in line or line.rstrip().endswith(" deg")
    (only,) = captured.out.strip().splitlines()
    d = json.loads(only)
    angle = d["mean_dynamic_angle_deg"][0]
    assert angle is None or 0 < angle < 90


def test_failed_external_engine_is_one_error_line(tmp_path, capsys):
    rc = main(["run", "repose", "--preset", "tiny", "--engine", "liggghts", "--exe", "/bin/false",
               "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1
    assert err[-1].startswith("bedstruct run: error: liggghts failed") and "Traceback" not in err[0]


def test_calibrate_progress_is_passed_on(tmp_path, monkeypatch):
    # `bedstruct run calibrate --progress` was accepted and dropped
    import bedstruct.workflows as wf
    from bedstruct.workflows import CalibrationResult
    seen = {}

    def fake(cfg, **kw):
        seen.update(kw)
        return CalibrationResult(cohesion=1e3, cohesion_std=1.0, target_deg=30.0,
                                 slope_deg_per_unit=1e-3, converged=True, bracketed=True,
                                 curve=(), n_runs=0)
    monkeypatch.setattr(wf, "calibrate_cohesion", fake)
    assert main(["run", "calibrate", "--preset", "tiny", "--progress", "--out",
                 str(tmp_path)]) == 0
    assert seen["progress"] is True and seen["overwrite"] is False


def test_a_folder_of_another_configuration_needs_overwrite(tmp_path, capsys):
    args = ["run", "repose", "--preset", "tiny", "--set", "repose.drain_time=0.01",
            "--set", "repose.fill_time=0.01", "--out", str(tmp_path)]
    assert main(args) == 0
    first = json.loads((tmp_path / "results.json").read_text())
    capsys.readouterr()
    assert main(args) == 0                        # the same run again: reused at once
    assert "resumed the finished run" in capsys.readouterr().err
    assert json.loads((tmp_path / "results.json").read_text()) == first
    assert main(args + ["--set", "seed=2"]) == 1
    err = capsys.readouterr().err
    assert "`seed`: 1 in the folder, 2 now" in err and "--overwrite" in err
    assert json.loads((tmp_path / "results.json").read_text()) == first
    assert main(args + ["--set", "seed=2", "--overwrite"]) == 0
    assert json.loads((tmp_path / "run.json").read_text())["config"]["seed"] == 2
    assert json.loads((tmp_path / "results.json").read_text())["replicates"][0]["seed"] == 2


def test_sigterm_then_the_same_command_resumes(tmp_path):
    # the audit's case: a run killed with SIGTERM left no mark of being unfinished and
    # could not be resumed
    import signal
    import subprocess
    import sys
    import time
    out = tmp_path / "run"
    args = ["run", "spread", "--preset", "tiny", "--set", "spread.gaps=[4.5e-4]",
            "--set", "spread.n_frames=3", "--set", "spread.pile_particles=300",
            "--set", "spread.pile_time=0.004", "--set", "spread.plate_length=1.2e-3",
            "--set", "spread.pile_length=0.6e-3", "--set", "output.checkpoint_every=1000",
            "--out", str(out)]
    proc = subprocess.Popen([sys.executable, "-m", "bedstruct", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    t0 = time.time()
    while not (out / "progress.npz").is_file():
        assert proc.poll() is None, proc.communicate()
        assert time.time() - t0 < 300
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    proc.communicate(timeout=60)
    assert proc.returncode == -signal.SIGTERM
    assert json.loads((out / "run.json").read_text())["status"] == "running"
    assert not (out / "results.json").exists()
    assert main(args) == 0
    assert json.loads((out / "run.json").read_text())["status"] == "complete"
    assert not (out / "progress.npz").exists()
    ref = tmp_path / "ref"
    assert main(args[:-1] + [str(ref)]) == 0
    a, b = (json.loads((d / "results.json").read_text()) for d in (out, ref))
    for d in (a, b):
        d.pop("extra")
        d["layers"][0].pop("wall_time")
    assert a == b


def _fake_replicates(monkeypatch, angles):
    from bedstruct.workflows import repose
    from bedstruct.workflows.repose_measure import ReposeReplicate

    def fake(cfg, *, seed, cohesion, layout=None, stage=""):
        a = angles[seed - 1]
        note = "" if a == a else "no pile formed: 1 of 797 particles drained"
        return ReposeReplicate(seed=seed, cohesion=cohesion, angle_deg=a, angle_std_deg=1.0,
                               left_deg=a, right_deg=a, n_inserted=797, n_remaining=796,
                               n_fallen=1, pile_height=1e-3, wall_time=0.0, stage=stage,
                               note=note)
    monkeypatch.setattr(repose, "repose_replicate", fake)


def test_repose_without_any_pile_says_why_and_fails(tmp_path, capsys, monkeypatch):
    _fake_replicates(monkeypatch, [float("nan")])
    rc = main(["run", "repose", "--preset", "tiny", "--out", str(tmp_path), "--json", "--no-3d"])
    captured = capsys.readouterr()
    assert rc == 1
    assert "no pile formed: 1 of 797 particles drained" in captured.err
    assert "nan" not in captured.out.splitlines()[0]
    d = json.loads(captured.out.strip().splitlines()[-1])
    assert d["n_measured"] == 0 and "rep00" in d["unmeasured"]


def test_repose_mean_says_how_many_piles_it_is_over(tmp_path, capsys, monkeypatch):
    nan = float("nan")
    _fake_replicates(monkeypatch, [30.0, nan, nan])
    rc = main(["run", "repose", "--preset", "tiny", "--set", "repose.replicates=3",
               "--out", str(tmp_path), "--json", "--no-3d"])
    captured = capsys.readouterr()
    assert rc == 0
    line = [ln for ln in captured.err.splitlines() if "piles" in ln][0]
    assert "mean of 1 of 3 piles (2 could not be measured: rep01: no pile formed" in line
    d = json.loads(captured.out.strip())
    assert d["n_measured"] == 1 and sorted(d["unmeasured"]) == ["rep01", "rep02"]


@pytest.mark.parametrize("assignment, key", [
    ("spread.blade_height=1e-4", "spread.blade_height"),
    ("spread.width=1e-4", "spread.width"),
    ("psd.d_max=70", "psd.d_max"),
    ("preset=small", "--preset"),
])
def test_bad_geometry_is_refused_before_anything_is_written(tmp_path, capsys, assignment, key):
    out = tmp_path / "run"
    assert main(["run", "spread", "--preset", "tiny", "--set", assignment, "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert key in err and f"--set {assignment}" in err
    assert not out.exists()
