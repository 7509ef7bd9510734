"""A diagnosis served by a run library from the command line: answer, emulator check, reuse."""

from __future__ import annotations

import json
import pathlib

import numpy as np
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
"""
#: The same library, its recalibrated parameters varied by 20 % (not the default 25 %).
SIM_VARY = SIM + "vary = 0.2\n"


def test_diagnose_on_a_library_then_reuse_it(tmp_path, capsys):
    sim = tmp_path / "sim.toml"
    sim.write_text(SIM_VARY)
    lib = tmp_path / "lib"
    argv = ["diagnose", "--sim", str(sim), "--real", str(SEED), "--library", str(lib), "--json"]
    assert main([*argv, "--out", str(tmp_path / "a")]) == 0
    first = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert first["effect"] == "missing_fines" and first["library_runs"] > 0
    assert 0 < first["emulator_confirm_rmse_sigma"] < 5
    assert 0 <= first["emulator_confirm_within_2sigma"] <= 1
    full = json.loads((tmp_path / "a" / "diagnosis.json").read_text())
    assert full["emulator"]["library_runs"] == first["library_runs"]
    # the emulator's prediction against the confirming rerun, per observable component
    rows = full["emulator"]["confirm"]
    assert {r["observable"] for r in rows} >= {"static_angle", "psd_before"}
    z = np.array([(r["rerun"] - r["predicted"]) / r["predicted_sd"] for r in rows])
    np.testing.assert_allclose(z, [r["z"] for r in rows])
    assert full["emulator"]["confirm_rmse_sigma"] == pytest.approx(np.sqrt(np.mean(z ** 2)))
    assert full["emulator"]["confirm_within_2sigma"] == pytest.approx(np.mean(np.abs(z) <= 2))
    html = (tmp_path / "a" / "report.html").read_text(encoding="utf-8")
    assert '<section id="emulator">' in html and "emulator prediction" in html
    assert full["sim_config"]["library"] == {"n_base": 6, "n_per_effect": 6, "replicates": 2,
                                             "vary": 0.2}
    runs = sorted(p.name for p in (lib / "runs").iterdir())
    # a second diagnosis reuses the library: no run is added; its default output says in
    # one plain line how well the emulator predicted the simulator's rerun
    assert main([*argv[:-1], "--out", str(tmp_path / "b")]) == 0
    assert sorted(p.name for p in (lib / "runs").iterdir()) == runs
    check = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("Check:")]
    assert len(check) == 1 and "within 2 standard deviations of what the emulator" in check[0]
    assert "sigma" not in check[0] and "t=" not in check[0]
    # another design of the library is refused by name, not reused
    sim.write_text(SIM_VARY.replace("n_base = 6", "n_base = 7"))
    assert main([*argv, "--out", str(tmp_path / "c")]) == 1
    assert "library" in capsys.readouterr().err


def test_an_emulators_leave_one_out_error_is_shown_and_an_overconfident_one_is_not_trusted(
        tmp_path, capsys):
    """The plain output has a line with the emulator's leave-one-out error and the --json
    line ``emulator_loo_rmse_sigma``; an emulator far more confident than its runs allow
    (LOO error above 3) gives its answer with a caveat first and ``emulator_trusted`` false."""
    sim = tmp_path / "sim.toml"
    sim.write_text(SIM)
    lib = tmp_path / "lib"
    argv = ["diagnose", "--sim", str(sim), "--real", str(SEED), "--library", str(lib)]
    assert main([*argv, "--out", str(tmp_path / "a"), "--json"]) == 0
    good = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert 0.3 < good["emulator_loo_rmse_sigma"] < 3 and 0 < good["emulator_loo_within_2sigma"] <= 1
    assert good["emulator_trusted"] is True and "caveat" not in good
    # overconfident hyperparameters for the same runs: no noise, long length scales
    fit = json.loads((lib / "emulator.json").read_text())
    fit["theta"] = {k: [np.log(1e-3)] + [np.log(100.0)] * (len(v) - 2) + [np.log(1e-8)]
                    for k, v in fit["theta"].items()}
    (lib / "emulator.json").write_text(json.dumps(fit))
    assert main([*argv, "--out", str(tmp_path / "b")]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].startswith("NOT TO BE TRUSTED: the emulator is overconfident (its "
                               "leave-one-out error is ")
    loo = [ln for ln in lines if ln.startswith("Emulator: leave-one-out error ")]
    assert len(loo) == 1 and "of its stated uncertainty (" in loo[0]
    assert main([*argv, "--out", str(tmp_path / "c"), "--json"]) == 0
    bad = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert bad["emulator_loo_rmse_sigma"] > 3
    assert bad["emulator_trusted"] is False and bad["trusted"] is False
    assert bad["caveat"].startswith("the emulator is overconfident")
    full = json.loads((tmp_path / "c" / "diagnosis.json").read_text())["emulator"]
    assert full["trusted"] is False and full["caveat"] == bad["caveat"]


def test_library_options_are_checked(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[library]\nsize = 3\n")
    assert main(["diagnose", "--sim", str(bad), "--real", str(SEED), "--out", str(tmp_path)]) == 1
    assert "[library]: key 'size': unknown" in capsys.readouterr().err
    assert main(["diagnose", "--sim", "surrogate", "--real", str(SEED), "--out", str(tmp_path),
                 "--workers", "2"]) == 2
    assert "--library" in capsys.readouterr().err


def test_emulator_check_against_its_own_predictive_distribution(tmp_path):
    """The check's standardised error is N(0, 1) for runs drawn as the emulator predicts.

    Runs share one draw of the emulator's own error (its ``sd``) and add independent
    run noise (``noise_sd``): the mean of R of them departs from the prediction with
    standard deviation ``sqrt(sd**2 + noise_sd**2 / R)``, which the check must use.
    """
    from bedstruct.diagnose import (BASE_PARAMETERS, MeasurementSet, SurrogateSimulator,
                                    build_library, design_spec, fit_emulator,
                                    measurement_from_dict)
    m = measurement_from_dict({"name": "aor", "kind": "static_angle", "role": "calibrate",
                               "uncertainty": 0.5, "value": 33.0})
    sim = SurrogateSimulator(MeasurementSet((m,)))
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=6, n_per_effect=6)
    emu = fit_emulator(build_library(sim, spec, tmp_path, progress=False))
    point = {"wall_friction": 0.2}
    p = emu.predict({}, point)
    # exact prediction: no error; a mean 3 predictive sd off: z = 3
    exact = emu.check(np.tile(p.mean, (2, 1)), {}, point)
    assert exact.rmse_sigma == 0 and exact.within_2sigma == 1 and exact.n_runs == 2
    sd2 = np.sqrt(p.sd ** 2 + p.noise_sd ** 2 / 2)
    off = emu.check(np.tile(p.mean + 3 * sd2, (2, 1)), {}, point)
    np.testing.assert_allclose(off.z_mean, 3.0)
    assert off.within_2sigma == 0
    # a run that gave no value: the mean is of the runs that did
    one = emu.check(np.array([[np.nan], p.mean + np.sqrt(p.sd ** 2 + p.noise_sd ** 2)]), {}, point)
    np.testing.assert_allclose(one.z_mean, 1.0)
    # Monte Carlo: 4000 repetitions of a 3-run rerun drawn from the predictive model
    rng = np.random.default_rng(0)
    z = []
    for _ in range(4000):
        runs = p.mean + p.sd * rng.standard_normal() + p.noise_sd * rng.standard_normal((3, 1))
        z.append(emu.check(runs, {}, point).z_mean[0])
    z = np.asarray(z)
    assert abs(np.mean(z)) < 0.06 and abs(np.std(z) - 1.0) < 0.04
    assert abs(np.mean(np.abs(z) <= 2) - 0.954) < 0.015
    with pytest.raises(ValueError, match="emulator predicts 1"):
        emu.check(np.zeros((2, 3)), {}, point)
