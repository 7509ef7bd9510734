"""The user's own engine model as the diagnosis' simulator: a workflow configuration file,
LIGGGHTS or LAMMPS with MPI ranks, and the catalogue effects an engine cannot realise
refused by name before any run."""

import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from bedstruct.diagnose import (MeasurementSet, diagnosis_design, load_sim_config,
                                make_simulator, measurement_from_dict)
from bedstruct.errors import ConfigError

MODEL = """\
preset = "tiny"
description = "my CoCr powder on my machine"
[material]
density = 7900.0
[contact]
friction = 0.45
"""

STATIC = {"name": "static_angle", "kind": "static_angle", "value": 33.0, "uncertainty": 1.0,
          "unit": "deg", "role": "calibrate", "conditions": {"box_width": 0.03}}


def _design():
    return MeasurementSet((measurement_from_dict(dict(STATIC)),))


def _sim_file(tmp_path, engine_table: str, catalogue: str = "") -> str:
    (tmp_path / "model.toml").write_text(MODEL)
    path = tmp_path / "my.sim.toml"
    path.write_text(f"""[simulator]
kind = "engine"
[engine]
{engine_table}
{catalogue}
""")
    return str(path)


def test_the_users_workflow_configuration_is_the_model_at_full_scale(tmp_path):
    cfg = load_sim_config(_sim_file(tmp_path, 'config = "model.toml"'))
    assert cfg.engine["config"] == str(tmp_path / "model.toml")   # relative to the sim file
    # the base point is the user's contact model unless [base] says otherwise
    from bedstruct.workflows import load_config
    tiny_cohesion = load_config(preset="tiny")["contact"]["cohesion"]
    assert cfg.base == {"cohesion_energy_density": tiny_cohesion, "friction": 0.45,
                        "rolling_friction": load_config(preset="tiny")["contact"]["rolling_friction"],
                        "restitution": load_config(preset="tiny")["contact"]["restitution"]}
    sim = make_simulator(cfg, diagnosis_design(_design(), cfg.effects))
    assert sim.run_config(cfg.base, {}, 0)["contact"]["cohesion"] == tiny_cohesion
    run = sim.run_config({"friction": 0.5}, {}, 3)
    assert run["material"]["density"] == 7900.0                    # the user's material
    assert run["contact"]["friction"] == 0.5                       # the base parameter on top
    over = load_sim_config(_sim_file(tmp_path, 'config = "model.toml"', "[base]\nfriction = 0.3"))
    assert over.base["friction"] == 0.3
    assert run["engine"] == "embedded"
    # their model is the machine: no scale model between the measurements and the runs
    for key in ("cohesion_scale", "speed_scale", "ageing_time_scale", "blade_time_scale",
                "fines_scale"):
        assert getattr(sim, key) == 1.0, key
    # a preset keeps the diagnosis' scale model (tiny: coarse-grained, faster blade)
    tiny = make_simulator(load_sim_config(_sim_file(tmp_path, 'preset = "tiny"')),
                          _design())
    assert tiny.cohesion_scale != 1.0 and tiny.ageing_time_scale == 1000.0


def test_an_engine_refuses_the_catalogue_effects_it_cannot_realise_by_name(tmp_path):
    cfg = load_sim_config(_sim_file(tmp_path, 'config = "model.toml"\nengine = "liggghts"\nnp = 2'))
    with pytest.raises(ConfigError) as err:
        make_simulator(cfg, diagnosis_design(_design(), cfg.effects))
    msg = str(err.value)
    assert "liggghts engine cannot realise" in msg
    assert "'contact_ageing'" in msg and "'blade_startup'" in msg
    # LIGGGHTS has easo bridges, but they skip the catalogue's humidity films
    assert "'capillary_bridges'" in msg and "volume" in msg and "cut-off" in msg
    assert "exclude" in msg
    cfg = load_sim_config(_sim_file(
        tmp_path, 'config = "model.toml"\nengine = "liggghts"\nnp = 2',
        '[catalogue]\nexclude = ["contact_ageing", "blade_startup", "capillary_bridges"]'))
    sim = make_simulator(cfg, diagnosis_design(_design(), cfg.effects))
    run = sim.run_config({}, {"non_sphericity": 0.2}, 0)
    assert sim.engine == run["engine"] == "liggghts" and run["external"]["np"] == 2
    assert run["contact"]["rolling_friction"] > 0.2
    # LAMMPS realises neither bridges nor ageing
    cfg = load_sim_config(_sim_file(tmp_path, 'preset = "tiny"\nengine = "lammps"'))
    with pytest.raises(ConfigError, match="lammps engine cannot realise.*'capillary_bridges'"):
        make_simulator(cfg, _design())


