import tomllib

import pytest

from bedstruct.errors import ConfigError
from bedstruct.workflows import (DEFAULTS, apply_override, available_presets, config_to_toml,
                                 load_config)


def test_presets_exist_and_state_scaling():
    assert available_presets() == ["seed", "small", "tiny"]
    from bedstruct.workflows import preset_path
    for name in available_presets():
        text = preset_path(name).read_text().lower()
        assert "scaling" in text and "modulus" in text and "periodic" in text
        cfg = load_config(preset=name)
        assert cfg["preset"] == name


def test_seed_preset_is_the_seed_geometry():
    cfg = load_config(preset="seed")
    assert cfg["spread"]["plate_length"] == pytest.approx(18.9e-3)
    assert cfg["spread"]["gaps"] == pytest.approx([508e-6, 508e-6, 102e-6, 127e-6])
    assert cfg["repose"]["box"] == pytest.approx([6e-3, 3e-3, 1.8e-3])
    assert cfg["psd"]["d50"] == pytest.approx(52.08e-6)


def test_defaults_then_preset_then_file_then_overrides(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text('preset = "tiny"\n[spread]\nspeed = 0.05\n[contact]\nfriction = 0.3\n')
    cfg = load_config(p, overrides=["spread.speed=0.07", "spread.tool=roller"])
    assert cfg["spread"]["speed"] == 0.07          # override beats file
    assert cfg["contact"]["friction"] == 0.3        # file beats preset/defaults
    assert cfg["psd"]["scale"] == 2.0               # from the tiny preset
    assert cfg["contact"]["restitution"] == DEFAULTS["contact"]["restitution"]
    assert cfg["spread"]["tool"] == "roller"


@pytest.mark.parametrize("assignment, key", [
    ("spread.speed=fast", "spread.speed"),
    ("spread.gaps=3", "spread.gaps"),
    ("repose.replicates=1.5", "repose.replicates"),
    ("output.frames=1", "output.frames"),
    ("spread.sped=1", "spread.sped"),
    ("nosection.x=1", "nosection"),
    ("spread.tool=shovel", "spread.tool"),
    ("spread.gaps=[1e-4, -1e-4]", "spread.gaps"),
])
def test_bad_overrides_name_the_key(assignment, key):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        load_config(preset="tiny", overrides=[assignment])


def test_int_to_float_and_list_parsing():
    cfg = load_config(preset="tiny")
    apply_override(cfg, "spread.speed=1")
    assert isinstance(cfg["spread"]["speed"], float)
    apply_override(cfg, "spread.gaps=[1e-4, 2e-4, 3]")
    assert cfg["spread"]["gaps"] == [1e-4, 2e-4, 3.0]
    with pytest.raises(ConfigError, match="section.key=value"):
        apply_override(cfg, "spread.speed")


def test_unknown_preset_and_bad_toml(tmp_path):
    with pytest.raises(ConfigError, match="unknown preset 'huge'"):
        load_config(preset="huge")
    p = tmp_path / "bad.toml"
    p.write_text("[spread\nspeed = 1")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(p)


def test_toml_round_trip():
    for name in available_presets():
        cfg = load_config(preset=name)
        assert load_config(tomllib.loads(config_to_toml(cfg))) == cfg


def test_other_engines_not_yet_supported():
    # repose and spreading run on liggghts/lammps (tests/workflows/test_external_*.py)
    from bedstruct.workflows import run_repose, run_spread
    cfg = load_config(preset="tiny", overrides=['engine="liggghts"', 'external.exe="/nonexistent/x"'])
    with pytest.raises(ConfigError, match="not available"):
        run_repose(cfg)
    with pytest.raises(ConfigError, match="not available"):
        run_spread(cfg)
    # the roller runs on the external engines too (tests/workflows/test_external_spread.py)
    with pytest.raises(ConfigError, match="not available"):
        run_spread(load_config(preset="tiny", overrides=['engine="lammps"', "spread.tool=roller",
                                                         'external.exe="/nonexistent/x"']))


@pytest.mark.parametrize("assignment, key", [
    # values that crashed a run (UnboundLocalError, ZeroDivisionError, box-bounds errors)
    # or were named by an internal name, or were accepted
    ("spread.gaps=[]", "spread.gaps"),
    ("spread.roller_radius=0", "spread.roller_radius"),
    ("spread.settle_time=-1", "spread.settle_time"),
    ("spread.settle_time=0", "spread.settle_time"),
    ("spread.regions=0", "spread.regions"),
    ("spread.stop_margin=-1", "spread.stop_margin"),
    ("spread.n_frames=0", "spread.n_frames"),
    ("n_threads=0", "n_threads"),
    ("seed=-1", "seed"),
    ("spread.blade_thickness=0", "spread.blade_thickness"),
    ("spread.bevel_deg=90", "spread.bevel_deg"),
    ("repose.fill_time=0", "repose.fill_time"),
    ("repose.drain_time=-0.1", "repose.drain_time"),
    ("repose.slide_fraction=0", "repose.slide_fraction"),
    ("repose.pedestal_fraction=1", "repose.pedestal_fraction"),
    ("calibrate.tolerance_deg=0", "calibrate.tolerance_deg"),
    ("output.checkpoint_every=-5", "output.checkpoint_every"),
    ("external.timeout=-1", "external.timeout"),
    # an unstable time step: the run exited 0 with an angle of nan
    ("time.safety=2.5", "time.safety"),
    ("time.safety=0", "time.safety"),
    ("time.v_max=0", "time.v_max"),
    ("time.v_max=-1e-4", "time.v_max"),
])
def test_values_out_of_range_name_the_key(assignment, key):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        load_config(preset="tiny", overrides=[assignment])


def test_safety_limit_is_the_engines_rayleigh_limit():
    from bedstruct.dem import Simulation
    from bedstruct.workflows.config import MAX_SAFETY
    import inspect
    limit = inspect.signature(Simulation).parameters["max_rayleigh_fraction"].default
    assert MAX_SAFETY == limit
    assert load_config(preset="tiny", overrides=[f"time.safety={limit}"])["time"]["safety"] == limit


def test_workflows_validate_a_config_changed_after_loading(tmp_path):
    from bedstruct.workflows import calibrate_cohesion, run_repose, run_spread
    cfg = load_config(preset="tiny")
    cfg["spread"]["gaps"] = []
    with pytest.raises(ConfigError, match=r"`spread\.gaps`"):
        run_spread(cfg, out=tmp_path / "s")
    assert not (tmp_path / "s").exists()          # refused before anything was written
    cfg = load_config(preset="tiny")
    cfg["time"]["v_max"] = 0.0
    with pytest.raises(ConfigError, match=r"`time\.v_max`"):
        run_repose(cfg)
    with pytest.raises(ConfigError, match=r"`time\.v_max`"):
        calibrate_cohesion(cfg, evaluate=lambda k: (30.0, 1.0, ()))
