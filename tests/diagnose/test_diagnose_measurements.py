"""Measurement files: the seed example, every source of values, and errors naming the key."""

from __future__ import annotations

import pathlib

import numpy as np
import pytest
from scipy import stats

from bedstruct.diagnose import (Conditions, MeasurementSet, Observations, load_measurements,
                                measurement_from_dict, write_measurements)
from bedstruct.errors import ConfigError
from diagnose_helpers import heap_particles

SEED = pathlib.Path(__file__).resolve().parents[2] / "data" / "measurements" / "seed.toml"


def test_seed_file_holds_the_report_values_in_canonical_units():
    ms = load_measurements(SEED)
    assert ms["static_angle"].values[0] == 33.0
    np.testing.assert_allclose([ms[f"dynamic_angle_x{k}_steady"].values[0] for k in (1, 2, 5)],
                               [27.3, 29.6, 38.3])
    np.testing.assert_allclose([ms[f"bed_height_layer{k}"].values[0] for k in (1, 2, 3, 4)],
                               [508e-6, 1016e-6, 1118e-6, 1245e-6])
    np.testing.assert_allclose(ms["psd_before"].values, [29.84e-6, 52.08e-6, 86.11e-6])
    assert ms["psd_before"].labels == ("d10", "d50", "d90")
    assert ms["bed_height_layer1"].conversions == ("um -> m (x1e-06)",)
    spike = ms["dynamic_angle_x1_early"]
    assert spike.conditions.time_window == (0.0, 0.1)
    assert spike.provenance == "read from a qualitative statement"
    assert spike.uncertainty[0] == 4.0
    assert set(ms.roles()) == {"calibrate", "validate"}
    assert ms.n_components == len(ms.values()) == len(ms.uncertainty()) == 12


def _write(tmp_path, text, name="m.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.parametrize("body, key", [
    ('name = "a"\nkind = "static_angle"\nvalue = 1.0', "uncertainty"),
    ('name = "a"\nkind = "angle"\nvalue = 1.0\nuncertainty = 1.0', "kind"),
    ('name = "a"\nkind = "static_angle"\nvalue = 1.0\nuncertainty = 1.0\nunit = "um"', "unit"),
    ('name = "a"\nkind = "static_angle"\nvalue = 1.0\nuncertainty = -1.0', "uncertainty"),
    ('name = "a"\nkind = "static_angle"\nvalue = 1.0\nuncertainty = 1.0\nrole = "fit"', "role"),
    ('name = "a"\nkind = "static_angle"\nvalue = 1.0\nuncertainty = 1.0\ncolour = 1', "colour"),
    ('name = "a"\nkind = "dynamic_angle_series"\nvalue = [1.0]\nuncertainty = 1.0', "windows"),
    ('name = "a"\nkind = "dynamic_angle_series"\nvalue = [1.0]\nuncertainty = 1.0\n'
     'windows = [[0.5, 0.2]]', "windows"),
    ('name = "a"\nkind = "psd"\nvalue = [1.0]\nuncertainty = 1.0\nunit = "um"', "percentiles"),
    ('name = "a"\nkind = "static_angle"\nuncertainty = 1.0', "value"),
    ('name = "a"\nkind = "static_angle"\nvalue = 1.0\nuncertainty = 1.0\n'
     '[observable.conditions]\nhumidity = 0.5', "conditions.humidity"),
    ('name = "a"\nkind = "static_angle"\nvalue = 1.0\nuncertainty = 1.0\n'
     '[observable.conditions]\nlayer = 0', "conditions.layer"),
])
def test_errors_name_the_key(tmp_path, body, key):
    p = _write(tmp_path, "[[observable]]\n" + body + "\n")
    with pytest.raises(ConfigError, match=f"'{key}'"):
        load_measurements(p)


