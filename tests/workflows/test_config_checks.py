"""Configuration checks across keys at load: lengths against the particle sizes, the size
table's ends, bounds, the preset, and where a refused value came from."""

import pytest

from bedstruct.errors import ConfigError
from bedstruct.workflows import load_config


@pytest.mark.parametrize("overrides, key", [
    # tiny's particles are 80-140 um: a 50 um layer holds none of them
    (["spread.gaps=[50e-6, 50e-6]"], "spread.gaps"),
    (["spread.gaps=[4.5e-4, 50e-6]"], "spread.gaps"),
    # a strip narrower than the insertion and the neighbour cells need
    (["spread.width=1e-4"], "spread.width"),
    (["repose.box=[2.5e-3, 1e-4, 0.85e-3]"], "repose.box"),
    # a blade lower than it is thick
    (["spread.blade_height=1e-4"], "spread.blade_height"),
    # a pile longer than the platform
    (["spread.pile_length=5e-3"], "spread.pile_length"),
    # a plate that slides less than a particle, without a ledge: nothing can drain
    (["repose.pedestal_fraction=0", "repose.slide_fraction=0.02"], "repose.slide_fraction"),
    # sizes given in um instead of m
    (["psd.d10=45", "psd.d50=52", "psd.d90=60", "psd.d_min=40", "psd.d_max=70"], "units"),
    # the angle to calibrate for must be an angle of repose
    (["calibrate.target_deg=120"], "calibrate.target_deg"),
    (["calibrate.target_deg=-5"], "calibrate.target_deg"),
    # a size table that stops at half the volume
    (["psd.diameters=[80e-6, 100e-6, 140e-6]", "psd.volume_fractions=[0.0, 0.25, 0.5]",
      "psd.scale=1"], "psd.volume_fractions"),
    (["psd.diameters=[80e-6, 100e-6, 140e-6]", "psd.volume_fractions=[0.1, 0.5, 0.8]",
      "psd.scale=1"], "psd.volume_fractions"),
])
def test_inconsistent_geometry_is_refused_at_load_naming_the_key(overrides, key):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        load_config(preset="tiny", overrides=overrides)


def test_gap_at_the_smallest_particle_and_the_presets_pass():
    for name in ("tiny", "small", "seed"):
        load_config(preset=name)
    load_config(preset="tiny", overrides=["spread.gaps=[80e-6]"])
    # a measured table cut off in its tails (a little volume beyond each end) still loads
    load_config(preset="tiny", overrides=["psd.diameters=[80e-6, 100e-6, 140e-6]",
                                          "psd.volume_fractions=[0.01, 0.5, 0.995]",
                                          "psd.scale=1"])


def test_a_roller_ignores_the_blade_height():
    load_config(preset="tiny", overrides=["spread.tool=roller", "spread.blade_height=1e-4"])


def test_preset_cannot_be_set_by_an_override():
    with pytest.raises(ConfigError, match="--preset"):
        load_config(preset="tiny", overrides=["preset=small"])
    with pytest.raises(ConfigError, match="--preset"):
        load_config(overrides=["preset=small"])


def test_a_calibration_without_any_pile_says_which_bracket_suits_the_modulus():
    # the seed's 3e7 J/m^3 blows the tiny packing apart (E = 1e6 Pa): the error says the
    # bracket to give, not "raise cohesion"
    from bedstruct.workflows.calibrate import CalibrationPoint, _no_point_measured
    pts = {k: CalibrationPoint(k, float("nan"), float("nan"), (), "only 9 particles remain")
           for k in (3e7, 3.6e7)}
    msg = str(_no_point_measured(pts, None))
    assert "k = 3e+07 J/m^3: only 9 particles remain" in msg
    assert "calibrate.cohesion_bracket=[1e3, 1e4]" in msg


