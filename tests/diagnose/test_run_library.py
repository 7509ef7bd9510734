"""Run library and emulator: design, resumable build, stale keys, LOO error, emulated diagnosis."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import qmc

pytest.importorskip("sklearn")

from bedstruct.diagnose import (BASE_PARAMETERS, MeasurementSet, Observations, SurrogateSimulator,
                                catalogue, diagnose, diagnosis_design, load_measurements,
                                measurement_from_dict)
from bedstruct.diagnose.emulator import EmulatedSimulator
from bedstruct.diagnose.emulator_fit import fit_emulator
from bedstruct.diagnose.run_design import design_points, design_spec
from bedstruct.diagnose.run_library import StaleLibraryError, build_library, load_library
from bedstruct.errors import ConfigError

from diagnose_helpers import small_design

ROOT = Path(__file__).resolve().parents[2]


def _one_angle():
    return MeasurementSet((measurement_from_dict({"name": "aor", "kind": "static_angle",
                                                  "role": "calibrate", "uncertainty": 0.5,
                                                  "value": 33.0}),))


class Flaky:
    """The surrogate, counting its calls and failing after ``fail_after`` of them."""

    name = "flaky-surrogate"

    def __init__(self, design, fail_after=None):
        self.sim = SurrogateSimulator(design)
        self.design = design
        self.fail_after = fail_after
        self.calls = []

    def library_identity(self):  # the same runs whether or not it fails
        return {"wraps": "surrogate", "noise": 1.0}

    def __call__(self, base, effects, seed):
        if self.fail_after is not None and len(self.calls) >= self.fail_after:
            raise KeyboardInterrupt("cut short")
        self.calls.append((dict(base), dict(effects), int(seed)))
        return self.sim(base, effects, seed)


class Smooth:
    """A known smooth function of cohesion and wall friction with known Gaussian noise."""

    name = "smooth"
    noise = 0.2

    def __init__(self):
        self.design = _one_angle()

    def library_identity(self):
        return {"noise": self.noise}

    @staticmethod
    def mean(base, effects):
        c = base.get("cohesion_energy_density", 3.6e7) / 3.6e7 - 1.0
        w = effects.get("wall_friction", 0.0)
        return 30.0 + 8.0 * c + 6.0 * w + 2.0 * np.sin(8.0 * w)

    def __call__(self, base, effects, seed):
        rng = np.random.default_rng([int(seed), int(1e6 * (1 + base["cohesion_energy_density"] / 1e8)),
                                     int(1e6 * (1 + effects.get("wall_friction", 0.0)))])
        return Observations({"aor": [self.mean(base, effects) + self.noise * rng.standard_normal()]})


# ----------------------------------------------------------------------------- design
def test_design_is_space_filling_and_inside_physical_bounds():
    spec = design_spec(BASE_PARAMETERS, vary={"cohesion_energy_density": 0.25,
                                              "friction": (0.3, 0.5)},
                       effects=["wall_friction", "capillary_bridges"], n_base=16, n_per_effect=16)
    pts = design_points(spec)
    lo, hi = spec.box
    assert len(pts) == 1 + 2 * 2 + 16 + 2 * 16
    for p in pts:
        x = np.array([p.base[k] for k in spec.varied]
                     + [p.effects.get(e, 0.0) for e in spec.effects])
        assert np.all(x >= lo) and np.all(x <= hi)
        assert len(p.effects) <= 1                       # one effect on at a time
        assert p.base["restitution"] == BASE_PARAMETERS["restitution"]   # not varied: held
    # each effect's sub-design: a Latin hypercube (one point per stratum of every input) with
    # a centred discrepancy below that of independent uniform draws
    sub = np.array([[(p.base[k] - spec.ranges[k][0]) / np.ptp(spec.ranges[k]) for k in spec.varied]
                    + [(p.effects["wall_friction"] + 0.2) / 0.6]
                    for p in pts if p.group == "wall_friction"])
    for j in range(sub.shape[1]):
        assert sorted(np.floor(sub[:, j] * 16).astype(int)) == list(range(16))
    rng = np.random.default_rng(0)
    random = [qmc.discrepancy(rng.uniform(size=sub.shape)) for _ in range(50)]
    assert qmc.discrepancy(sub) < np.percentile(random, 10)


def test_design_ranges_must_respect_physical_bounds():
    with pytest.raises(ConfigError, match="friction.*physical bounds"):
        design_spec(BASE_PARAMETERS, vary={"friction": (-0.1, 0.5)})
    with pytest.raises(ConfigError, match="does not contain the base value"):
        design_spec(BASE_PARAMETERS, vary={"friction": (0.5, 0.6)})
    with pytest.raises(ConfigError, match="restitution.*physical bounds"):
        design_spec(BASE_PARAMETERS, vary={"restitution": (0.05, 1.2)})
    with pytest.raises(ConfigError, match="replicates"):
        design_spec(BASE_PARAMETERS, replicates=1)


# ----------------------------------------------------------------------------- build
def test_a_build_cut_short_resumes_without_redoing_a_finished_run(tmp_path):
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=4, n_per_effect=4,
                       replicates=2)
    total = len(design_points(spec)) * 2
    first = Flaky(_one_angle(), fail_after=5)
    with pytest.raises(KeyboardInterrupt):
        build_library(first, spec, tmp_path, progress=False)
    files = sorted((tmp_path / "runs").glob("*.json"))
    assert len(files) == 5
    stamps = {f.name: f.stat().st_mtime_ns for f in files}
    again = Flaky(_one_angle())
    lib = build_library(again, spec, tmp_path, progress=False)
    assert len(again.calls) == total - 5 and lib.n_new == total - 5
    assert lib.complete and lib.n_runs == total
    done = {(json.dumps(r["base"], sort_keys=True), json.dumps(r["effects"], sort_keys=True), r["seed"])
            for r in (json.loads(f.read_text()) for f in files)}
    redone = {(json.dumps(b, sort_keys=True), json.dumps(e, sort_keys=True), s) for b, e, s in again.calls}
    assert not done & redone
    assert all((tmp_path / "runs" / n).stat().st_mtime_ns == t for n, t in stamps.items())
    # the same runs as one uninterrupted build
    whole = build_library(Flaky(_one_angle()), spec, tmp_path / "whole", progress=False)
    np.testing.assert_array_equal(whole.outputs, lib.outputs)


class Costly(Flaky):
    """The surrogate with a cost estimate: a run with wall friction costs 4 runs without."""

    def relative_cost(self, base, effects):
        return 4.0 if effects.get("wall_friction", 0.0) else 1.0


def test_the_progress_bar_advances_by_each_runs_estimated_cost(tmp_path, capsys):
    from bedstruct.diagnose.run_library import _CostBar, _longest_first, _run_costs
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=2, n_per_effect=2,
                       replicates=2)
    sim = Costly(_one_angle())
    todo = [(i, p, s) for i, p in enumerate(design_points(spec)) for s in spec.seeds]
    costs = _run_costs(sim, todo)
    heavy = sum(1 for i, p, _ in todo if p.effects.get("wall_friction", 0.0))
    assert 0 < heavy < len(todo)
    assert costs == {i: 4.0 if p.effects.get("wall_friction", 0.0) else 1.0 for i, p, _ in todo}
    order = _longest_first(sim, todo, costs)
    bar = _CostBar(order, costs)
    for i, _, _ in order[:heavy]:   # the costly runs first: most of the work, few of the runs
        bar.update(i)
    done = bar.bar.n / bar.bar.total
    assert done == pytest.approx(4 * heavy / (4 * heavy + len(todo) - heavy))
    assert done > heavy / len(todo)
    for i, _, _ in order[heavy:]:
        bar.update(i)
    assert bar.bar.n == pytest.approx(bar.bar.total) and bar.done == len(todo)
    bar.close()
    assert _run_costs(Flaky(_one_angle()), todo) == {i: 1.0 for i, _, _ in todo}
    # a build shows the runs done beside the bar
    build_library(sim, spec, tmp_path, progress=True)
    err = capsys.readouterr().err
    assert f"{len(todo)}/{len(todo)} runs" in err and "100%" in err


class Unpriced(Flaky):
    """The surrogate with a cost estimate that is no number for runs with wall friction."""

    def relative_cost(self, base, effects):
        return float("nan") if effects.get("wall_friction", 0.0) else 1.0


def test_a_cost_estimate_that_is_no_positive_number_is_refused_before_any_run(tmp_path):
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=2, n_per_effect=2,
                       replicates=2)
    with pytest.raises(ConfigError, match="relative_cost gave nan for design point"):
        build_library(Unpriced(_one_angle()), spec, tmp_path, progress=True)
    assert not list(tmp_path.glob("runs/*.json"))  # refused before any run was made


def test_parallel_builds_give_the_runs_of_a_serial_one(tmp_path):
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=3, n_per_effect=3,
                       replicates=2)
    sim = SurrogateSimulator(_one_angle())
    serial = build_library(sim, spec, tmp_path / "serial", progress=False)
    pooled = build_library(sim, spec, tmp_path / "pool", workers=2, progress=False)
    np.testing.assert_array_equal(serial.outputs, pooled.outputs)
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        on_dask = build_library(sim, spec, tmp_path / "dask", scheduler=client, progress=False)
    np.testing.assert_array_equal(serial.outputs, on_dask.outputs)


def test_a_stale_library_is_refused_naming_what_differs(tmp_path):
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=2, n_per_effect=2,
                       replicates=2)
    build_library(SurrogateSimulator(_one_angle()), spec, tmp_path, progress=False)
    with pytest.raises(StaleLibraryError, match=r"simulator\.config\.noise: 1\.0 -> 0\.5"):
        load_library(tmp_path, SurrogateSimulator(_one_angle(), noise=0.5))
    with pytest.raises(StaleLibraryError, match=r"observables\.pf \(new\)"):
        build_library(SurrogateSimulator(small_design()), spec, tmp_path, progress=False)
    # a library written by other code (another surrogate source) is stale too
    meta = json.loads((tmp_path / "library.json").read_text())
    meta["key_document"]["code"]["diagnose/surrogate.py"] = "0" * 20
    meta["key"] = "older"
    (tmp_path / "library.json").write_text(json.dumps(meta))
    with pytest.raises(StaleLibraryError, match=r"code\.diagnose/surrogate\.py"):
        build_library(SurrogateSimulator(_one_angle()), spec, tmp_path, progress=False)
    # another design in the same folder is refused too (not mixed in)
    other = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=3, n_per_effect=2,
                        replicates=2)
    fresh = tmp_path / "fresh"
    build_library(SurrogateSimulator(_one_angle()), spec, fresh, progress=False)
    with pytest.raises(ConfigError, match="n_base"):
        build_library(SurrogateSimulator(_one_angle()), other, fresh, progress=False)


def test_an_engine_simulators_library_key_names_its_cache_and_deck_revisions():
    from bedstruct.diagnose import engine_cache
    from bedstruct.diagnose.engine_simulator import EngineSimulator
    from bedstruct.diagnose.run_library import library_key_document
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=2, n_per_effect=2)
    doc = library_key_document(EngineSimulator(_one_angle(), {"preset": "tiny"}), spec)
    config = doc["simulator"]["config"]
    assert config["preset"] == "tiny"
    assert config["cache_schema"] == engine_cache._CACHE_SCHEMA
    assert config["deck_revision"] == engine_cache._DECK_REVISION
    assert config["model_revisions"] == engine_cache._MODEL_REVISIONS
    assert "dem" in doc["code"]


# ----------------------------------------------------------------------------- emulator
@pytest.fixture(scope="module")
def surrogate_emulator(tmp_path_factory):
    sim = SurrogateSimulator(small_design())
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction", "capillary_bridges"],
                       n_base=8, n_per_effect=10, replicates=3)
    lib = build_library(sim, spec, tmp_path_factory.mktemp("lib"), progress=False)
    return sim, lib, fit_emulator(lib)


def test_emulator_loo_error_is_reported_and_bounded_on_a_surrogate_library(surrogate_emulator):
    sim, lib, emu = surrogate_emulator
    loo = emu.loo
    assert 0.5 <= loo.loo_rmse_sigma <= 2.0
    assert loo.loo_within_2sigma >= 0.85
    assert loo.z.shape == lib.outputs.shape and loo.rmse_sigma.shape == (lib.outputs.shape[1],)
    # the fitted white noise is the surrogate's run-to-run scatter (static angle: 0.35 deg)
    assert emu.predict({}, {}).noise_sd[0] == pytest.approx(0.35, rel=0.3)
    # the hyperparameters are stored: a second fit of the same runs gives the same emulator
    again = fit_emulator(load_library(lib.path, sim))
    assert again.loo.loo_rmse_sigma == pytest.approx(loo.loo_rmse_sigma, rel=1e-6)


def test_emulator_recovers_a_known_smooth_function_and_its_noise(tmp_path):
    sim = Smooth()
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=6, n_per_effect=24,
                       replicates=3)
    emu = fit_emulator(build_library(sim, spec, tmp_path, progress=False))
    assert emu.predict({}, {}).noise_sd[0] == pytest.approx(sim.noise, rel=0.3)
    errs, sds = [], []
    for c in np.linspace(2.8e7, 4.4e7, 5):
        for w in np.linspace(-0.18, 0.38, 7):
            p = emu.predict({"cohesion_energy_density": c}, {"wall_friction": w})
            errs.append(p.mean[0] - sim.mean({"cohesion_energy_density": c}, {"wall_friction": w}))
            sds.append(p.sd[0])
    errs, sds = np.abs(errs), np.asarray(sds)
    assert errs.max() < 0.25                       # the function spans ~6 deg; noise 0.2
    assert np.mean(errs <= 2.5 * sds) >= 0.85      # the emulator's own uncertainty covers it


def test_emulated_simulator_refuses_points_outside_the_design_box(surrogate_emulator):
    sim, lib, emu = surrogate_emulator
    esim = EmulatedSimulator(emu)
    obs = esim({}, {"wall_friction": 0.3}, 4)
    assert obs.source == "emulator" and set(obs.names) == {"aor", "dyn", "pf"}
    np.testing.assert_array_equal(obs.vector(["aor"]), esim({}, {"wall_friction": 0.3}, 4).vector(["aor"]))
    assert esim({}, {}, 1)["aor"][0] != esim({}, {}, 2)["aor"][0]
    with pytest.raises(ConfigError, match=r"cohesion_energy_density = 2e\+07 lies outside"):
        esim({"cohesion_energy_density": 2.0e7}, {}, 0)
    with pytest.raises(ConfigError, match=r"wall_friction = 0\.5 lies outside"):
        esim({}, {"wall_friction": 0.5}, 0)
    with pytest.raises(ConfigError, match="friction = 0.5 differs"):
        esim({"friction": 0.5}, {}, 0)
    with pytest.raises(ConfigError, match="'missing_fines' is not in the run library"):
        esim({}, {"missing_fines": 0.05}, 0)
    # two effects at once: composed additively around the base point
    both = emu.predict({}, {"wall_friction": 0.2, "capillary_bridges": 0.4}).mean
    parts = (emu.predict({}, {"wall_friction": 0.2}).mean + emu.predict({}, {"capillary_bridges": 0.4}).mean
             - emu.predict({}, {}).mean)
    np.testing.assert_allclose(both, parts)
    # how well it predicts real runs at a point
    chk = emu.check([sim({}, {"wall_friction": 0.3}, s) for s in range(100, 104)], {},
                    {"wall_friction": 0.3})
    assert chk.z.shape == (4, 4) and chk.rmse_sigma < 3.0


def test_a_diagnosis_on_the_emulated_surrogate_names_the_surrogates_effect(tmp_path):
    ms = load_measurements(ROOT / "data/measurements/seed.toml")
    effects = catalogue(["missing_fines", "wall_friction"])
    sim = SurrogateSimulator(diagnosis_design(ms, effects))
    spec = design_spec(BASE_PARAMETERS, effects=effects, n_base=6, n_per_effect=8, replicates=3)
    emu = fit_emulator(build_library(sim, spec, tmp_path, progress=False))
    on_sim = diagnose(ms, sim, base=BASE_PARAMETERS, effects=effects)
    on_emu = diagnose(ms, EmulatedSimulator(emu), base=BASE_PARAMETERS, effects=effects)
    assert on_sim.attribution.verdict == "attributed"
    assert on_emu.attribution.verdict == on_sim.attribution.verdict
    assert on_emu.attribution.best.effects == on_sim.attribution.best.effects
    a, b = on_sim.shrink.magnitudes, on_emu.shrink.magnitudes
    assert set(a) == set(b) and all(abs(a[k] - b[k]) < 0.3 * abs(a[k]) for k in a)


def test_engine_simulator_library_key_covers_its_config_and_code():
    """An embedded-engine simulator's library key names its preset, resolved configuration,
    scale factors and the hashes of the engine, external decks and observation code (the
    same code list as its engine-call cache), and changes with the preset."""
    from bedstruct.diagnose import catalogue, diagnosis_design, engine_twin_design
    from bedstruct.diagnose import engine_cache as es
    from bedstruct.diagnose.engine_simulator import diagnosis_simulator
    from bedstruct.diagnose.run_library import library_key, library_key_document

    design = diagnosis_design(engine_twin_design("seed"), catalogue())
    spec = design_spec(BASE_PARAMETERS, n_base=2, n_per_effect=2, replicates=2)
    doc = library_key_document(diagnosis_simulator(design, {"preset": "tiny"}), spec)
    assert doc["simulator"]["config"]["preset"] == "tiny"
    assert set(doc["code"]) == set(es._CODE["engine"]) | set(es._CODE["observation"])
    assert {"dem", "engines", "workflows", "io", "analysis"} <= set(doc["code"])
    other = library_key_document(diagnosis_simulator(design, {"preset": "small"}), spec)
    assert library_key(other) != library_key(doc)


class NoReadingAbove(Smooth):
    """:class:`Smooth` with a second angle that gives no reading where the wall friction
    is above 0.2 (every replicate of such a point: a trial that gave no reading)."""

    name = "smooth-no-reading"

    def __init__(self):
        super().__init__()
        second = measurement_from_dict({"name": "aor2", "kind": "static_angle",
                                        "role": "validate", "uncertainty": 0.5, "value": 30.0})
        self.design = MeasurementSet(self.design.measurements + (second,))

    def __call__(self, base, effects, seed):
        obs = super().__call__(base, effects, seed)
        w = effects.get("wall_friction", 0.0)
        return Observations({"aor": obs["aor"], "aor2": [np.nan if w > 0.2 else obs["aor"][0] - 3.0]})


def test_points_whose_replicates_all_gave_no_reading_fit_without_warnings(tmp_path):
    import warnings

    sim = NoReadingAbove()
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=4, n_per_effect=12,
                       replicates=2)
    lib = build_library(sim, spec, tmp_path, progress=False)
    col = list(lib.names).index("aor2")
    assert np.isnan(lib.outputs[:, col]).any() and np.isfinite(lib.outputs[:, col]).any()
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        emu = fit_emulator(lib)
    # the runs that read it still teach the emulator the offset of the second angle
    p = emu.predict({}, {"wall_friction": 0.0})
    assert p.mean[col] - p.mean[list(lib.names).index("aor")] == pytest.approx(-3.0, abs=0.3)


def test_a_library_made_by_other_code_is_replayed_only_when_asked_and_only_for_its_code(
        tmp_path, monkeypatch, caplog):
    """``replay`` reads a library whose key differs only in the code that made it (its runs
    as recorded, a warning naming the code), runs nothing, and refuses one made for another
    simulator configuration or design as a plain load does."""
    from bedstruct.diagnose import run_library
    from bedstruct.diagnose.amortised import library_emulator
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=2, n_per_effect=2,
                       replicates=2)
    sim = SurrogateSimulator(_one_angle())
    made = build_library(sim, spec, tmp_path, progress=False)
    monkeypatch.setattr(run_library, "_code_hash", lambda rel: "f" * 20)  # the code changed
    with pytest.raises(StaleLibraryError, match=r"code\.diagnose/surrogate\.py"):
        load_library(tmp_path, sim)
    with caplog.at_level("WARNING", logger="bedstruct.diagnose.run_library"):
        lib = load_library(tmp_path, sim, replay=True)
    assert "replayed as recorded, made by other code (code.diagnose/catalogue.py" in caplog.text
    assert "code.diagnose/surrogate.py" in caplog.text
    assert lib.key == made.key and np.array_equal(lib.outputs, made.outputs, equal_nan=True)
    emu = library_emulator(sim, base=BASE_PARAMETERS, library=tmp_path, effects=["wall_friction"],
                           n_base=2, n_per_effect=2, library_replicates=2, replay=True)
    assert emu.n_runs == made.n_runs
    # a replay fits the recorded runs: the same emulator as before the code changed
    monkeypatch.undo()
    same = library_emulator(sim, base=BASE_PARAMETERS, library=tmp_path,
                            effects=["wall_friction"], n_base=2, n_per_effect=2,
                            library_replicates=2)
    x = dict(BASE_PARAMETERS)
    assert emu.predict(x, {"wall_friction": 0.2}).mean == pytest.approx(
        same.predict(x, {"wall_friction": 0.2}).mean, rel=1e-12)
    monkeypatch.setattr(run_library, "_code_hash", lambda rel: "f" * 20)
    # another configuration is not a code change: refused under replay too
    with pytest.raises(StaleLibraryError, match=r"not only by other code.*noise: 1\.0 -> 0\.5"):
        load_library(tmp_path, SurrogateSimulator(_one_angle(), noise=0.5), replay=True)
    # a design the library does not hold is refused, nothing is run
    with pytest.raises(ConfigError, match="does not hold the design asked for"):
        library_emulator(sim, base=BASE_PARAMETERS, library=tmp_path, effects=["wall_friction"],
                         n_base=3, n_per_effect=2, library_replicates=2, replay=True)
    # an edited library.json (key not its document's hash) is refused
    meta = json.loads((tmp_path / "library.json").read_text())
    meta["key_document"]["catalogue"]["wall_friction"]["prior"] = [0.0, 9.0]
    (tmp_path / "library.json").write_text(json.dumps(meta))
    with pytest.raises(StaleLibraryError, match="library.json edited"):
        load_library(tmp_path, sim, replay=True)


# ----------------------------------------------------------------------------- keys of any simulator
class Shifted:
    """The surrogate without noise, its output shifted by ``offset`` (a setting in its state)."""

    name = "shifted"

    def __init__(self, design, offset):
        self.design = design
        self.offset = offset
        self.sim = SurrogateSimulator(design, noise=0.0)

    def __call__(self, base, effects, seed):
        obs = self.sim(base, effects, seed)
        return Observations({k: np.asarray(v) + self.offset for k, v in obs.values.items()})


class NoisySub(SurrogateSimulator):
    """A subclass of the surrogate (its settings are the surrogate's)."""


def _shifted(base, effects, seed, offset=0.0):
    obs = SurrogateSimulator(_one_angle(), noise=0.0)(base, effects, seed)
    return Observations({k: np.asarray(v) + offset for k, v in obs.values.items()})


def test_a_simulators_settings_are_in_its_library_key_whatever_its_class(tmp_path):
    """A user simulator is keyed by its attributes, a surrogate subclass by the surrogate's
    settings, a partial by its function and arguments, each with the file that defines it;
    one whose state has no JSON form is refused, naming the ``library_identity`` hook."""
    import functools
    import threading

    from bedstruct.diagnose.run_library import library_key, library_key_document
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=2, n_per_effect=2,
                       replicates=2)
    build_library(Shifted(_one_angle(), 0.0), spec, tmp_path / "a", progress=False)
    with pytest.raises(StaleLibraryError, match=r"simulator\.state\.offset: 0\.0 -> 100\.0"):
        build_library(Shifted(_one_angle(), 100.0), spec, tmp_path / "a", progress=False)
    build_library(NoisySub(_one_angle(), noise=0.0), spec, tmp_path / "b", progress=False)
    with pytest.raises(StaleLibraryError, match=r"simulator\.config\.noise: 0\.0 -> 5\.0"):
        build_library(NoisySub(_one_angle(), noise=5.0), spec, tmp_path / "b", progress=False)
    docs = []
    for offset in (0.0, 50.0):
        p = functools.partial(_shifted, offset=offset)
        p.design = _one_angle()
        docs.append(library_key_document(p, spec))
    assert library_key(docs[0]) != library_key(docs[1])
    assert docs[0]["simulator"]["keywords"] == {"offset": 0.0}
    assert docs[0]["simulator"]["function"]["function"].endswith("._shifted")
    # the file defining a simulator outside the package is part of its code
    assert "simulator_source" in docs[0]["code"]
    assert "simulator_source" in library_key_document(Shifted(_one_angle(), 0.0), spec)["code"]
    assert "simulator_source" not in library_key_document(SurrogateSimulator(_one_angle()),
                                                          spec)["code"]
    odd = Shifted(_one_angle(), 0.0)
    odd._lock = threading.Lock()     # internal state (a leading underscore): not a setting
    assert library_key(library_key_document(odd, spec)) == \
        library_key(library_key_document(Shifted(_one_angle(), 0.0), spec))
    odd.lock = threading.Lock()
    with pytest.raises(ConfigError, match=r"state lock \(a lock\) has no JSON form.*"
                                          r"library_identity\(\)"):
        build_library(odd, spec, tmp_path / "c", progress=False)
    assert not (tmp_path / "c").exists()


