"""A measurement file's set-up ([conditions]): read in SI, mapped onto the engine's runs."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from bedstruct.diagnose import SurrogateSimulator, load_measurements, write_measurements
from bedstruct.diagnose.engine_simulator import EngineSimulator
from bedstruct.errors import ConfigError

_PSD_CSV = "diameter,fraction\n20,1\n30,1\n40,1\n50,1\n60,1\n"

_ANGLE = '''
[[observable]]
name = "aor"
kind = "static_angle"
value = 33.0
uncertainty = 1.0
'''
_PSD_BEFORE = '''
[[observable]]
name = "psd0"
kind = "psd"
percentiles = [10, 50, 90]
value = [30.0, 40.0, 55.0]
uncertainty = [1.0, 1.0, 1.0]
unit = "um"
[observable.conditions]
stage = "before"
'''
_HEIGHT = '''
[[observable]]
name = "h3"
kind = "bed_height"
value = 300.0
uncertainty = 10.0
unit = "um"
[observable.conditions]
layer = 3
'''


def _file(tmp_path, conditions: str, observables: str = _ANGLE, name="m.toml"):
    (tmp_path / "psd.csv").write_text(_PSD_CSV)
    f = tmp_path / name
    f.write_text(textwrap.dedent(conditions) + observables)
    return f


def test_setup_is_read_in_si_and_written_back(tmp_path):
    f = _file(tmp_path, '''
        [conditions]
        psd = {file = "psd.csv", unit = "um"}
        layers = 20
        layer_thickness = "100 um"
        blade_speed = "5.08 cm/s"
        platform_length = "18.9 mm"
        platform_width = {value = 3, unit = "mm"}
        side_walls = false
    ''', _HEIGHT)
    s = load_measurements(f).setup
    # equal volume fractions in 5 classes: midpoint positions 10, 30, 50, 70, 90 %
    np.testing.assert_allclose(s.psd, [20e-6, 40e-6, 60e-6, 15e-6, 65e-6], rtol=1e-12)
    assert s.n_layers == 20 and s.layer_thickness == (100e-6,) * 20
    assert s.blade_speed == pytest.approx(0.0508)
    assert (s.platform_length, s.platform_width) == pytest.approx((18.9e-3, 3e-3))
    assert s.side_walls is False and s.path == str(f)
    assert any("cm/s -> m/s" in c for c in s.conversions)
    back = load_measurements(write_measurements(load_measurements(f), tmp_path / "w.toml")).setup
    np.testing.assert_allclose(back.psd, s.psd)
    assert back.layer_thickness == s.layer_thickness and back.blade_speed == s.blade_speed
    assert (back.platform_length, back.side_walls) == (s.platform_length, False)


def test_setup_changes_the_engine_runs_config(tmp_path):
    f = _file(tmp_path, '''
        [conditions]
        psd = {file = "psd.csv", unit = "um"}
        layer_thickness = ["500 um", "400 um", "200 um"]
        blade_speed = "2.54 cm/s"
        platform_length = "8 mm"
        platform_width = "0.8 mm"
    ''', _HEIGHT)
    sim = EngineSimulator(load_measurements(f), {"preset": "tiny"})
    cfg = sim.run_config({}, {}, 0)
    p = cfg["psd"]
    assert [p[k] for k in ("d10", "d50", "d90", "d_min", "d_max")] == \
        pytest.approx([20e-6, 40e-6, 60e-6, 15e-6, 65e-6])
    assert p["scale"] == 2.0     # the tiny preset's coarse-graining stays
    # the file's whole distribution: cumulative volume fractions at the classes' edges
    assert p["diameters"] == pytest.approx([15e-6, 25e-6, 35e-6, 45e-6, 55e-6, 65e-6])
    assert p["volume_fractions"] == pytest.approx([0.0, 0.2, 0.4, 0.6, 0.8, 1.0])
    sp = cfg["spread"]
    assert sp["gaps"] == pytest.approx([500e-6, 400e-6, 200e-6])
    assert sp["speed"] == pytest.approx(0.0254 * sim.speed_scale) == pytest.approx(0.1)
    assert (sp["plate_length"], sp["width"]) == pytest.approx((8e-3, 0.8e-3))
    # twenty layers
    f20 = _file(tmp_path, '''
        [conditions]
        layers = 20
        layer_thickness = "300 um"
    ''', _HEIGHT, "twenty.toml")
    gaps = EngineSimulator(load_measurements(f20), {"preset": "tiny"}).run_config({}, {}, 0)[
        "spread"]["gaps"]
    assert gaps == pytest.approx([300e-6] * 20)
    # without the set-up: the preset's
    plain = EngineSimulator(load_measurements(_file(tmp_path, "", _HEIGHT, "p.toml")),
                            {"preset": "tiny"}).run_config({}, {}, 0)
    assert plain["psd"]["d50"] == pytest.approx(52e-6) and len(plain["spread"]["gaps"]) == 2


def test_psd_condition_changes_the_simulated_powder(tmp_path):
    """The powder the engine draws follows the file's size distribution (no DEM run needed)."""
    f = _file(tmp_path, '''
        [conditions]
        psd = {d10 = "30 um", d50 = "40 um", d90 = "55 um"}
    ''', _PSD_BEFORE)
    ms = load_measurements(f)
    got = EngineSimulator(ms, {"preset": "tiny"})({}, {}, 0)["psd0"]
    plain = EngineSimulator(load_measurements(_file(tmp_path, "", _PSD_BEFORE, "p.toml")),
                            {"preset": "tiny"})({}, {}, 0)["psd0"]
    # 1000 drawn particles: percentiles within a few % of the condition's
    np.testing.assert_allclose(got, [30e-6, 40e-6, 55e-6], rtol=0.06)
    assert plain[1] > 48e-6   # the tiny preset's own D50, 52 um