def test_errors_name_the_file_preset_or_set(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[spread]\nspeed = "fast"\n')
    with pytest.raises(ConfigError, match="bad.toml: config key `spread.speed`"):
        load_config(bad, preset="tiny")
    bad.write_text("[spread]\nspeed = -1\n")
    with pytest.raises(ConfigError, match="bad.toml: config key `spread.speed`"):
        load_config(bad, preset="tiny")
    bad.write_text("[sprad]\nspeed = 1\n")
    with pytest.raises(ConfigError, match="bad.toml: unknown config key `sprad`"):
        load_config(bad, preset="tiny")
    with pytest.raises(ConfigError, match=r"--set spread\.speed=-1: config key `spread\.speed`"):
        load_config(preset="tiny", overrides=["spread.speed=-1"])
    with pytest.raises(ConfigError, match=r"--set spread\.speed=fast"):
        load_config(preset="tiny", overrides=["spread.speed=fast"])
    # a value out of range with another key: both sources are named
    with pytest.raises(ConfigError, match=r"--set spread\.pile_length=5e-3; preset tiny"):
        load_config(preset="tiny", overrides=["spread.pile_length=5e-3"])


@pytest.mark.parametrize("workflow, overrides, key", [
    ("spread", ["spread.width=3.5e-4"], "spread.width"),
    ("repose", ["repose.box=[2.5e-3, 3.5e-4, 0.85e-3]"], "repose.box"),
])
def test_a_periodic_width_too_narrow_for_the_neighbour_cells_is_refused_before_writing(
        tmp_path, workflow, overrides, key):
    from bedstruct.workflows import run_repose, run_spread
    cfg = load_config(preset="tiny", overrides=overrides)
    run = {"spread": run_spread, "repose": run_repose}[workflow]
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        run(cfg, out=tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_a_workflow_is_checked_on_its_own_sections():
    """A repose run is not refused over the spreading layers' gaps, nor a spread over the
    repose box; a run checks its own sections again before it writes anything."""
    from bedstruct.workflows.config import check_run_geometry
    thin = ["spread.gaps=[50e-6]"]
    cfg = load_config(preset="tiny", overrides=thin, workflow="repose")
    load_config(preset="tiny", overrides=thin, workflow="calibrate")
    with pytest.raises(ConfigError, match=r"spread\.gaps"):
        load_config(preset="tiny", overrides=thin, workflow="spread")
    with pytest.raises(ConfigError, match=r"spread\.gaps"):
        check_run_geometry(cfg, "spread")
    narrow = ["repose.box=[2.5e-3, 1e-4, 0.85e-3]"]
    load_config(preset="tiny", overrides=narrow, workflow="spread")
    with pytest.raises(ConfigError, match=r"repose\.box"):
        load_config(preset="tiny", overrides=narrow, workflow="repose")
    with pytest.raises(ConfigError, match="unknown workflow"):
        load_config(preset="tiny", workflow="sprad")


@pytest.mark.parametrize("overrides, match", [
    (["psd.fines_mass_fraction=0.2", "psd.fines_min_diameter=2e-3"],
     r"`psd\.fines_min_diameter` \(0\.002 m\) must lie below the smallest diameter"),
    (["contact.wall_friction=-0.5"], r"`contact\.wall_friction` must be >= 0, or -1"),
    (["contact.wall_cohesion=-3"], r"`contact\.wall_cohesion` must be >= 0, or -1"),
])
def test_fines_above_the_powder_and_negative_wall_values_are_refused_at_load(overrides, match):
    with pytest.raises(ConfigError, match=match):
        load_config(preset="tiny", overrides=overrides)
    load_config(preset="tiny", overrides=["contact.wall_friction=-1"])   # the particle value


def test_unreadable_configuration_files_are_named(tmp_path):
    with pytest.raises(ConfigError, match="configuration file not found: .*missing.toml"):
        load_config(tmp_path / "missing.toml")
    with pytest.raises(ConfigError, match="is a folder"):
        load_config(tmp_path)
    binary = tmp_path / "bin.toml"
    binary.write_bytes(b"\xff\xfe speed = 1\n")
    with pytest.raises(ConfigError, match=r"bin\.toml: not a UTF-8 text file"):
        load_config(binary)
    units = tmp_path / "units.toml"
    units.write_text("[spread]\nspeed = 0.05 m/s\n")
    with pytest.raises(ConfigError, match=r"units\.toml: not valid TOML.*plain numbers in SI"):
        load_config(units)


def test_a_calibration_tolerance_is_an_angle_below_a_right_angle():
    with pytest.raises(ConfigError, match=r"calibrate\.tolerance_deg"):
        load_config(preset="tiny", overrides=["calibrate.tolerance_deg=1000"])
    load_config(preset="tiny", overrides=["calibrate.tolerance_deg=2.5"])