def test_file_level_errors(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_measurements(tmp_path / "missing.toml")
    with pytest.raises(ConfigError, match="TOML"):
        load_measurements(_write(tmp_path, "[[observable]\n"))
    with pytest.raises(ConfigError, match="'observable'"):
        load_measurements(_write(tmp_path, "[meta]\ntitle = 'x'\n"))
    two = '[[observable]]\nname = "a"\nkind = "static_angle"\nvalue = 30.0\nuncertainty = 1.0\n'
    with pytest.raises(ConfigError, match="already the name of observable #1"):
        load_measurements(_write(tmp_path, two + two))


def test_replicates_give_mean_and_standard_error(tmp_path):
    p = _write(tmp_path, '[[observable]]\nname = "a"\nkind = "static_angle"\n'
                         'replicates = [32.0, 33.0, 34.0, 33.0]\n')
    m = load_measurements(p)["a"]
    assert m.values[0] == 33.0
    # four readings: the standard error at its 84 % upper bound, 3 / chi2.ppf(0.16, 3)
    bound = np.sqrt(3 / stats.chi2.ppf(0.16, 3))
    assert 1.85 < bound < 1.95
    assert m.uncertainty[0] == pytest.approx(np.std([32, 33, 34, 33], ddof=1) / 2 * bound)
    assert m.conversions == ("uncertainty: the standard error of 4 replicates at its one-sided "
                             f"84 % upper confidence bound (x{bound:.2f})",)
    # a stated (systematic) uncertainty adds in quadrature
    p = _write(tmp_path, '[[observable]]\nname = "a"\nkind = "static_angle"\n'
                         'replicates = [32.0, 33.0, 34.0, 33.0]\nuncertainty = 1.0\n')
    m2 = load_measurements(p)["a"]
    assert m2.uncertainty[0] == pytest.approx(np.hypot(1.0, m.uncertainty[0]))


def test_csv_time_series_goes_through_the_window_operator(tmp_path):
    t = np.linspace(0, 1.5, 151)           # seconds, one stroke of 1.5 s
    angle = 27.3 + 6.0 * np.exp(-t / 0.02)
    np.savetxt(tmp_path / "x1.csv", np.column_stack([t, angle]), delimiter=",", header="time,angle",
               comments="")
    p = _write(tmp_path, '[[observable]]\nname = "dyn"\nkind = "dynamic_angle_series"\n'
                         'csv = "x1.csv"\nstroke_duration = 1.5\nwindows = [[0, 0.1], [0.1, 1]]\n'
                         'uncertainty = 0.5\n')
    m = load_measurements(p)["dyn"]
    sel = t / 1.5 < 0.1
    assert m.values[0] == pytest.approx(angle[sel].mean())
    assert m.values[1] == pytest.approx(angle[~sel].mean())
    assert m.uncertainty[0] > 0.5          # window scatter added
    p2 = _write(tmp_path, '[[observable]]\nname = "dyn"\nkind = "dynamic_angle_series"\n'
                          'csv = "x1.csv"\nwindows = [[0, 0.1], [0.1, 1]]\nuncertainty = 0.5\n')
    with pytest.raises(ConfigError, match="stroke_duration"):
        load_measurements(p2)


def test_csv_cumulative_psd(tmp_path):
    np.savetxt(tmp_path / "psd.csv", [[20, 0], [30, 10], [50, 50], [90, 90], [110, 100]],
               delimiter=",", header="size_um,passing", comments="")
    p = _write(tmp_path, '[[observable]]\nname = "psd"\nkind = "psd"\ncsv = "psd.csv"\nunit = "um"\n'
                         'percentiles = [10, 50, 90]\nuncertainty = [0.5, 1, 2]\n')
    m = load_measurements(p)["psd"]
    np.testing.assert_allclose(m.values, [30e-6, 50e-6, 90e-6])
    np.testing.assert_allclose(m.uncertainty, [0.5e-6, 1e-6, 2e-6])


def test_csv_load_cell_record_gives_the_tool_force_ratio(tmp_path):
    """A two-axis load-cell record of one stroke (force of the powder on the recoater): the
    ratio of the time means, its standard error from batch means added to the stated one."""
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 0.74, 500)
    fx = -2.0e-3 * (1 + 0.3 * rng.standard_normal(t.size))
    fz = 0.17 * fx + 1e-4 * rng.standard_normal(t.size)
    np.savetxt(tmp_path / "load.csv", np.column_stack([t, fx, fz]), delimiter=",",
               header="time,force_x,force_z", comments="")
    p = _write(tmp_path, '[[observable]]\nname = "blade"\nkind = "tool_force_ratio"\n'
                         'csv = "load.csv"\nuncertainty = 0.005\n'
                         'conditions = {speed = 0.0254, layer = 2}\n')
    m = load_measurements(p)["blade"]
    assert m.values[0] == pytest.approx(fz.mean() / fx.mean())
    assert m.values[0] == pytest.approx(0.17, abs=0.01)
    assert 0.005 < m.uncertainty[0] < 0.02
    assert m.conditions.layer == 2
    # no push recorded: a clear error naming the file
    np.savetxt(tmp_path / "load.csv", np.column_stack([t, 0 * fx, fz]), delimiter=",",
               header="time,force_x,force_z", comments="")
    with pytest.raises(ConfigError, match="load.csv.*horizontal load is zero"):
        load_measurements(p)
    np.savetxt(tmp_path / "load.csv", np.column_stack([t, fx]), delimiter=",",
               header="time,force_x", comments="")
    with pytest.raises(ConfigError, match="force_z"):
        load_measurements(p)