def test_side_walls_map_onto_the_spreading_run_and_the_repose_box(tmp_path):
    f = _file(tmp_path, '''
        [conditions]
        side_walls = true
        wall_distance = "1.2 mm"
    ''', _ANGLE + _HEIGHT)
    cfg = EngineSimulator(load_measurements(f), {"preset": "tiny"}).run_config({}, {}, 0)
    assert cfg["repose"]["periodic_width"] is False
    assert cfg["repose"]["box"][1] == pytest.approx(1.2e-3)
    assert cfg["spread"]["side_walls"] is True
    assert cfg["spread"]["width"] == pytest.approx(1.2e-3)
    # without wall_distance the walls bound the platform's width
    f2 = _file(tmp_path, '''
        [conditions]
        side_walls = true
        platform_width = "0.9 mm"
    ''', _ANGLE + _HEIGHT, "spread.toml")
    sp = EngineSimulator(load_measurements(f2), {"preset": "tiny"}).run_config({}, {}, 0)["spread"]
    assert sp["side_walls"] is True and sp["width"] == pytest.approx(0.9e-3)
    f3 = _file(tmp_path, '''
        [conditions]
        side_walls = false
    ''', _ANGLE + _HEIGHT, name="open.toml")
    cfg3 = EngineSimulator(load_measurements(f3), {"preset": "tiny"}).run_config({}, {}, 0)
    assert cfg3["repose"]["periodic_width"] is True and cfg3["spread"]["side_walls"] is False
    f4 = _file(tmp_path, '''
        [conditions]
        side_walls = true
        platform_width = "2 mm"
        wall_distance = "1.2 mm"
    ''', _HEIGHT, "narrow.toml")
    with pytest.raises(ConfigError, match=r"narrow\.toml: key 'conditions\.wall_distance'.*"
                                          r"expected wall_distance >= platform_width"):
        EngineSimulator(load_measurements(f4), {"preset": "tiny"})


