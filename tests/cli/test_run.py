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
def test_external_engines_not_yet_supported(tmp_path, capsys, engine):
    # repose and one-layer blade spreading run on the external engines
    # (tests/workflows/test_external_engines.py); the roller does not
    assert main(["run", "spread", "--preset", "tiny", "--engine", engine, "--set", "spread.tool=roller",
                 "--out", str(tmp_path)]) == 1
    assert "roller" in capsys.readouterr().err


def test_repose_json(tmp_path, capsys):
    rc = main(["run", "repose", "--preset", "tiny", "--set", "repose.drain_time=0.02",
               "--out", str(tmp_path), "--json"])
    assert rc == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    d = json.loads(last)
    assert 5 < d["angle_deg"] < 60 and d["angle_std_deg"] > 0
    assert json.loads((tmp_path / "results.json").read_text())["angle_deg"] == pytest.approx(d["angle_deg"])
