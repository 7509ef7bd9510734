"""A diagnosis served by a run library from the command line: answer, emulator check, reuse."""

from __future__ import annotations

import json
import pathlib

import pytest

from bedstruct.cli import main

pytest.importorskip("sklearn")
SEED = pathlib.Path(__file__).resolve().parents[2] / "data" / "measurements" / "seed.toml"

SIM = """
[simulator]
kind = "surrogate"
replicates = 2

[catalogue]
effects = ["missing_fines", "wall_friction"]

[diagnosis]
refine = 0

[library]
n_base = 6
n_per_effect = 6
replicates = 2
vary = 0.2
"""


def test_diagnose_on_a_library_then_reuse_it(tmp_path, capsys):
    sim = tmp_path / "sim.toml"
    sim.write_text(SIM)
    lib = tmp_path / "lib"
    argv = ["diagnose", "--sim", str(sim), "--real", str(SEED), "--library", str(lib), "--json"]
    assert main([*argv, "--out", str(tmp_path / "a")]) == 0
    first = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert first["effect"] == "missing_fines" and first["library_runs"] > 0
    assert 0 < first["emulator_confirm_rmse_sigma"] < 5
    full = json.loads((tmp_path / "a" / "diagnosis.json").read_text())
    assert full["emulator"]["library_runs"] == first["library_runs"]
    assert full["sim_config"]["library"] == {"n_base": 6, "n_per_effect": 6, "replicates": 2,
                                             "vary": 0.2}
    runs = sorted(p.name for p in (lib / "runs").iterdir())
    # a second diagnosis reuses the library: no run is added
    assert main([*argv, "--out", str(tmp_path / "b")]) == 0
    assert sorted(p.name for p in (lib / "runs").iterdir()) == runs
    # another design of the library is refused by name, not reused
    sim.write_text(SIM.replace("n_base = 6", "n_base = 7"))
    assert main([*argv, "--out", str(tmp_path / "c")]) == 1
    assert "library" in capsys.readouterr().err


def test_library_options_are_checked(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[library]\nsize = 3\n")
    assert main(["diagnose", "--sim", str(bad), "--real", str(SEED), "--out", str(tmp_path)]) == 1
    assert "[library]: key 'size': unknown" in capsys.readouterr().err
    assert main(["diagnose", "--sim", "surrogate", "--real", str(SEED), "--out", str(tmp_path),
                 "--workers", "2"]) == 2
    assert "--library" in capsys.readouterr().err