def test_an_engine_simulators_options_are_in_its_library_key():
    from bedstruct.diagnose.engine_simulator import EngineSimulator
    from bedstruct.diagnose.run_library import library_key, library_key_document
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=2, n_per_effect=2)
    plain = EngineSimulator(_one_angle(), {"preset": "tiny"})
    other = EngineSimulator(_one_angle(), {"preset": "tiny"})
    other.options = {"contact.friction": 0.9}
    a, b = library_key_document(plain, spec), library_key_document(other, spec)
    assert "options" not in a["simulator"]["config"]   # none set: the key as before
    assert b["simulator"]["config"]["options"] == {"contact.friction": 0.9}
    assert library_key(a) != library_key(b)


# ----------------------------------------------------------------------------- interrupts
_SLOW_BUILD = """
import os, sys, time
sys.path[:0] = {paths!r}
from bedstruct.diagnose import BASE_PARAMETERS, SurrogateSimulator
from bedstruct.diagnose.run_design import design_spec
from bedstruct.diagnose.run_library import build_library
from test_run_library import _one_angle


class Slow:
    name = "slow"

    def __init__(self, marks, delay):
        self.design = _one_angle()
        self.marks = marks
        self.delay = delay

    def __call__(self, base, effects, seed):
        open(os.path.join(self.marks, f"{{os.getpid()}}-{{time.time_ns()}}"), "w").close()
        time.sleep(self.delay)
        return SurrogateSimulator(self.design)(base, effects, seed)


if __name__ == "__main__":
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=4, n_per_effect=4,
                       replicates=2)
    build_library(Slow(sys.argv[2], float(sys.argv[3])), spec, sys.argv[1], workers=2,
                  progress=False)
"""