@pytest.mark.parametrize("table, match", [
    ('config = "absent.toml"', "workflow configuration not found"),
    ('config = 3', "key 'config': expected the path"),
    ('preset = "tiny"\nengine = "openfoam"', "key 'engine': expected one of embedded"),
    ('preset = "tiny"\nnp = 0', "key 'np': expected a whole number >= 1"),
])
def test_bad_engine_tables_are_named(tmp_path, table, match):
    with pytest.raises(ConfigError, match=match):
        cfg = load_sim_config(_sim_file(tmp_path, table))
        make_simulator(cfg, _design())


def test_np_on_the_command_line_reaches_the_runs_and_needs_an_engine(tmp_path, capsys):
    from bedstruct.cli import main

    code = main(["diagnose", "--sim", "surrogate", "--real", "data/measurements/seed.toml",
                 "--out", str(tmp_path / "d"), "--np", "2"])
    assert code != 0 and "--np needs a simulation config" in capsys.readouterr().err
    code = main(["diagnose", "validate", "--np", "2"])
    assert code != 0 and "--np are for a diagnosis" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("liggghts") is None and shutil.which("lmp_liggghts") is None,
                    reason="liggghts is not installed (.ci/install-engines.sh)")
def test_the_users_liggghts_model_answers_a_static_angle(tmp_path, monkeypatch):
    from bedstruct.engines import find_liggghts
    from bedstruct.workflows import external
    try:
        find_liggghts()
    except Exception:
        pytest.skip("liggghts is not installed")
    decks = []
    real_run_deck = external.run_deck

    def recording_run_deck(deck_path, **kw):
        deck = Path(deck_path)
        inputs = "".join(f.read_text() for f in deck.parent.iterdir()
                         if f.is_file() and f.suffix == ".data")
        decks.append((deck.read_text(), inputs, kw.get("np")))
        return real_run_deck(deck_path, **kw)

    monkeypatch.setattr(external, "run_deck", recording_run_deck)
    cfg = load_sim_config(_sim_file(
        tmp_path, f'config = "model.toml"\nengine = "liggghts"\nworkdir = "{tmp_path / "runs"}"',
        '[catalogue]\nexclude = ["contact_ageing", "blade_startup"]'))
    sim = make_simulator(cfg, diagnosis_design(_design(), cfg.effects))
    obs = sim(cfg.base, {}, 0)
    angle = float(np.asarray(obs["static_angle"]).ravel()[0])
    assert math.isfinite(angle) and 10.0 < angle < 60.0
    # LIGGGHTS ran the user's powder (density 7900 kg/m^3) and friction 0.45, on one rank
    assert decks and all(n == 1 for *_, n in decks)
    assert any(re.search(r"coefficientFriction peratomtypepair \d 0\.45\b", d) for d, *_ in decks)
    assert any("7900" in d or "7900" in data for d, data, _ in decks)


def test_every_preset_maps_the_seed_cohesion_onto_its_softened_modulus(tmp_path):
    """The seed preset runs E = 1e7 Pa: the seed's 3.6e7 J/m^3 there would pull spheres
    into each other (SJKR k pi R* d against Hertz 4/3 E* sqrt(R*) d^1.5 balance at an
    overlap of millimetres), so the base cohesion maps onto the preset's own value."""
    from bedstruct.workflows import load_config
    def mapped(preset):
        sim = make_simulator(load_sim_config(_sim_file(tmp_path, f'preset = "{preset}"')),
                             _design())
        return sim.run_config({"cohesion_energy_density": 3.6e7}, {}, 0)["contact"]["cohesion"]

    # tiny: its own calibration of the seed's value
    assert mapped("tiny") == pytest.approx(load_config(preset="tiny")["contact"]["cohesion"],
                                           rel=1e-12)
    # seed: the pull-in force k^3 / E*^2 of CoCr (2.1e11 Pa) kept at 1e7 Pa
    k = mapped("seed")
    assert k ** 3 / 1e7 ** 2 == pytest.approx(3.6e7 ** 3 / 2.1e11 ** 2, rel=1e-9)
    assert 4.6e4 < k < 4.8e4
    # the balance overlap at the seed's 3.6e7 J/m^3 and E = 1e7 Pa (two d50 spheres)
    r_eff, e_eff = 0.5 * 26.04e-6, 1e7 / (2 * (1 - 0.3 ** 2))
    overlap = (3.6e7 * math.pi * r_eff / (4 / 3 * e_eff * math.sqrt(r_eff))) ** 2
    assert overlap > 50e-6