def test_a_psd_file_is_drawn_in_full_not_refitted(tmp_path):
    """A bimodal size distribution from a file reaches the engine's sampler whole: the drawn
    powder has both modes (a fit to its d10/d50/d90 has one)."""
    from bedstruct.workflows._common import psd_sampler
    d = np.arange(10.0, 101.0, 2.0)
    frac = np.exp(-0.5 * ((d - 25.0) / 3.0) ** 2) + np.exp(-0.5 * ((d - 80.0) / 5.0) ** 2)
    rows = "\n".join(f"{a:g},{b:.6g}" for a, b in zip(d, frac))
    (tmp_path / "bimodal.csv").write_text("diameter,fraction\n" + rows + "\n")
    f = tmp_path / "b.toml"
    f.write_text('[conditions]\npsd = {file = "bimodal.csv", unit = "um"}\n' + _ANGLE)
    cfg = EngineSimulator(load_measurements(f), {"preset": "tiny"}).run_config({}, {}, 0)
    scale = cfg["psd"]["scale"]
    rng = np.random.default_rng(0)
    drawn = 2e6 * psd_sampler(cfg)(100000, rng) / scale                       # um
    fitted = dict(cfg, psd=dict(cfg["psd"], diameters=[], volume_fractions=[]))
    refit = 2e6 * psd_sampler(fitted)(100000, rng) / scale
    edges = np.arange(9.0, 102.0, 6.0)

    def volume_modes(x):
        h = np.pad(np.histogram(x, bins=edges, weights=x ** 3)[0], 1)
        return [0.5 * (edges[i - 1] + edges[i]) for i in range(1, len(h) - 1)
                if h[i] > h[i - 1] and h[i] >= h[i + 1] and h[i] > 0.2 * h.max()]
    modes = volume_modes(drawn)
    assert len(modes) == 2 and abs(modes[0] - 25) < 6 and abs(modes[1] - 80) < 6
    assert len(volume_modes(refit)) == 1
    # the volume fraction below the gap between the modes is the file's
    below = frac[d < 50].sum() / frac.sum()
    assert np.sum(drawn[drawn < 50] ** 3) / np.sum(drawn ** 3) == pytest.approx(below, abs=0.01)


def test_the_surrogate_refuses_a_setup(tmp_path):
    f = _file(tmp_path, '''
        [conditions]
        blade_speed = "5 cm/s"
    ''')
    with pytest.raises(ConfigError, match=r"m\.toml: key 'conditions\.blade_speed'.*surrogate"):
        SurrogateSimulator(load_measurements(f))


@pytest.mark.parametrize("conditions, match", [
    ('platform_length = 18.9', r"'conditions\.platform_length': 18\.9 has no unit"),
    ('platform_length = "18.9 furlong"', r"unknown length unit 'furlong'"),
    ('blade_speed = "5 mm"', r"'conditions\.blade_speed': unknown speed unit 'mm'"),
    ('layers = 0\nlayer_thickness = "100 um"', r"'conditions\.layers': expected a whole number"),
    ('layers = 3', r"'conditions\.layer_thickness': 'layers' needs the layer thickness"),
    ('layers = 2\nlayer_thickness = ["1 mm", "1 mm", "1 mm"]', r"3 thicknesses but layers = 2"),
    ('wall_distance = "3 mm"', r"'conditions\.wall_distance'.*needs side_walls = true"),
    ('side_walls = "yes"', r"'conditions\.side_walls': expected true or false"),
    ('psd = {file = "none.csv", unit = "um"}', r"'conditions\.psd\.file': file not found"),
    ('psd = {file = "psd.csv"}', r"'conditions\.psd\.unit'"),
    ('psd = {d10 = "30 um", d50 = "20 um", d90 = "55 um"}',
     r"expected d10 < d50 < d90; got 30 um, 20 um, 55 um"),
    ('psd = {d10 = "30 um", d50 = "40 um", d90 = "55 um", d_min = "35 um"}',
     r"d_min < d10 < d50 < d90 < d_max"),
    ('psd = {d50 = "20 um"}', r"'conditions\.psd\.d10': the percentile form needs"),
    ('humidity = 0.4', r"'conditions\.humidity': unknown condition of the set-up"),
    ('layers = 10\nlayer_thickness = "100 mm"',
     r"'conditions\.layer_thickness': implausible layer thickness 100 mm; expected 1 um to 10 mm"),
    ('platform_length = "18.9 um"', r"implausible platform length 18\.9 um"),
    ('side_walls = true\nwall_distance = "30 m"', r"implausible wall distance 30 m"),
])
def test_bad_setup_names_file_key_and_expectation(tmp_path, conditions, match):
    f = _file(tmp_path, "[conditions]\n" + conditions + "\n", name="bad.toml")
    with pytest.raises(ConfigError, match=match) as info:
        load_measurements(f)
    assert str(f) in str(info.value)