def test_image_observable_uses_the_image_operator(tmp_path):
    from skimage import io
    from bedstruct.diagnose import render_side_view
    pos, rad = heap_particles(31.0, seed=11)
    img = (render_side_view(pos, rad, pixel_size=5e-6) * 255).astype(np.uint8)
    io.imsave(tmp_path / "heap.png", img, check_contrast=False)
    p = _write(tmp_path, '[[observable]]\nname = "aor"\nkind = "static_angle"\nimage = "heap.png"\n'
                         'pixel_size = 5e-6\nuncertainty = 0.5\n')
    assert load_measurements(p)["aor"].values[0] == pytest.approx(31.0, abs=1.0)


def test_write_then_load_round_trip(tmp_path):
    ms = load_measurements(SEED)
    back = load_measurements(write_measurements(ms, tmp_path / "copy.toml"))
    assert back.names == ms.names
    np.testing.assert_allclose(back.values(), ms.values(), rtol=1e-15)
    np.testing.assert_allclose(back.uncertainty(), ms.uncertainty(), rtol=1e-15)
    assert list(back.roles()) == list(ms.roles())
    assert back["dynamic_angle_x1_early"].conditions == ms["dynamic_angle_x1_early"].conditions


def test_with_values_and_observations():
    ms = load_measurements(SEED)
    obs = Observations({n: ms[n].values * 2 for n in ms.names}, source="test")
    twin = ms.with_values(obs)
    np.testing.assert_allclose(twin.values(), 2 * ms.values())
    with pytest.raises(ValueError, match="components"):
        ms.with_values(Observations({n: [1.0, 2.0, 3.0, 4.0] for n in ms.names}))
    with pytest.raises(KeyError, match="missing"):
        obs.vector(["nope"])


def test_conditions_label_and_candidates():
    c = Conditions(speed=0.127, layer=3, region="start", time_window=(0.0, 0.1),
                   extra=(("rest_time", 600.0),))
    assert c.label() == "v=12.7 cm/s, layer 3, start region, t=0-10% of stroke, rest_time=600.0"
    assert c.get("rest_time") == 600.0 and c.get("box_width", 1.0) == 1.0
    m = measurement_from_dict({"name": "c", "kind": "psd", "role": "candidate", "percentiles": [10, 90],
                               "uncertainty": 1.0, "unit": "um"})
    assert np.isnan(m.values).all() and m.uncertainty[0] == 1e-6
    with pytest.raises(ConfigError, match="candidate"):
        measurement_from_dict({"name": "c", "kind": "static_angle", "role": "candidate", "value": 1.0,
                               "uncertainty": 1.0})
    assert isinstance(MeasurementSet((m,)).select(["calibrate"]), MeasurementSet)