def _slow_build(tmp_path, delay):
    """A build of slow runs in 2 worker processes, in a process of its own, once both
    workers have started a run: the process, the folder of run-start marks, the library."""
    import os
    import subprocess
    import sys
    import time
    script = tmp_path / "slow_build.py"
    script.write_text(_SLOW_BUILD.format(paths=[str(Path(__file__).parent), str(ROOT)]))
    marks, lib = tmp_path / "marks", tmp_path / "lib"
    marks.mkdir()
    err = tmp_path / "stderr.txt"
    with err.open("w") as fh:   # a file: a worker that outlives the build holds no pipe open
        proc = subprocess.Popen([sys.executable, str(script), str(lib), str(marks), str(delay)],
                                stderr=fh, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    t0 = time.time()
    while len(list(marks.iterdir())) < 2:
        assert proc.poll() is None, err.read_text()
        assert time.time() - t0 < 120, "the workers started no run"
        time.sleep(0.05)
    return proc, marks, lib


def _gone(pid) -> bool:
    import os
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(")", 1)[1].split()[0] == "Z"
    except OSError:
        return True


def test_ctrl_c_during_a_parallel_build_saves_the_runs_in_flight_and_starts_no_more(tmp_path):
    import signal
    import time
    delay = 2.0
    proc, marks, lib = _slow_build(tmp_path, delay)
    proc.send_signal(signal.SIGINT)
    t0 = time.time()
    proc.wait(timeout=60)
    err = (tmp_path / "stderr.txt").read_text()
    assert proc.returncode != 0 and "KeyboardInterrupt" in err
    assert time.time() - t0 < delay + 5.0            # no run queued behind them was waited for
    assert len(list(marks.iterdir())) == 2           # nothing started after the interrupt
    assert len(list((lib / "runs").glob("*.json"))) == 2   # both runs in flight were saved
    assert "Waiting for the 2 run(s) in flight to finish and be saved" in err
    assert not (lib / "build.lock").exists()


def test_a_killed_parallel_build_leaves_no_worker_processes(tmp_path):
    import os
    import signal
    import time
    proc, marks, lib = _slow_build(tmp_path, 1.0)
    pids = {int(m.name.split("-")[0]) for m in marks.iterdir()}
    assert len(pids) == 2 and proc.pid not in pids
    proc.send_signal(signal.SIGTERM)
    t0 = time.time()
    try:
        proc.wait(timeout=30)
        while not all(_gone(p) for p in pids) and time.time() - t0 < 15:
            time.sleep(0.2)
        assert all(_gone(p) for p in pids), "worker processes outlived their build"
    finally:
        for p in pids:   # the workers of this test only
            if not _gone(p):
                os.kill(p, signal.SIGKILL)


# ----------------------------------------------------------------------------- one folder, one build
def test_a_folder_takes_one_build_at_a_time_and_only_its_designs_runs(tmp_path, caplog):
    import os
    import shutil
    import subprocess
    import sys
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=2, n_per_effect=2,
                       replicates=2)
    sim = SurrogateSimulator(_one_angle())
    lib = build_library(sim, spec, tmp_path / "a", progress=False)
    own = sorted((tmp_path / "a" / "runs").glob("*.json"))
    # runs of another design with the same key dropped into the folder are not read
    other = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=4, n_per_effect=3,
                        replicates=2)
    build_library(sim, other, tmp_path / "b", progress=False)
    for f in (tmp_path / "b" / "runs").glob("*.json"):
        if not (tmp_path / "a" / "runs" / f.name).exists():
            shutil.copy(f, tmp_path / "a" / "runs" / f.name)
    with caplog.at_level("WARNING", logger="bedstruct.diagnose.run_library"):
        again = load_library(tmp_path / "a", sim)
    assert "not of its design ignored" in caplog.text
    assert again.n_runs == lib.n_runs and again.complete
    assert again.point_index.max() < len(again.points)
    np.testing.assert_array_equal(again.outputs, lib.outputs)
    # a build running in a folder (its lock) refuses a second one, naming its process
    own[0].unlink()
    import socket
    lock = tmp_path / "a" / "build.lock"
    lock.write_text(json.dumps({"pid": os.getpid(), "host": socket.gethostname(), "started": 0}))
    with pytest.raises(ConfigError, match=rf"another build is running in this folder \(process "
                                          rf"{os.getpid()} on "):
        build_library(sim, spec, tmp_path / "a", progress=False)
    # a lock left by a process that is gone is taken over
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    lock.write_text(json.dumps({"pid": int(dead), "host": socket.gethostname(), "started": 0}))
    assert build_library(sim, spec, tmp_path / "a", progress=False).n_new == 1
    assert not lock.exists()
    # of two builds creating library.json together one creates it, the other checks it
    from bedstruct.diagnose.run_library import _create_exclusive
    assert not _create_exclusive(tmp_path / "a" / "library.json", {"key": "other"})
    assert json.loads((tmp_path / "a" / "library.json").read_text())["key"] == lib.key
    assert _create_exclusive(tmp_path / "new.json", {"key": "x"})
    assert not _create_exclusive(tmp_path / "new.json", {"key": "y"})
    assert json.loads((tmp_path / "new.json").read_text()) == {"key": "x"}


