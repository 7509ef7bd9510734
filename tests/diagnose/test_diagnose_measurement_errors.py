"""Measurement files: bad or implausible input is an error naming the file, the observable and
the key; images, time series and replicates read right (the audit's cases)."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest
from scipy import ndimage
from scipy.signal import lfilter

from bedstruct.diagnose import Conditions, MeasurementSet, load_measurements, measurement_from_dict
from bedstruct.errors import ConfigError

HEAD = '[[observable]]\nname = "a"\n'


def _write(tmp_path, text, name="m.toml"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def _where(path, key):
    """The location an error must name: the file, the observable (number and name), the key."""
    return re.escape(f"{path}: observable #1 'a': key '{key}'")


def _refused(path, key, message=""):
    """Reading ``path`` is an error naming the file, observable #1 'a' and ``key``, and then
    matching ``message`` (a regular expression)."""
    with pytest.raises(ConfigError, match=_where(path, key) + ".*" + message):
        load_measurements(path)


def _heap(angle, *, nr=300, nc=600, two=False):
    """A binary side view: flat top at 20 % of the rows, a flank at ``angle``, toe at 90 %."""
    r, c = np.mgrid[0:nr, 0:nc].astype(float)
    t = np.tan(np.radians(angle))
    surf = (0.2 * nr + np.abs(c - nc / 2) * t) if two else \
        np.where(c < 150, 0.2 * nr, 0.2 * nr + (c - 150) * t)
    return (r >= np.minimum(surf, 0.9 * nr)).astype(float)


def _photo(img, *, dark=False, seed=0):
    """Grey levels 0.3/0.7 (powder bright or dark), blurred, with noise, as 8-bit."""
    im = 0.7 - 0.4 * img if dark else 0.3 + 0.4 * img
    im = ndimage.gaussian_filter(im, 1.5) + np.random.default_rng(seed).normal(0, 0.08, im.shape)
    return (np.clip(im, 0, 1) * 255).astype(np.uint8)


def _save(tmp_path, name, img):
    from skimage import io
    io.imsave(tmp_path / name, img, check_contrast=False)


# --------------------------------------------------------------------------- 1. images

@pytest.mark.parametrize("dark", [False, True])
@pytest.mark.parametrize("powder", [None, "auto", "explicit"])
def test_image_file_reads_both_polarities(tmp_path, dark, powder):
    _save(tmp_path, "heap.png", _photo(_heap(30.0), dark=dark))
    key = "" if powder is None else \
        f'powder = "{"auto" if powder == "auto" else "dark" if dark else "bright"}"\n'
    p = _write(tmp_path, HEAD + 'kind = "static_angle"\nimage = "heap.png"\npixel_size = 1e-4\n'
                                'uncertainty = 1.0\n' + key)
    m = load_measurements(p)["a"]
    assert m.values[0] == pytest.approx(30.0, abs=0.5)
    assert any(("dark" if dark else "bright") in c for c in m.conversions)


def test_image_with_the_wrong_polarity_is_an_error_naming_the_file(tmp_path):
    _save(tmp_path, "heap.png", _photo(_heap(30.0), dark=True))
    p = _write(tmp_path, HEAD + 'kind = "static_angle"\nimage = "heap.png"\npixel_size = 1e-4\n'
                                'uncertainty = 1.0\npowder = "bright"\n')
    with pytest.raises(ConfigError, match=_where(p, "image") + ".*heap.png.*bottom of the image"):
        load_measurements(p)
    p = _write(tmp_path, HEAD + 'kind = "static_angle"\nimage = "heap.png"\npixel_size = 1e-4\n'
                                'uncertainty = 1.0\npowder = "grey"\n')
    with pytest.raises(ConfigError, match=_where(p, "powder")):
        load_measurements(p)


@pytest.mark.parametrize("transform", ["upside_down", "rot90", "rot270", "transposed", "noise"])
def test_image_not_a_side_view_is_an_error_naming_the_file(tmp_path, transform):
    img = _heap(30.0)
    img = {"upside_down": img[::-1], "rot90": np.rot90(img), "rot270": np.rot90(img, -1),
           "transposed": img.T, "noise": np.random.default_rng(1).random(img.shape)}[transform]
    _save(tmp_path, "bad.png", _photo(img))
    p = _write(tmp_path, HEAD + 'kind = "static_angle"\nimage = "bad.png"\npixel_size = 1e-4\n'
                                'uncertainty = 1.0\npowder = "bright"\n')
    with pytest.raises(ConfigError, match=_where(p, "image") + ".*bad.png: no angle read"):
        load_measurements(p)


def test_image_unit_applies_to_the_stated_uncertainty_only(tmp_path):
    _save(tmp_path, "heap.png", _photo(_heap(30.0)))
    p = _write(tmp_path, HEAD + 'kind = "static_angle"\nimage = "heap.png"\npixel_size = 1e-4\n'
                                'uncertainty = 0.02\nunit = "rad"\n')
    m = load_measurements(p)["a"]
    assert m.values[0] == pytest.approx(30.0, abs=0.5)          # not x57.3
    assert m.uncertainty[0] == pytest.approx(np.degrees(0.02))
    assert "uncertainty: rad -> deg (x57.2958)" in m.conversions


def test_image_series_from_files(tmp_path):
    files = []
    for i, a in enumerate([40.0, 38.0, 30.0, 31.0, 29.0]):
        _save(tmp_path, f"f{i}.png", _photo(_heap(a), seed=i))
        files.append(f"f{i}.png")
    body = (HEAD + 'kind = "dynamic_angle_series"\npixel_size = 1e-4\nwindows = [[0, 0.2], [0.2, 1]]\n'
            f'images = {{files = {files!r}, times = [0.0, 0.1, 0.4, 0.6, 0.9]}}\n').replace("'", '"')
    m = load_measurements(_write(tmp_path, body))["a"]
    np.testing.assert_allclose(m.values, [39.0, 30.0], atol=0.5)
    bad = body.replace("times = [0.0, 0.1, 0.4, 0.6, 0.9]", "times = [0.5]")
    p = _write(tmp_path, bad)
    with pytest.raises(ConfigError, match=_where(p, "images.times") + ".*1 times for 5 files"):
        load_measurements(p)


# --------------------------------------------------------------------------- 2. time series

def test_csv_series_uncertainty_accounts_for_autocorrelation(tmp_path):
    """An AR(1) angle series (phi = 0.99): the stated uncertainty of the window mean is the spread
    of window means over repeated series (std/sqrt(k) was ~15x too small)."""
    rng = np.random.default_rng(5)
    n, phi = 2000, 0.99
    t = np.linspace(0, 1, n)
    e = rng.normal(0, np.sqrt(1 - phi ** 2), (200, n))
    e[:, 0] = rng.normal(0, 1, 200)
    series = 30.0 + 2.0 * lfilter([1], [1, -phi], e, axis=1)
    means, stated = [], []
    for i, y in enumerate(series):
        np.savetxt(tmp_path / "s.csv", np.column_stack([t, y]), delimiter=",", header="t,angle",
                   comments="")
        m = load_measurements(_write(tmp_path, HEAD + 'kind = "dynamic_angle_series"\n'
                                                      'csv = "s.csv"\nwindows = [[0.1, 1.0]]\n'))["a"]
        means.append(m.values[0])
        stated.append(m.uncertainty[0])
    ratio = np.sqrt(np.mean(np.square(stated))) / np.std(means)
    assert 0.7 < ratio < 1.3, ratio


# --------------------------------------------------------------------------- 3. plausibility

@pytest.mark.parametrize("body, key, hint", [
    ('kind = "packing_fraction"\nvalue = 55.0\nuncertainty = 1.0', "value", "unit = '%'"),
    ('kind = "static_angle"\nvalue = 0.576\nuncertainty = 0.0175', "value", "unit = 'rad'"),
    ('kind = "bed_height"\nvalue = 508.0\nuncertainty = 10.0', "value", "unit = 'um'"),
    ('kind = "static_angle"\nvalue = 330.0\nuncertainty = 1.0', "value", "5 < value < 90 deg"),
    ('kind = "bed_height"\nvalue = -0.5\nuncertainty = 0.01\nunit = "mm"', "value", "positive"),
    ('kind = "static_angle"\nvalue = 33.0\nuncertainty = 1.0\nunit = "rad"', "value", "unit = 'deg'"),
    ('kind = "psd"\npercentiles = [10, 50, 90]\nvalue = [30, 50, 80]\nuncertainty = 1', "value",
     "unit = 'um'"),
    ('kind = "roughness"\nreplicates = [5.0, 6.0, 5.5]', "replicates", "unit = 'um'"),
    ('kind = "psd"\npercentiles = [0.1, 0.5, 0.9]\nvalue = [30, 50, 80]\nuncertainty = 1\n'
     'unit = "um"', "percentiles", "[10.0, 50.0, 90.0]"),
    ('kind = "psd"\npercentiles = [10, 50, 90]\nvalue = [80, 50, 30]\nuncertainty = 1\nunit = "um"',
     "value", "must increase"),
    ('kind = "psd"\npercentiles = [10, 50, 90]\nunit = "um"\n'
     'replicates = [[29.5, 30.0], [51.8, 52.1], [85.9, 86.2]]', "replicates", "transposed"),
    ('kind = "psd"\npercentiles = [10, 50, 90]\nunit = "um"\n'
     'replicates = [[29.5, 30.0, 30.1], [51.8, 52.1, 52.4], [85.9, 86.2, 86.0]]', "replicates",
     "each row must be one reading of all percentiles"),
    ('kind = "psd"\npercentiles = [10, 50, 90]\nunit = "um"\nreplicates = [30.0, 52.0, 86.0]',
     "replicates", "one list per replicate"),
])
def test_implausible_values_are_errors_suggesting_the_unit(tmp_path, body, key, hint):
    p = _write(tmp_path, HEAD + body + "\n")
    with pytest.raises(ConfigError, match=_where(p, key) + ".*" + re.escape(hint)):
        load_measurements(p)


def test_plausible_values_in_their_units_load(tmp_path):
    p = _write(tmp_path, HEAD + 'kind = "packing_fraction"\nvalue = 55.0\nuncertainty = 1.0\nunit = "%"\n'
                                '[[observable]]\nname = "b"\nkind = "static_angle"\nvalue = 0.576\n'
                                'uncertainty = 0.0175\nunit = "rad"\n'
                                '[[observable]]\nname = "c"\nkind = "psd"\nunit = "um"\n'
                                'percentiles = [10, 50, 90]\n'
                                'replicates = [[29.5, 51.8, 85.9], [30.0, 52.1, 86.2], [30.1, 52.4, 86.0]]\n')
    ms = load_measurements(p)
    assert ms["a"].values[0] == pytest.approx(0.55)
    assert ms["b"].values[0] == pytest.approx(33.0, abs=0.01)
    np.testing.assert_allclose(ms["c"].values, [29.8667e-6, 52.1e-6, 86.0333e-6], rtol=1e-4)


def test_psd_csv_with_cumulative_fractions_is_converted_and_recorded(tmp_path):
    np.savetxt(tmp_path / "psd.csv", [[10, 0], [30, 0.1], [50, 0.5], [90, 0.9], [120, 1.0]],
               delimiter=",", header="size,frac", comments="")
    body = (HEAD + 'kind = "psd"\npercentiles = [10, 50, 90]\ncsv = "psd.csv"\nunit = "um"\n'
                   'uncertainty = [0.6, 1.0, 1.7]\n')
    m = load_measurements(_write(tmp_path, body))["a"]
    np.testing.assert_allclose(m.values, [30e-6, 50e-6, 90e-6])
    assert any("fractions (max <= 1) -> percent (x100)" in c for c in m.conversions)
    # a curve that does not reach the 90th percentile is not extrapolated
    np.savetxt(tmp_path / "psd.csv", [[10, 0], [30, 10], [50, 50], [90, 80]], delimiter=",",
               header="size,pct", comments="")
    p = _write(tmp_path, body)
    with pytest.raises(ConfigError, match=_where(p, "csv") + ".*psd.csv.*covers 0..80"):
        load_measurements(p)


# --------------------------------------------------------------------------- 5. error messages

@pytest.mark.parametrize("body, key", [
    ('kind = "psd"\npercentiles = [10, 50]\nreplicates = [[30.0, 31.0], [29.0]]\nunit = "um"',
     "replicates"),
    ('kind = "static_angle"\nreplicates = ["a", "b"]', "replicates"),
    ('kind = "static_angle"\nreplicates = [30.0, [31.0]]', "replicates"),
    ('kind = "dynamic_angle_series"\nvalue = [33, 30]\nuncertainty = 1\nwindows = [[0, 0.1], [0.1]]',
     "windows"),
    ('kind = "static_angle"\nvalue = 33\nuncertainty = 1\n[observable.conditions]\nspeed = "fast"',
     "conditions.speed"),
    ('kind = "dynamic_angle_series"\nvalue = 33\nuncertainty = 1\n[observable.conditions]\n'
     'time_window = 0.5', "conditions.time_window"),
    ('kind = "dynamic_angle_series"\ncsv = "ts.csv"\nstroke_duration = "2 s"\nuncertainty = 1\n'
     'windows = [[0, 1]]', "stroke_duration"),
    ('kind = "static_angle"\nimage = "h.png"\npixel_size = "0.1 mm"\nuncertainty = 1', "pixel_size"),
    ('kind = "dynamic_angle_series"\ncsv = "one.csv"\nuncertainty = 1\nwindows = [[0, 1]]', "csv"),
    ('kind = "static_angle"\nimage = "nope.png"\npixel_size = 1e-4\nuncertainty = 1', "image"),
    ('kind = "dynamic_angle_series"\nimages = {files = ["h.png", "h.png"], times = [0.5]}\n'
     'pixel_size = 1e-4\nwindows = [[0, 1]]\nuncertainty = 1', "images.times"),
    ('kind = "static_angle"\nvalue = "30"\nuncertainty = 1', "value"),
    ('kind = "static_angle"\nvalue = 30\nuncertainty = 1\nwindows = [[0, 0.1]]', "windows"),
    ('kind = "static_angle"\nvalue = 33\nuncertainty = 1\n[observable.conditions]\nlayer = true',
     "conditions.layer"),
    ('kind = "static_angle"\nvalue = 33\nuncertainty = 1\n[observable.conditions]\nlayer = 2.0',
     "conditions.layer"),
    ('kind = "packing_fraction"\nvalue = 0.5\nuncertainty = 0.01\n[observable.conditions]\n'
     'region = "middle"', "conditions.region"),
])
def test_errors_name_the_file_the_observable_and_the_key(tmp_path, body, key):
    (tmp_path / "one.csv").write_text("angle\n30\n31\n")
    (tmp_path / "ts.csv").write_text("t,angle\n" + "".join(f"{t},30\n" for t in np.linspace(0, 2, 50)))
    _save(tmp_path, "h.png", _photo(_heap(30.0)))
    p = _write(tmp_path, HEAD + body + "\n")
    with pytest.raises(ConfigError, match=_where(p, key)):
        load_measurements(p)


# --------------------------------------------------------------------------- 6. regions

def test_regions_are_normalised_and_unknown_ones_are_errors(tmp_path):
    body = (HEAD + 'kind = "packing_fraction"\nvalue = 0.5\nuncertainty = 0.01\n'
                   '[observable.conditions]\nregion = "{}"\nlayer = 1\n')
    for spelling, canonical in (("Centre", "center"), ("center", "center"), ("START", "start"),
                                (" end", "end")):
        m = load_measurements(_write(tmp_path, body.format(spelling)))["a"]
        assert m.conditions.region == canonical


def _packing(region):
    m = measurement_from_dict({"name": "pf", "kind": "packing_fraction", "value": 0.5,
                               "uncertainty": 0.01,
                               "conditions": {"speed": 0.0254, "layer": 1, "region": "start"}})
    return dataclasses.replace(m, conditions=Conditions(speed=0.0254, layer=1, region=region))


def test_surrogate_region_lookup_is_strict():
    from bedstruct.diagnose import SurrogateSimulator
    vals = {r: SurrogateSimulator(MeasurementSet((_packing(r),)), noise=0)({}, {}, 0)["pf"][0]
            for r in ("start", "center", "Centre", "end")}
    assert vals["Centre"] == vals["center"] != vals["start"]
    with pytest.raises(ConfigError, match="'pf'.*'middle'"):
        SurrogateSimulator(MeasurementSet((_packing("middle"),)), noise=0)({}, {}, 0)


def test_engine_region_lookup_is_strict():
    from bedstruct.diagnose.engine_runs import _region_index
    assert [_region_index(_packing(r)) for r in ("start", "Centre", "center", "end", None)] == \
        [0, 1, 1, 2, 1]
    with pytest.raises(ConfigError, match="'pf'.*'middle'"):
        _region_index(_packing("middle"))


_ONE = 'name = "a"\nkind = "static_angle"\nvalue = 33.0\nuncertainty = 1.0\n'


@pytest.mark.parametrize("text, match", [
    ('[meta]\ntitel = "x"\n[[observable]]\n' + _ONE, r"key 'meta\.titel': unknown; expected title"),
    ('[[observable]]\n' + _ONE + '[observable.conditions]\nstage = "after"\n',
     r"#1 'a': key 'conditions\.stage': only a psd has a stage; this is a static_angle"),
    ('[[observable]]\n' + _ONE + '[observable.conditions]\ntime_window = [0, 0.1]\n',
     r"#1 'a': key 'conditions\.time_window': only a dynamic_angle_series"),
    ('[[observable]]\n' + _ONE + 'labels = [1]\n', r"#1 'a': key 'labels': expected a list of strings"),
    ('[[observable]]\n' + _ONE + 'note = 3\n', r"#1 'a': key 'note': expected a string"),
    ('[[observable]]\n' + _ONE + '[[observable]]\n' + _ONE,
     r"observable #2 'a': key 'name': already the name of observable #1"),
    ('[[observable]]\n' + _ONE + '[observable.conditions]\nspeed = "2.54 furlong/s"\n',
     r"#1 'a': key 'conditions\.speed': unknown speed unit 'furlong/s'"),
])
def test_more_bad_files_name_file_key_and_expectation(tmp_path, text, match):
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(ConfigError, match=match) as info:
        load_measurements(p)
    assert str(info.value).startswith(str(p))


def test_speeds_and_box_widths_may_carry_units(tmp_path):
    p = tmp_path / "u.toml"
    p.write_text('[[observable]]\n' + _ONE + '[observable.conditions]\nbox_width = "30 mm"\n'
                 '[[observable]]\nname = "b"\nkind = "bed_height"\nvalue = 5e-4\n'
                 'uncertainty = 1e-5\n[observable.conditions]\nspeed = "2.54 cm/s"\nlayer = 1\n')
    ms = load_measurements(p)
    assert ms["b"].conditions.speed == pytest.approx(0.0254)
    assert ms["a"].conditions.get("box_width") == pytest.approx(0.03)
    assert any("cm/s -> m/s" in c for c in ms["b"].conversions)


def test_a_measured_series_window_without_a_finite_value_is_named(tmp_path):
    """A measured angle series with only NaN in one window is a gap in the file: an error
    naming the file, the key and the window (a simulated series reads NaN there instead)."""
    t = np.linspace(0.0, 1.0, 21)
    y = np.where(t < 0.5, np.nan, 30.0)
    np.savetxt(tmp_path / "s.csv", np.column_stack([t, y]), delimiter=",", header="t,angle",
               comments="")
    f = _write(tmp_path, HEAD + 'kind = "dynamic_angle_series"\ncsv = "s.csv"\n'
                                'windows = [[0.0, 0.4], [0.5, 1.0]]\n')
    with pytest.raises(ConfigError, match=r"m\.toml.*window \[0, 0\.4\] holds no finite value"):
        load_measurements(f)


# --------------------------------------------------------------------------- 7. too small

@pytest.mark.parametrize("body, key, hint", [
    # sizes in mm labelled um: 1000x too small, refused like those too large
    ('kind = "psd"\npercentiles = [10, 50, 90]\nvalue = [0.02984, 0.05208, 0.08611]\n'
     'uncertainty = 0.0006\nunit = "um"', "value", "unit = 'mm'"),
    ('kind = "bed_height"\nvalue = 0.508\nuncertainty = 0.01\nunit = "um"', "value",
     "unit = 'mm'"),
    ('kind = "roughness"\nvalue = 0.012\nuncertainty = 0.001\nunit = "um"', "value",
     "unit = 'mm'"),
    ('kind = "packing_fraction"\nvalue = 0.55\nuncertainty = 0.01\nunit = "%"', "value",
     "unit = '1'"),
    ('kind = "coordination"\nvalue = 0.05\nuncertainty = 0.01', "value", "0.1 < value < 20"),
])
def test_values_too_small_for_their_unit_are_errors_suggesting_the_unit(tmp_path, body, key,
                                                                         hint):
    p = _write(tmp_path, HEAD + body + "\n")
    _refused(p, key, re.escape(hint))


def test_a_psd_csv_in_mm_labelled_um_is_refused(tmp_path):
    np.savetxt(tmp_path / "psd.csv", [[0.01, 0], [0.03, 10], [0.05, 50], [0.09, 90],
                                      [0.12, 100]], delimiter=",", header="size,pct", comments="")
    p = _write(tmp_path, HEAD + 'kind = "psd"\npercentiles = [10, 50, 90]\ncsv = "psd.csv"\n'
                                'unit = "um"\nuncertainty = [0.6, 1.0, 1.7]\n')
    _refused(p, "csv", "unit = 'mm'")


def test_percent_is_refused_where_it_means_nothing(tmp_path):
    p = _write(tmp_path, HEAD + 'kind = "coordination"\nvalue = 6.0\nuncertainty = 0.2\n'
                                'unit = "%"\n')
    _refused(p, "unit", "count per particle.*'%' does not apply")
    t = np.linspace(0, 1, 50)
    np.savetxt(tmp_path / "f.csv", np.column_stack([t, 10 + 0.1 * np.sin(40 * t),
                                                    2 + 0.1 * np.cos(30 * t)]),
               delimiter=",", header="t,force_x,force_z", comments="")
    body = HEAD + 'kind = "tool_force_ratio"\ncsv = "f.csv"\nuncertainty = 0.01\n{}'
    p = _write(tmp_path, body.format('unit = "%"\n'))
    _refused(p, "unit", "ratio of its two force columns.*'%' does not apply")
    assert load_measurements(_write(tmp_path, body.format("")))["a"].values[0] == \
        pytest.approx(0.2, abs=0.01)
    assert load_measurements(_write(tmp_path, body.format('unit = "1"\n')))["a"].values[0] == \
        pytest.approx(0.2, abs=0.01)


def test_the_greek_mu_and_the_micro_sign_both_read_as_micro(tmp_path):
    for mu in ("\u00b5", "\u03bc"):
        p = _write(tmp_path, HEAD + f'kind = "bed_height"\nvalue = 508.0\nuncertainty = 10.0\n'
                                    f'unit = "{mu}m"\n[observable.conditions]\nlayer = 1\n'
                                    f'speed = "25400 {mu}m/s"\n')
        m = load_measurements(p)["a"]
        assert m.values[0] == pytest.approx(508e-6)
        assert m.conditions.speed == pytest.approx(0.0254)


# --------------------------------------------------------------------------- 8. conditions

@pytest.mark.parametrize("cond, key, hint", [
    ("speed = 2.54", "conditions.speed", 'is it in cm/s or mm/s? write "2.54 cm/s"'),
    ("speed = 12.7", "conditions.speed", 'write "12.7 cm/s"'),
    ('speed = "254 cm/s"', "conditions.speed", "implausible speed 2.54 m/s; expected 0.1 mm/s to 2 m/s"),
    ("speed = 1e-6", "conditions.speed", "implausible speed 1e-06 m/s"),
])
def test_implausible_speeds_are_errors_with_a_unit_hint(tmp_path, cond, key, hint):
    p = _write(tmp_path, HEAD + 'kind = "bed_height"\nvalue = 5e-4\nuncertainty = 1e-5\n'
                                f'[observable.conditions]\nlayer = 1\n{cond}\n')
    _refused(p, key, re.escape(hint))


@pytest.mark.parametrize("cond, hint", [
    ("box_width = 30", 'implausible box width 30 m; expected 100 um to 1 m; is it in mm? '
                       'write "30 mm"'),
    ("box_width = 0.0", "must be > 0"),
    ('box_width = "3 m"', "implausible box width 3 m"),
    ("rest_time = 1e9", "implausible rest time 1e+09 s"),
])
def test_implausible_boxes_and_rest_times_are_errors(tmp_path, cond, hint):
    p = _write(tmp_path, HEAD + f'kind = "static_angle"\nvalue = 33.0\nuncertainty = 1.0\n'
                                f'[observable.conditions]\n{cond}\n')
    key = "conditions." + cond.split(" =")[0]
    _refused(p, key, re.escape(hint))


def test_an_implausible_blade_speed_of_the_set_up_is_an_error(tmp_path):
    p = _write(tmp_path, '[conditions]\nblade_speed = "254 cm/s"\n[[observable]]\nname = "a"\n'
                         'kind = "static_angle"\nvalue = 33.0\nuncertainty = 1.0\n')
    with pytest.raises(ConfigError, match=re.escape(f"{p}: key 'conditions.blade_speed': "
                                                    f"implausible speed 2.54 m/s")):
        load_measurements(p)


@pytest.mark.parametrize("kind, extra, cond, key, applies", [
    ("static_angle", "", 'region = "end"', "region",
     "only a packing_fraction, coordination, segregation_index or psd has a region"),
    ("static_angle", "", "speed = 0.5", "speed", "has a speed; this is a static_angle (its "
                                                 "conditions: box_width, rest_time, "
                                                 "relative_humidity)"),
    ("static_angle", "", "layer = 4", "layer", "has a layer; this is a static_angle"),
    ("packing_fraction", "", "box_width = 0.03", "box_width",
     "only a static_angle has a box width; this is a packing_fraction"),
    ("bed_height", "", 'region = "start"', "region", "this is a bed_height (its conditions: "
                                                     "speed, layer, relative_humidity)"),
])
def test_conditions_that_mean_nothing_for_the_kind_are_errors(tmp_path, kind, extra, cond, key,
                                                             applies):
    value = {"static_angle": "33.0", "packing_fraction": "0.5", "bed_height": "5e-4"}[kind]
    p = _write(tmp_path, HEAD + f'kind = "{kind}"\nvalue = {value}\nuncertainty = 0.01\n{extra}'
                                f'[observable.conditions]\n{cond}\n')
    _refused(p, f"conditions.{key}", re.escape(applies))


# --------------------------------------------------------------------------- 9. no traceback

@pytest.mark.parametrize("body, key", [
    ('kind = "static_angle"\nvalue = 33.0\nuncertainty = 1.0\ntrials = inf', "trials"),
    ('kind = "static_angle"\nvalue = 33.0\nuncertainty = 1.0\ntrials = nan', "trials"),
    ('kind = "static_angle"\nvalue = 33.0\nuncertainty = 1.0\ntrials = 3\nnot_measured = inf',
     "not_measured"),
    ('kind = "static_angle"\nvalue = 33.0\nuncertainty = 1.0\ntrials = 3\n'
     'not_measured = [nan]', "not_measured"),
    ('kind = "static_angle"\nvalue = []\nuncertainty = 1.0', "value"),
    ('kind = "static_angle"\nvalue = 33.0\nuncertainty = []', "uncertainty"),
])
def test_non_finite_counts_and_empty_lists_are_errors_not_tracebacks(tmp_path, body, key):
    p = _write(tmp_path, HEAD + body + "\n")
    _refused(p, key)


def test_a_csv_that_is_not_utf8_is_an_error_naming_the_key(tmp_path):
    (tmp_path / "s.csv").write_bytes("t,angle (°)\n0,30\n0.5,31\n1,30\n".encode("latin-1"))
    p = _write(tmp_path, HEAD + 'kind = "dynamic_angle_series"\ncsv = "s.csv"\n'
                                'windows = [[0, 1]]\nuncertainty = 1.0\n')
    _refused(p, "csv", "s.csv is not UTF-8 text")


# --------------------------------------------------------------------------- 10. coverage

def _series(tmp_path, t, y, extra=""):
    np.savetxt(tmp_path / "s.csv", np.column_stack([t, y]), delimiter=",", header="t,angle",
               comments="")
    return _write(tmp_path, HEAD + 'kind = "dynamic_angle_series"\ncsv = "s.csv"\n'
                                   f'windows = [[0.0, 0.5], [0.5, 1.0]]\n{extra}')


def test_a_series_that_does_not_cover_its_windows_is_refused(tmp_path):
    """Times in seconds of a 0.744 s stroke, read as stroke fractions: the second window
    would be averaged over half of itself."""
    t = np.linspace(0.0, 0.744, 200)
    y = 30.0 + 4.0 * t + np.random.default_rng(0).normal(0, 0.5, t.size)
    p = _series(tmp_path, t, y)
    _refused(p, "csv", "run from 0 to 0.744.*do not cover window \\[0.5, 1\\].*"
                       "stroke_duration")
    m = load_measurements(_series(tmp_path, t, y, "stroke_duration = 0.744\n"))["a"]
    assert m.values == pytest.approx([30.0 + 4 * 0.744 * 0.25, 30.0 + 4 * 0.744 * 0.75],
                                     abs=0.2)
    # a series sampled up to one spacing short of a window's end covers it
    t = np.linspace(0.0, 0.98, 50)
    assert load_measurements(_series(tmp_path, t, 30.0 + t))["a"].n_components == 2


def test_samples_of_a_series_without_an_angle_are_noted_and_bad_ones_refused(tmp_path):
    t = np.linspace(0.0, 1.0, 200)
    y = 30.0 + np.random.default_rng(1).normal(0, 0.5, t.size)
    y[[10, 150]] = np.nan
    m = load_measurements(_series(tmp_path, t, y))["a"]
    assert any("2 sample(s) without an angle (NaN" in c for c in m.conversions)
    y[150] = -40.0
    p = _series(tmp_path, t, y)
    _refused(p, "csv", "holds -40 deg at time .*outside 0..90 deg")
    t[20] = np.nan
    p = _series(tmp_path, t, y)
    _refused(p, "csv", "time column 't' holds nan")


# --------------------------------------------------------------------------- 11. duplicates

def test_names_with_surrounding_white_space_are_refused(tmp_path):
    p = _write(tmp_path, '[[observable]]\nname = "static_angle "\nkind = "static_angle"\n'
                         'value = 33.0\nuncertainty = 1.0\n')
    with pytest.raises(ConfigError, match=re.escape(f"{p}: observable #1: key 'name': "
                                                    f"'static_angle ' begins or ends with white "
                                                    f"space; expected 'static_angle'")):
        load_measurements(p)


def test_the_same_measurement_twice_is_refused(tmp_path):
    one = ('kind = "static_angle"\nvalue = 33.0\nuncertainty = 1.0\n'
           '[observable.conditions]\nbox_width = 0.03\n')
    p = _write(tmp_path, HEAD + one + '[[observable]]\nname = "b"\n' + one)
    with pytest.raises(ConfigError, match=re.escape(f"{p}: observable #2 'b': repeats "
                                                    f"observable #1 'a'")):
        load_measurements(p)
    # another box: another measurement
    p = _write(tmp_path, HEAD + one + '[[observable]]\nname = "b"\n'
               + one.replace("0.03", "0.003"))
    assert load_measurements(p).names == ("a", "b")


def test_duplicate_labels_are_refused(tmp_path):
    p = _write(tmp_path, HEAD + 'kind = "psd"\npercentiles = [10, 50, 90]\n'
                                'value = [30, 52, 86]\nunit = "um"\nuncertainty = 1.0\n'
                                'labels = ["a", "a", "b"]\n')
    _refused(p, "labels", "'a' labels more than one")


def test_an_observable_read_in_no_trial_has_no_uncertainty(tmp_path):
    p = _write(tmp_path, HEAD + 'kind = "static_angle"\ntrials = 3\nnot_measured = 3\n'
                                'uncertainty = 1.0\n')
    _refused(p, "uncertainty", "no reading in any of its 3 trial")
    p = _write(tmp_path, HEAD + 'kind = "static_angle"\ntrials = 3\nnot_measured = 3\n'
                                '[[observable]]\nname = "b"\nkind = "static_angle"\n'
                                'value = 33.0\nuncertainty = 1.0\n')
    assert [m.name for m in load_measurements(p).unmeasured] == ["a"]


# --------------------------------------------------------------------------- 9. slips a file can hide

@pytest.mark.parametrize("body, key, message", [
    # repeated readings written as components of a one-number kind
    ('kind = "static_angle"\nunit = "deg"\nvalue = [33.0, 34.5, 32.1]\nuncertainty = 1.0\n',
     "value", "a static_angle is one number, got 3; repeated readings go in 'replicates"),
    # an uncertainty in another unit than the value: larger than the value, or far finer
    ('kind = "bed_height"\nunit = "mm"\nvalue = 0.508\nuncertainty = 10.0\n'
     '[observable.conditions]\nlayer = 1\n',
     "uncertainty", "10 mm is larger than the value 0.508 mm"),
    ('kind = "packing_fraction"\nunit = "%"\nvalue = 55.0\nuncertainty = 0.015\n'
     '[observable.conditions]\nlayer = 1\n',
     "uncertainty", "0.015 % is 0.03% of the value 55 %, finer than a powder measurement"),
    # a coefficient of variation is never negative
    ('kind = "segregation_index"\nvalue = -0.2\nuncertainty = 0.05\n'
     '[observable.conditions]\nlayer = 1\n',
     "value", "implausible segregation_index -0.2"),
    # labels that name other percentiles than they label
    ('kind = "psd"\nunit = "um"\npercentiles = [10, 50, 90]\nlabels = ["D90", "D50", "D10"]\n'
     'value = [30.0, 52.0, 86.0]\nuncertainty = 1.0\n',
     "labels", "'D90' labels the 10th percentile"),
])
def test_slips_that_would_give_wrong_numbers_are_errors(tmp_path, body, key, message):
    p = _write(tmp_path, HEAD + body)
    _refused(p, key, re.escape(message))


def test_a_packing_fraction_above_one_is_not_offered_percent(tmp_path):
    """1.2 read as % would be 0.012, no packing of a powder bed: the error names the range
    and suggests no unit."""
    p = _write(tmp_path, HEAD + 'kind = "packing_fraction"\nunit = "1"\nvalue = 1.2\n'
                                'uncertainty = 0.02\n[observable.conditions]\nlayer = 1\n')
    with pytest.raises(ConfigError) as info:
        load_measurements(p)
    assert "expected 0.05 < value < 0.9" in str(info.value) and "fit unit" not in str(info.value)


def test_rest_times_and_humidities_take_units(tmp_path):
    p = _write(tmp_path, HEAD + 'kind = "static_angle"\nunit = "deg"\nvalue = 35.0\n'
                                'uncertainty = 1.0\n[observable.conditions]\n'
                                'rest_time = "10 min"\nrelative_humidity = "45 %"\n')
    c = load_measurements(p)["a"].conditions.as_dict()
    assert c["rest_time"] == pytest.approx(600.0) and c["relative_humidity"] == pytest.approx(0.45)
    bad = _write(tmp_path, HEAD + 'kind = "static_angle"\nunit = "deg"\nvalue = 35.0\n'
                                  'uncertainty = 1.0\n[observable.conditions]\nrest_time = "10 weeks"\n',
                 name="bad.toml")
    _refused(bad, "conditions.rest_time", re.escape("unknown time unit 'weeks'; expected one of s, min"))
