"""The observable registry: each kind is its bedstruct.analysis definition; user kinds."""

from __future__ import annotations

import importlib
import textwrap

import numpy as np
import pytest

from bedstruct import Frame
from bedstruct import analysis as an
from bedstruct.diagnose import (load_measurements, observable_kind, observable_kinds, observe,
                                register_observable, unregister_observable, write_measurements)
from bedstruct.errors import ConfigError


@pytest.fixture(scope="module")
def bed():
    """A graded, jittered bed of two sizes: fine spheres at small x, coarse at large x."""
    rng = np.random.default_rng(4)
    g = np.stack(np.meshgrid(np.arange(24), np.arange(8), np.arange(5), indexing="ij"),
                 -1).reshape(-1, 3)
    pos = (g + 0.5) * 50e-6 + rng.normal(0.0, 4e-6, g.shape)
    rad = np.where(pos[:, 0] < 0.6e-3, 18e-6, 24e-6) * rng.uniform(0.9, 1.1, len(g))
    return Frame(pos, rad, box=([0, 0, 0], [1.2e-3, 0.4e-3, 0.5e-3]))


def test_every_kind_names_its_definition():
    kinds = {k.name: k for k in observable_kinds()}
    assert {"static_angle", "dynamic_angle_series", "bed_height", "packing_fraction", "psd",
            "roughness", "coordination", "segregation_index", "tool_force_ratio"} <= set(kinds)
    for k in kinds.values():
        assert k.unit in ("deg", "m", "1") and k.needs and k.inputs
        if k.analysis:   # the named function exists
            mod, _, name = k.analysis.rpartition(".")
            assert callable(getattr(importlib.import_module(mod), name))
    with pytest.raises(ValueError, match="unknown observable kind 'temperature'"):
        observable_kind("temperature")


def test_frame_kinds_equal_the_analysis_functions(bed):
    plate = float(np.min(bed.positions[:, 2] - bed.radii))
    assert observe("bed_height", bed)[0] == an.bed_height(bed, plate)
    lo, hi = [0.2e-3, 0.0, 0.0], [1.0e-3, 0.4e-3, 0.2e-3]
    assert observe("packing_fraction", {"frame": bed, "region_lo": lo, "region_hi": hi})[0] == \
        an.packing_fractions(bed, [lo], [hi]).fractions[0]
    assert observe("roughness", bed)[0] == an.surface_height_map(bed).sa
    assert observe("coordination", bed)[0] == an.coordination(bed).mean
    seg = observe("segregation_index", bed)[0]
    assert seg == an.segregation_index(bed) and seg > 0.05   # graded along x
    d = 2 * bed.radii
    np.testing.assert_array_equal(observe("psd", bed, percentiles=[10, 50, 90]),
                                  an.percentile_diameter(d, [0.1, 0.5, 0.9], weights=d ** 3))
    np.testing.assert_array_equal(observe("psd", {"diameters": d}, percentiles=[50]),
                                  observe("psd", bed, percentiles=[50]))


def test_static_angle_is_the_pile_angle_of_analysis():
    # a ridge with two flanks at 32 deg, spheres filling it, periodic across
    from bedstruct.core import Box
    rng = np.random.default_rng(2)
    t, half = np.tan(np.radians(32.0)), 1.5e-3
    p = rng.uniform([0, 0, 0], [2 * half, 0.5e-3, half * t], (60000, 3))
    p = p[p[:, 2] < t * (half - np.abs(p[:, 0] - half))][:6000]
    f = Frame(p, np.full(len(p), 20e-6), box=Box.from_box(([-0.5e-3, 0, -1e-4],
                                                            [3.5e-3, 0.5e-3, 2e-3]),
                                                           boundary=("ff", "pp", "ff")))
    a = observe("static_angle", f)[0]
    assert a == an.pile_angle(f, axis=0).repose.angle_deg
    assert a == pytest.approx(32.0, abs=1.5)


