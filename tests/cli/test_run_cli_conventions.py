"""`bedstruct run` follows the CLI conventions: a machine-clean --json, errors worded by the
flag typed, exit status 2 for options that do not fit together, a short --help."""

import json
from pathlib import Path

import pytest

from bedstruct.cli import main


def _fake_replicates(monkeypatch, angles):
    from bedstruct.workflows import repose
    from bedstruct.workflows.repose_measure import ReposeReplicate

    def fake(cfg, *, seed, cohesion, layout=None, stage=""):
        a = angles[seed - 1]
        return ReposeReplicate(seed=seed, cohesion=cohesion, angle_deg=a, angle_std_deg=1.0,
                               left_deg=a, right_deg=a, n_inserted=797, n_remaining=796,
                               n_fallen=1, pile_height=1e-3, wall_time=0.0, stage=stage,
                               note="")
    monkeypatch.setattr(repose, "repose_replicate", fake)


def test_repose_json_is_the_only_thing_on_stdout(tmp_path, capsys, monkeypatch):
    _fake_replicates(monkeypatch, [30.0])
    out = tmp_path / "run"
    args = ["run", "repose", "--preset", "tiny", "--out", str(out), "--json", "--no-3d"]
    assert main(args) == 0
    captured = capsys.readouterr()
    d = json.loads(captured.out)             # the whole of stdout is one JSON object
    assert captured.out.count("\n") == 1
    assert "angle of repose: 30.00" in captured.err
    assert d["angle_deg"] == pytest.approx(30.0)
    assert d["out"] == str(out) and d["resumed"] is False
    assert d["files"]["results"] == str(out / "results.json")
    assert all(Path(path).is_file() for path in d["files"].values())
    assert main(args) == 0                   # the same command again resumes
    d = json.loads(capsys.readouterr().out)
    assert d["resumed"] is True


def test_repose_without_json_prints_the_result_on_stdout(tmp_path, capsys, monkeypatch):
    _fake_replicates(monkeypatch, [30.0])
    assert main(["run", "repose", "--preset", "tiny", "--out", str(tmp_path), "--no-3d"]) == 0
    captured = capsys.readouterr()
    assert captured.out.startswith("angle of repose: 30.00")
    assert f"results: {tmp_path}/results.json" in captured.err


def test_write_only_json_is_machine_clean(tmp_path, capsys):
    out = tmp_path / "deck"
    assert main(["run", "spread", "--preset", "tiny", "--engine", "liggghts", "--write-only",
                 "--out", str(out), "--json"]) == 0
    captured = capsys.readouterr()
    d = json.loads(captured.out)
    assert "deck written" in captured.err and "deck written" not in captured.out
    assert d["out"] == str(out) and d["write_only"] is True and d["resumed"] is False
    assert d["files"]["decks"] == [str(out / "in.spread")]
    assert d["files"]["results"] == str(out / "results.json")


def test_calibrate_json_is_machine_clean(tmp_path, capsys, monkeypatch):
    import bedstruct.workflows as wf
    from bedstruct.workflows import CalibrationResult

    def fake(cfg, **kw):
        return CalibrationResult(cohesion=1e3, cohesion_std=1.0, target_deg=30.0,
                                 slope_deg_per_unit=1e-3, converged=True, bracketed=True,
                                 curve=(), n_runs=0)
    monkeypatch.setattr(wf, "calibrate_cohesion", fake)
    assert main(["run", "calibrate", "--preset", "tiny", "--out", str(tmp_path), "--json"]) == 0
    captured = capsys.readouterr()
    d = json.loads(captured.out)
    assert d["cohesion"] == 1e3 and d["out"] == str(tmp_path)
    assert "calibrated cohesion" in captured.err


@pytest.mark.parametrize("flags, said", [
    (["--np", "0"], "--np 0: must be >= 1"),
    (["--engine", "liggghts", "--np", "0"], "--np 0: must be >= 1"),
])
def test_flag_errors_name_the_flag(tmp_path, capsys, flags, said):
    assert main(["run", "spread", "--preset", "tiny", *flags, "--out", str(tmp_path / "x")]) == 1
    err = capsys.readouterr().err
    assert said in err and "--set" not in err and "external.np" not in err
    assert not (tmp_path / "x").exists()


def test_missing_engine_binary_names_exe(tmp_path, capsys):
    assert main(["run", "repose", "--preset", "tiny", "--engine", "liggghts", "--exe",
                 "/nonexistent/liggghts", "--out", str(tmp_path / "x")]) == 1
    err = capsys.readouterr().err
    assert "--exe /nonexistent/liggghts" in err and "external.exe" not in err


@pytest.mark.parametrize("argv", [
    ["run", "repose", "--out", "X"],
    ["run", "repose", "--preset", "tiny", "--write-only", "--out", "X"],
    ["run", "spread", "--preset", "tiny", "--engine", "embedded", "--write-only", "--out", "X"],
    ["run", "calibrate", "--preset", "tiny", "--write-only", "--out", "X"],
])
def test_options_that_do_not_fit_are_usage_errors(tmp_path, capsys, argv):
    argv = [str(tmp_path / "x") if a == "X" else a for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "bedstruct run: error:" in err
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("workflow", ["repose", "spread", "calibrate"])
def test_help_is_short(workflow, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "100")
    with pytest.raises(SystemExit) as e:
        main(["run", workflow, "--help"])
    assert e.value.code == 0
    text = capsys.readouterr().out
    assert len(text.splitlines()) < 35
    assert "docs/workflows.md" in text and f"bedstruct run {workflow} --help-config" in text
    assert "[material]" not in text                     # no config reference
    if workflow != "spread":
        assert "spread." not in text and f"{workflow}." in text
    if workflow == "calibrate":
        assert "--write-only" not in text and "--no-3d" not in text


@pytest.mark.parametrize("workflow, section, other", [
    ("repose", "[repose]", "[spread]"), ("spread", "[spread]", "[repose]"),
    ("calibrate", "[calibrate]", "[spread]")])
def test_help_config_prints_the_reference(workflow, section, other, capsys):
    with pytest.raises(SystemExit) as e:
        main(["run", workflow, "--help-config"])      # no --out needed
    assert e.value.code == 0
    text = capsys.readouterr().out
    assert section in text and "[material]" in text and "[external]" in text
    assert other not in text
