import json

import pytest

from bedstruct.cli import main


def test_help(capsys):
    with pytest.raises(SystemExit) as e:
        main(["run", "--help"])
    assert e.value.code == 0
    assert "repose" in capsys.readouterr().out


def test_needs_config_or_preset(tmp_path, capsys):
    assert main(["run", "repose", "--out", str(tmp_path)]) == 1
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
    last = capsys.readouterr().out.strip().splitlines()[-1]
    d = json.loads(last)
    assert 5 < d["angle_deg"] < 60 and d["angle_std_deg"] > 0
    assert json.loads((tmp_path / "results.json").read_text())["angle_deg"] == pytest.approx(d["angle_deg"])


def test_spread_summary_never_prints_nan(tmp_path, capsys):
    # the tiny platform is too short for a heap with a free toe: the summary must say so
    rc = main(["run", "spread", "--preset", "tiny", "--set", "spread.gaps=[4.5e-4]",
               "--out", str(tmp_path), "--json"])
    assert rc == 0
    out = capsys.readouterr().out
    line = [ln for ln in out.splitlines() if ln.startswith("layer 1:")][0]
    assert "nan" not in line.lower()
    assert "not measurable" in line or line.rstrip().endswith(" deg")
    d = json.loads(out.strip().splitlines()[-1])
    angle = d["mean_dynamic_angle_deg"][0]
    assert angle is None or 0 < angle < 90


def test_failed_external_engine_is_one_error_line(tmp_path, capsys):
    rc = main(["run", "repose", "--preset", "tiny", "--engine", "liggghts", "--exe", "/bin/false",
               "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1
    assert err[-1].startswith("bedstruct run: error: liggghts failed") and "Traceback" not in err[0]