def test_dynamic_angle_from_frames_is_the_analysis_series_windowed():
    x = np.arange(5.25, 30, 0.5)
    frames = []
    for ang in (35.0, 35.0, 30.0, 30.0):
        z = 1 + np.clip(8 - np.tan(np.radians(ang)) * (x - 5), 0, None)
        frames.append(Frame(np.c_[x, np.zeros_like(x), z], np.full(x.size, 0.25),
                            box=([0, -1, 0], [40, 1, 12])))
    blade = [5.0] * 4
    t = np.array([0.05, 0.1, 0.6, 0.9])
    got = observe("dynamic_angle_series", {"frames": frames, "blade_positions": blade, "times": t},
                  windows=[[0, 0.2], [0.5, 1.0]])
    series = an.dynamic_repose_series(frames, blade).angle_deg
    np.testing.assert_allclose(got, [series[:2].mean(), series[2:].mean()])
    assert got[0] - got[1] == pytest.approx(5.0, abs=0.5)


def test_dynamic_angle_from_frames_with_the_platform_applies_the_heap_checks():
    """Given the platform, frames whose heap has no free toe on it read NaN (not the angle
    of a cut heap), as the spreading workflow measures them; the others equal
    analysis.heap_front_angle."""
    x = np.arange(5.25, 30, 0.5)
    z = np.clip(8 - np.tan(np.radians(35.0)) * (x - 5), 0, None) - 1.0
    heap = Frame(np.c_[x, np.zeros_like(x), z], np.full(x.size, 0.25), box=([0, -1, -2], [40, 1, 12]))
    late = Frame(heap.positions + [6.0, 0, 0], heap.radii, box=([0, -1, -2], [40, 1, 12]))
    data = {"frames": [heap, heap, late, late], "blade_positions": [5.0, 5.0, 11.0, 11.0],
            "times": np.array([0.05, 0.1, 0.6, 0.9]), "platform_end": 20.0, "platform_z": -1.25}
    got = observe("dynamic_angle_series", data, windows=[[0, 0.2], [0.5, 1.0]])
    assert got[0] == pytest.approx(an.heap_front_angle(heap, 5.0, platform_end=20.0,
                                                       platform_z=-1.25, tool_bottom=0.0))
    assert got[0] == pytest.approx(35.0, abs=0.1)
    assert np.isnan(got[1])   # the heap reached the platform's end: no toe on it
    plain = observe("dynamic_angle_series", {k: v for k, v in data.items()
                                              if k not in ("platform_end", "platform_z")},
                    windows=[[0, 0.2], [0.5, 1.0]])
    assert np.isfinite(plain[1])   # without the platform, no check


def test_missing_input_names_what_the_kind_needs():
    with pytest.raises(ValueError, match="force_x"):
        observe("tool_force_ratio", {"force_z": [1.0]})


def test_user_observable_end_to_end_through_observe(bed):
    def heap_top(frames):
        """Highest sphere top of the last bed (m)."""
        f = frames[-1]
        return float(np.max(f.positions[:, 2] + f.radii))

    k = register_observable("heap_top", heap_top, unit="m")
    try:
        assert k.user and k.description.startswith("Highest") and "heap_top" in k.source
        expect = float(np.max(bed.positions[:, 2] + bed.radii))
        assert observe("heap_top", [bed])[0] == expect
        assert observe("heap_top", {"frames": [bed, bed]})[0] == expect
        with pytest.raises(ValueError, match="built-in"):
            register_observable("bed_height", heap_top, unit="m")
        with pytest.raises(ValueError, match="canonical unit"):
            register_observable("other", heap_top, unit="um")
    finally:
        unregister_observable("heap_top")
    with pytest.raises(ValueError, match="unknown observable kind"):
        observe("heap_top", [bed])