def test_an_observable_layer_beyond_the_setups_layers_is_refused(tmp_path):
    f = _file(tmp_path, '''
        [conditions]
        layers = 2
        layer_thickness = "100 um"
    ''', _HEIGHT, "layers.toml")
    with pytest.raises(ConfigError, match=r"layers\.toml: observable #1 'h3': key "
                                          r"'conditions\.layer': layer 3.*2 layer\(s\)"):
        load_measurements(f)


def test_the_answers_data_notes_list_the_setups_unit_conversions(tmp_path):
    from types import SimpleNamespace

    from bedstruct.diagnose import Diagnosis
    ms = load_measurements(_file(tmp_path, '''
        [conditions]
        blade_speed = "5.08 cm/s"
    ''', _HEIGHT))
    view = SimpleNamespace(settings={}, measurements=ms, trials_without_reading=lambda: [])
    notes = Diagnosis.data_notes(view)
    assert [n for n in notes if n.startswith("set-up: ")] == \
        [f"set-up: {c}" for c in ms.setup.conversions]
    assert any("cm/s -> m/s" in n for n in notes)


def test_a_psd_files_whole_distribution_survives_writing_and_reading(tmp_path):
    """write_measurements writes a file PSD's whole distribution beside its percentiles;
    read back, the set-up and the engine's run configuration are the same."""
    f = _file(tmp_path, '''
        [conditions]
        psd = {file = "psd.csv", unit = "um"}
    ''')
    s = load_measurements(f).setup
    back = load_measurements(write_measurements(load_measurements(f), tmp_path / "w.toml")).setup
    np.testing.assert_array_equal(back.psd, s.psd)
    assert back.psd_table == s.psd_table and len(s.psd_table[0]) == 6
    cfg = EngineSimulator(load_measurements(f), {"preset": "tiny"}).run_config({}, {}, 0)
    cfg_back = EngineSimulator(load_measurements(tmp_path / "w.toml"),
                               {"preset": "tiny"}).run_config({}, {}, 0)
    assert cfg_back["psd"] == cfg["psd"] and len(cfg["psd"]["diameters"]) == 6


@pytest.mark.parametrize("table, match", [
    ('diameters = ["15 um", "40 um", "65 um"]', "both diameters and cumulative"),
    ('diameters = ["15 um", "40 um", "65 um"], cumulative = [0.0, 0.7, 0.5]', "non-decreasing"),
    ('diameters = ["15 um", "40 um"], cumulative = [0.0, 1.0]', "at least 3"),
    ('diameters = ["10 um", "40 um", "65 um"], cumulative = [0.0, 0.5, 1.0]', "span d_min"),
])
def test_a_bad_whole_distribution_is_refused_by_key(tmp_path, table, match):
    f = _file(tmp_path, f'''
        [conditions]
        psd = {{d10 = "20 um", d50 = "40 um", d90 = "60 um", d_min = "15 um", d_max = "65 um", {table}}}
    ''')
    with pytest.raises(ConfigError, match=r"conditions\.psd.*" + match):
        load_measurements(f)


def test_a_conversion_many_observables_share_is_one_note(tmp_path):
    from types import SimpleNamespace

    from bedstruct.diagnose import Diagnosis
    layers = "".join(f'''
[[observable]]
name = "h{i}"
kind = "bed_height"
unit = "um"
value = {100.0 * i}
uncertainty = 10.0
[observable.conditions]
layer = {i}
speed = "5 cm/s"
''' for i in range(1, 7))
    f = tmp_path / "layers.toml"
    f.write_text('[meta]\ntitle = "six layers"\n' + layers)
    ms = load_measurements(f)
    view = SimpleNamespace(settings={}, measurements=ms, trials_without_reading=lambda: [])
    notes = Diagnosis.data_notes(view)
    speed = [n for n in notes if "cm/s -> m/s" in n]
    assert speed == ["h1, h2 and 4 more observables: conditions.speed: cm/s -> m/s"]
    assert len([n for n in notes if "um" in n]) == 1
