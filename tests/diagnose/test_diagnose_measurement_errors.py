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
    p.write_text(text)
    return p


def _where(path, key):
    """The location an error must name: the file, the observable (number and name), the key."""
    return re.escape(f"{path}: observable #1 'a': key '{key}'")


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
    p.write_text('[[observable]]\n' + _ONE + '[observable.conditions]\nspeed = "2.54 cm/s"\n'
                 'box_width = "30 mm"\n')
    m = load_measurements(p)["a"]
    assert m.conditions.speed == pytest.approx(0.0254)
    assert m.conditions.get("box_width") == pytest.approx(0.03)
    assert any("cm/s -> m/s" in c for c in m.conversions)


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