def test_user_observable_from_a_measurement_file(tmp_path, monkeypatch):
    (tmp_path / "my_observables.py").write_text(textwrap.dedent('''
        import numpy as np

        def bed_top(frames):
            """Highest sphere top of the last bed (m)."""
            f = frames[-1]
            return float(np.max(f.positions[:, 2] + f.radii))
    '''))
    monkeypatch.syspath_prepend(str(tmp_path))
    f = tmp_path / "m.toml"
    f.write_text(textwrap.dedent('''
        [[observable]]
        name = "top"
        kind = "bed_top"
        callable = "my_observables:bed_top"
        value = 210.0
        uncertainty = 5.0
        unit = "um"
        [observable.conditions]
        layer = 2
    '''))
    try:
        ms = load_measurements(f)
        m = ms["top"]
        assert m.kind == "bed_top" and m.unit == "m"
        assert m.values[0] == pytest.approx(210e-6) and m.uncertainty[0] == pytest.approx(5e-6)
        fr = Frame([[0.5e-3, 0.5e-3, 100e-6]], [20e-6], box=[1e-3, 1e-3, 1e-3])
        assert observe(m.kind, [fr])[0] == pytest.approx(120e-6)
        # worker processes register it again from its module
        from bedstruct.diagnose.engine_simulator import _user_kinds
        assert _user_kinds(ms) == (("bed_top", "my_observables:bed_top", "m"),)
        # written back with its callable, read back the same
        w = write_measurements(ms, tmp_path / "w.toml")
        assert 'callable = "my_observables:bed_top"' in w.read_text()
        assert load_measurements(w)["top"].values[0] == pytest.approx(210e-6)
    finally:
        unregister_observable("bed_top")
    bad = tmp_path / "bad.toml"
    bad.write_text(f.read_text().replace("my_observables:bed_top", "my_observables:nothing"))
    with pytest.raises(ConfigError, match=r"bad\.toml.*'callable'.*no callable 'nothing'"):
        load_measurements(bad)
    wrong = tmp_path / "wrong.toml"
    wrong.write_text(f.read_text().replace('kind = "bed_top"', 'kind = "bed_height"'))
    with pytest.raises(ConfigError, match=r"wrong\.toml.*'callable'.*built-in"):
        load_measurements(wrong)


def test_user_observable_and_segregation_through_the_engine_simulator(monkeypatch):
    """The engine simulator hands a user kind the beds after layers 1 .. its layer (read back
    from the run's dumps) and reads the segregation index of the layer's measurement."""
    import types

    import bedstruct.workflows.spread as spread
    from bedstruct.diagnose import MeasurementSet, measurement_from_dict
    from bedstruct.diagnose.engine_simulator import EngineSimulator
    from bedstruct.io import write_dump

    def layers_seen(frames):
        return [len(frames), float(np.max(frames[-1].positions[:, 2]))]

    register_observable("layers_seen", layers_seen, unit="1")
    try:
        design = MeasurementSet(tuple(measurement_from_dict(d) for d in (
            {"name": "mine", "kind": "layers_seen", "value": [0.0, 0.0], "uncertainty": [1, 1],
             "conditions": {"layer": 2}},
            {"name": "seg", "kind": "segregation_index", "value": 0.1, "uncertainty": 0.01,
             "conditions": {"layer": 1}})))
        sim = EngineSimulator(design, {"preset": "tiny"})
        layers = [types.SimpleNamespace(index=k, segregation_index=0.1 * k) for k in (1, 2)]

        def fake_run_spread(cfg, *, out=None, pile=None, progress=False):
            for k in (1, 2):
                (out / f"layer{k:02d}").mkdir(parents=True)
                write_dump(out / f"layer{k:02d}" / "bed.dump",
                           Frame([[1e-4, 1e-4, 1e-4 * k]], [2e-5], box=[1e-3, 1e-3, 1e-3]))
            return types.SimpleNamespace(layers=layers)

        monkeypatch.setattr(spread, "run_spread", fake_run_spread)
        monkeypatch.setattr(spread, "generate_pile", lambda cfg, **kw: ("the pile", 0))
        obs = sim({}, {}, 0)
        np.testing.assert_allclose(obs["mine"], [2.0, 2e-4])
        assert obs["seg"][0] == pytest.approx(0.1)
        # the user function's source is part of the call's cache entry
        assert "layers_seen" in sim._spec(design["mine"])["function"]
        # a function defined inside another cannot reach worker processes
        from bedstruct.diagnose.engine_simulator import _user_kinds
        with pytest.raises(ConfigError, match="cannot be imported by worker processes"):
            _user_kinds(design)
    finally:
        unregister_observable("layers_seen")


def test_the_docs_examples_of_observables_run():
    """docs/diagnose.md's Python examples (observe, a user observable) run as written."""
    import doctest
    import pathlib
    import re
    page = pathlib.Path(__file__).resolve().parents[2] / "docs" / "diagnose.md"
    blocks = [b for b in re.findall(r"```python\n(.*?)```", page.read_text(encoding="utf-8"), re.S)
              if ">>>" in b]
    assert len(blocks) >= 2
    for text in blocks:
        test = doctest.DocTestParser().get_doctest(text, {}, "diagnose.md", str(page), 0)
        runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE)
        runner.run(test)
        assert runner.summarize(verbose=False).failed == 0