# ----------------------------------------------------------------------------- unreadable files
def test_unreadable_run_files_are_named_and_redone_by_a_build(tmp_path):
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=2, n_per_effect=2,
                       replicates=2)
    sim = SurrogateSimulator(_one_angle())
    lib = build_library(sim, spec, tmp_path, progress=False)
    files = sorted((tmp_path / "runs").glob("*.json"))
    files[0].write_text(files[0].read_text()[:100])           # cut short
    files[1].write_text("")                                  # empty
    rec = json.loads(files[2].read_text())
    del rec["observations"]
    files[2].write_text(json.dumps(rec))                     # a field missing
    for f in files[:3]:
        with pytest.raises(ConfigError, match=rf"run file {f.name} is unreadable .*remove it"):
            load_library(tmp_path, sim)
        f.rename(f.with_suffix(".keep"))
    for f in files[:3]:
        f.with_suffix(".keep").rename(f)
    again = build_library(sim, spec, tmp_path, progress=False)
    assert again.n_new == 3 and again.complete
    np.testing.assert_array_equal(again.outputs, lib.outputs)
    assert len(list((tmp_path / "runs").glob("*.unreadable"))) == 3
    # an unreadable library.json is named, for a load and a build
    (tmp_path / "library.json").write_text((tmp_path / "library.json").read_text()[:50])
    for call in (lambda: load_library(tmp_path, sim),
                 lambda: build_library(sim, spec, tmp_path, progress=False)):
        with pytest.raises(ConfigError, match=r"library\.json is unreadable .*build it again"):
            call()


# ----------------------------------------------------------------------------- scheduler
def test_a_complete_library_needs_no_scheduler_and_a_bad_address_is_named(tmp_path):
    pytest.importorskip("distributed")
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=2, n_per_effect=2,
                       replicates=2)
    sim = SurrogateSimulator(_one_angle())
    lib = build_library(sim, spec, tmp_path, progress=False)
    bad = "tcp://host:notaport"
    again = build_library(sim, spec, tmp_path, scheduler=bad, progress=False)
    assert again.n_new == 0 and again.complete
    next(iter((tmp_path / "runs").glob("*.json"))).unlink()
    with pytest.raises(ConfigError, match=rf"--scheduler .*'{bad}'"):
        build_library(sim, spec, tmp_path, scheduler=bad, progress=False)
    assert lib.complete


# ----------------------------------------------------------------------------- emulator cache
def test_stored_hyperparameters_are_reused_only_for_as_many_restarts(tmp_path):
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=4, n_per_effect=6,
                       replicates=2)
    lib = build_library(Smooth(), spec, tmp_path, progress=False)
    cache = tmp_path / "emulator.json"
    fit_emulator(lib)
    assert json.loads(cache.read_text())["restarts"] == 0
    fit_emulator(lib, restarts=2)     # not the stored fit of no restarts
    assert json.loads(cache.read_text())["restarts"] == 2
    stamp = cache.stat().st_mtime_ns
    fit_emulator(lib, restarts=1)     # a fit of more restarts serves fewer
    assert cache.stat().st_mtime_ns == stamp


def test_a_simulator_defined_in_a_notebook_builds_in_parallel(tmp_path):
    # a class defined in a main module without a file (a notebook, python -c) cannot be
    # loaded by spawn-ed processes: such a build runs in forked ones
    import subprocess
    import sys
    code = f"""
from bedstruct.diagnose import BASE_PARAMETERS, SurrogateSimulator, catalogue, diagnosis_design, load_measurements
from bedstruct.diagnose.run_design import design_spec
from bedstruct.diagnose.run_library import build_library
class MySim(SurrogateSimulator):
    pass
ms = load_measurements({str(Path(__file__).parents[2] / "data" / "measurements" / "seed.toml")!r})
sim = MySim(diagnosis_design(ms, catalogue(["wall_friction"])))
spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=2, n_per_effect=2, replicates=2)
lib = build_library(sim, spec, {str(tmp_path / "lib")!r}, workers=2, progress=False)
print("runs", lib.n_runs)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=240)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split()[-1] == str(len(list((tmp_path / "lib" / "runs").glob("*.json")))) != "0"
