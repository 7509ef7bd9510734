"""Physical bounds of the recalibrated parameters and the effect magnitudes.

The recalibration is fitted within each parameter's physical bounds (a cohesion never
negative, a restitution within (0, 1]) or a configuration's narrower ones, and a fit that
ends on a bound says so in the verdict's reason and the JSON.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from bedstruct.diagnose import (BASE_PARAMETERS, Effect, MeasurementSet, Observations,
                                compute_fingerprints, diagnose, fit_model, load_sim_config,
                                measurement_from_dict)
from bedstruct.diagnose.parameters import PARAMETER_BOUNDS, parameter_bounds
from bedstruct.errors import ConfigError

_EFFECT = Effect(name="e", title="e", magnitude="m", unit="1", prior=(0.0, 1.0), physics="",
                 signature="", sources=(), engine_map=())


def _design():
    return MeasurementSet(tuple(measurement_from_dict(dict(
        name=n, kind="static_angle", value=0.0, uncertainty=1.0, role=r))
        for n, r in [("a", "calibrate"), ("b", "calibrate"), ("c", "validate")]))


def _simulator(base, effects, seed):
    """Linear toy: the cohesion raises a, lowers b; the effect moves all three."""
    m = effects.get("e", 0.0)
    noise = 0.01 * np.random.default_rng(seed).standard_normal(3)
    k = base["cohesion_energy_density"] / 1e7
    return Observations({"a": 10 * k + 30 * m + noise[0], "b": -10 * k + 40 * m + noise[1],
                         "c": m + noise[2]})


@pytest.fixture(scope="module")
def fps():
    return compute_fingerprints(_simulator, _design(), {"cohesion_energy_density": 1e7},
                                [_EFFECT], nuisance=("cohesion_energy_density",), replicates=2)


def test_every_base_parameter_has_physical_bounds():
    assert set(PARAMETER_BOUNDS) >= set(BASE_PARAMETERS)
    for name, (lo, hi) in PARAMETER_BOUNDS.items():
        assert lo < hi
        assert lo <= BASE_PARAMETERS.get(name, lo) <= hi
    assert PARAMETER_BOUNDS["cohesion_energy_density"][0] == 0.0
    assert PARAMETER_BOUNDS["friction"][0] == 0.0
    assert PARAMETER_BOUNDS["restitution"] == (0.0, 1.0)


def test_catalogue_magnitudes_are_bounded_by_their_priors():
    from bedstruct.diagnose import catalogue
    for e in catalogue():
        lo, hi = e.prior
        assert math.isfinite(lo) and math.isfinite(hi) and lo < hi, e.name
    # relative humidity is a fraction; wall friction never makes mu_w negative
    cap = [e for e in catalogue() if e.name == "capillary_bridges"][0]
    assert 0.0 <= cap.prior[0] and cap.prior[1] <= 1.0
    wall = [e for e in catalogue() if e.name == "wall_friction"][0]
    assert BASE_PARAMETERS["friction"] + wall.prior[0] >= 0.0


def test_a_recalibration_that_would_go_negative_stops_at_zero_and_says_so(fps):
    base_mean = fps.base_mean
    # data that the cohesion alone fits at -3e7 J/m^3 (a = -30, b = +30): impossible
    real = np.array([-30.0, 30.0, 0.0])
    residual = real - base_mean
    rows = fps.rows_calibrate
    free = np.linalg.lstsq(fps.sensitivities[rows] / fps.sigma[rows, None],
                           residual[rows] / fps.sigma[rows], rcond=None)[0]
    assert 1e7 + free[0] < -1e7          # unconstrained: a negative cohesion
    null = fit_model(residual, fps, ())
    assert null.nuisance[0] == pytest.approx(-1e7, rel=1e-6)     # cohesion 0, not below
    assert null.at_bound == ("cohesion_energy_density",)
    assert null.as_dict()["at_bound"] == ["cohesion_energy_density"]
    # with an effect in the model too
    one = fit_model(residual, fps, ("e",))
    assert 1e7 + one.nuisance[0] >= -1e-6 * 1e7
    assert "cohesion_energy_density" in one.at_bound


def test_a_fit_inside_its_bounds_names_no_bound(fps):
    real = np.array([15.0, -15.0, 0.0])       # cohesion 1.5e7: inside
    null = fit_model(real - fps.base_mean, fps, ())
    assert null.nuisance[0] == pytest.approx(0.5e7, rel=0.05) and null.at_bound == ()


def test_the_diagnosis_says_when_the_recalibration_ends_on_a_bound(fps):
    ms = MeasurementSet(tuple(measurement_from_dict(dict(
        name=n, kind="static_angle", value=v, uncertainty=1.0, role=r))
        for n, v, r in [("a", -30.0, "calibrate"), ("b", 30.0, "calibrate"),
                        ("c", 0.0, "validate")]))
    d = diagnose(ms, _simulator, base={"cohesion_energy_density": 1e7}, effects=[_EFFECT],
                 nuisance=("cohesion_energy_density",), replicates=2, fingerprints=fps,
                 refine=0, confirm_rounds=0)
    assert "bound of cohesion_energy_density" in d.attribution.reason
    js = d.to_json()
    assert js["recalibration"]["cohesion_energy_density"]["at_bound"] is True
    assert js["recalibration"]["cohesion_energy_density"]["value"] >= 0.0
    # and in words, for the engineer
    from bedstruct.diagnose.answer import answer, compact_answer
    assert "cohesion energy density stopped at its physical bound 0 MJ/m³" in \
        answer(d).recalibration
    assert compact_answer(d)["at_bound"] == ["cohesion_energy_density"]


def test_configured_bounds_narrow_the_physical_ones(tmp_path, fps):
    from dataclasses import replace
    narrow = replace(fps, bounds={"cohesion_energy_density": (0.8e7, 2e7)})
    null = fit_model(np.array([-30.0, 30.0, 0.0]) - fps.base_mean, narrow, ())
    assert 1e7 + null.nuisance[0] == pytest.approx(0.8e7, rel=1e-6) and null.at_bound
    p = tmp_path / "sim.toml"
    p.write_text('[recalibrate]\nparameters = ["cohesion_energy_density"]\n'
                 'bounds = { cohesion_energy_density = [1e6, 1e8] }\n')
    assert load_sim_config(p).bounds == {"cohesion_energy_density": [1e6, 1e8]}
    for text, match in (
            ('bounds = { cohesion_energy_density = [-1.0, 1e8] }', "physical bounds"),
            ('bounds = { friction = [0.1, 0.5] }', "not a recalibrated parameter"),
            ('bounds = { cohesion_energy_density = "wide" }', "lower, upper")):
        p.write_text(f'[recalibrate]\nparameters = ["cohesion_energy_density"]\n{text}\n')
        with pytest.raises(ConfigError, match=match):
            load_sim_config(p)
    p.write_text('[base]\nrestitution = 1.5\n[recalibrate]\nparameters = ["restitution"]\n')
    with pytest.raises(ConfigError, match="outside its bounds"):
        load_sim_config(p)
    assert parameter_bounds(["k"]) == {"k": (-math.inf, math.inf)}


class _Boxed:
    """The toy simulator answering only inside a design range, as an emulator does."""

    name = "boxed"

    def __init__(self, lo, hi):
        self.lo, self.hi = lo, hi
        self.asked = []

    def parameter_box(self):
        return {"cohesion_energy_density": (self.lo, self.hi)}

    def __call__(self, base, effects, seed):
        k = base["cohesion_energy_density"]
        self.asked.append(k)
        if not self.lo * (1 - 1e-9) <= k <= self.hi * (1 + 1e-9):
            raise ConfigError(f"cohesion_energy_density = {k:.6g} lies outside the design box")
        return _simulator(base, effects, seed)


def test_the_recalibration_stays_inside_the_simulators_domain():
    """Data that want a cohesion below a run library's range: the recalibration ends on the
    range's edge and says so, instead of asking the emulator outside its domain."""
    sim = _Boxed(0.8e7, 2e7)
    ms = MeasurementSet(tuple(measurement_from_dict(dict(
        name=n, kind="static_angle", value=v, uncertainty=1.0, role=r))
        for n, v, r in [("a", 5.0, "calibrate"), ("b", -5.0, "calibrate"),   # cohesion 0.5e7
                        ("c", 0.0, "validate")]))
    d = diagnose(ms, sim, base={"cohesion_energy_density": 1e7}, effects=[_EFFECT],
                 nuisance=("cohesion_energy_density",), replicates=2, refine=1, confirm_rounds=1)
    assert min(sim.asked) >= 0.8e7 * (1 - 1e-9)
    rec = d.to_json()["recalibration"]["cohesion_energy_density"]
    assert rec["at_bound"] is True and rec["value"] == pytest.approx(0.8e7, rel=1e-6)
    # a configured range wider than the simulator's is narrowed to it; a narrower one is kept
    from bedstruct.diagnose.diagnosis import _within_simulator_domain
    nu = ("cohesion_energy_density",)
    assert _within_simulator_domain(sim, nu, {"cohesion_energy_density": (0.0, 5e7)}) == \
        {"cohesion_energy_density": (0.8e7, 2e7)}
    assert _within_simulator_domain(sim, nu, {"cohesion_energy_density": (1e7, 1.5e7)}) == \
        {"cohesion_energy_density": (1e7, 1.5e7)}
    assert _within_simulator_domain(_simulator, nu, None) == {}


# --------------------------------------------------------------------------- at the bound

def test_the_surrogate_takes_every_parameter_at_its_physical_bound():
    """A cohesionless, frictionless powder is physical: the surrogate gives finite
    observables there (the bound a recalibration may end on), and refuses values beyond the
    bounds without blaming the configuration's [base]."""
    from bedstruct.diagnose import SurrogateSimulator
    design = MeasurementSet(tuple(measurement_from_dict(d) for d in (
        dict(name="sa", kind="static_angle", role="candidate", uncertainty=1.0),
        dict(name="dyn", kind="dynamic_angle_series", role="candidate", uncertainty=1.0,
             windows=[[0.0, 0.1], [0.1, 1.0]], conditions={"speed": 0.0254, "layer": 3}),
        dict(name="pf", kind="packing_fraction", role="candidate", uncertainty=0.01,
             conditions={"speed": 0.0254, "layer": 1, "region": "center"}))))
    sim = SurrogateSimulator(design, noise=0)
    at_zero = sim({"cohesion_energy_density": 0.0, "friction": 0.0, "rolling_friction": 0.0},
                  {}, 0)
    assert all(np.all(np.isfinite(at_zero[n])) for n in ("sa", "dyn", "pf"))
    assert at_zero["sa"][0] < sim({}, {}, 0)["sa"][0]
    # the friction laws saturate below their floor: continuous down to 0
    tiny = sim({"friction": 1e-9, "rolling_friction": 1e-9}, {}, 0)
    assert tiny["sa"][0] == pytest.approx(sim({"friction": 0.0, "rolling_friction": 0.0},
                                              {}, 0)["sa"][0])
    for key, v in (("cohesion_energy_density", -1.0), ("friction", math.inf),
                   ("rolling_friction", math.nan), ("restitution", 1.5)):
        with pytest.raises(ConfigError, match=f"surrogate parameter '{key}'") as info:
            sim({key: v}, {}, 0)
        assert "base" not in str(info.value)


def test_a_fit_to_zero_cohesion_runs_on_the_surrogate_and_says_so(tmp_path):
    """The seed file with a static angle of 8 deg (inside its plausible range): the
    recalibration drives the cohesion to its bound 0, the rerun runs there and the answer
    says the fit stopped on the bound."""
    from bedstruct.diagnose import diagnosis_design, load_measurements, make_simulator
    seed = Path(__file__).resolve().parents[2] / "data" / "measurements" / "seed.toml"
    text = seed.read_text(encoding="utf-8")
    assert text.count("value = 33.0\n") >= 1
    p = tmp_path / "static8.toml"
    p.write_text(text.replace("value = 33.0\n", "value = 8.0\n", 1), encoding="utf-8")
    ms = load_measurements(p)
    assert ms["static_angle"].values[0] == 8.0
    cfg = load_sim_config("surrogate")
    sim = make_simulator(cfg, diagnosis_design(ms, cfg.effects))
    d = diagnose(ms, sim, base=cfg.base, effects=cfg.effects, nuisance=cfg.nuisance,
                 **cfg.diagnose_settings())
    rec = d.to_json()["recalibration"]["cohesion_energy_density"]
    assert rec["at_bound"] is True and rec["value"] == pytest.approx(0.0, abs=1e-6)


class _NoZero:
    """The toy simulator refusing a cohesion of 0, as a simulator with a narrower domain."""

    name = "no-zero"

    def __call__(self, base, effects, seed):
        if not base["cohesion_energy_density"] > 0:
            raise ConfigError("key 'cohesion_energy_density' must be > 0; got 0.0")
        return _simulator(base, effects, seed)


def test_a_refused_recalibrated_point_is_named_as_such_not_as_the_base():
    ms = MeasurementSet(tuple(measurement_from_dict(dict(
        name=n, kind="static_angle", value=v, uncertainty=1.0, role=r))
        for n, v, r in [("a", -30.0, "calibrate"), ("b", 30.0, "calibrate"),
                        ("c", 0.0, "validate")]))
    with pytest.raises(ConfigError, match=r"refused the recalibrated parameters "
                                          r"\(cohesion_energy_density 0 \(at its bound\), base "
                                          r"1e\+07\), fitted to the calibration observables "
                                          r"a, b.*must be > 0") as info:
        diagnose(ms, _NoZero(), base={"cohesion_energy_density": 1e7}, effects=[_EFFECT],
                 nuisance=("cohesion_energy_density",), replicates=2, refine=0,
                 confirm_rounds=0)
    assert "[base]" not in str(info.value)


# --------------------------------------------------------------------------- [base] values

@pytest.mark.parametrize("line, match", [
    ("restitution = 1.5", r"\[base\]: key 'restitution': 1\.5 is outside its bounds: "
                          r"expected 0 < restitution <= 1"),
    ("restitution = -0.3", r"\[base\]: key 'restitution': -0\.3 is outside its bounds"),
    ("restitution = 0.0", r"\[base\]: key 'restitution': 0 is outside its bounds"),
    ("friction = inf", r"\[base\]: key 'friction': inf is outside its bounds: expected a "
                       r"finite number >= 0"),
    ("friction = -0.1", r"\[base\]: key 'friction': -0\.1 is outside its bounds"),
    ("rolling_friction = nan", r"\[base\]: key 'rolling_friction': nan is outside"),
    ("cohesion_energy_density = -1e7", r"\[base\]: key 'cohesion_energy_density': -1e\+07 is "
                                       r"outside its bounds: expected a finite number >= 0 J/m³"),
])
def test_every_base_value_is_checked_against_its_physical_bounds(tmp_path, line, match):
    """Recalibrated or not, each [base] value is finite and physical: an error naming the file
    and the key, before any run."""
    p = tmp_path / "sim.toml"
    p.write_text(f'[simulator]\nkind = "surrogate"\n[base]\n{line}\n')
    with pytest.raises(ConfigError, match=re.escape(str(p)) + " " + match):
        load_sim_config(p)


def test_base_values_on_the_bounds_load(tmp_path):
    p = tmp_path / "sim.toml"
    p.write_text('[base]\ncohesion_energy_density = 0.0\nfriction = 0\nrolling_friction = 0.0\n'
                 'restitution = 1.0\n')
    assert load_sim_config(p).base == {"cohesion_energy_density": 0.0, "friction": 0.0,
                                       "rolling_friction": 0.0, "restitution": 1.0}


def test_a_negative_seed_is_an_error_naming_its_key(tmp_path):
    p = tmp_path / "sim.toml"
    p.write_text('[simulator]\nseed = -3\n')
    with pytest.raises(ConfigError, match=re.escape(f"{p} [simulator]: key 'seed': expected an "
                                                    f"integer >= 0; got -3")):
        load_sim_config(p)
    with pytest.raises(ConfigError, match=r"seed \(the replicate seed, --seed\): expected an "
                                          r"integer >= 0; got -3"):
        load_sim_config("surrogate").diagnose_settings(seed=-3)
    assert load_sim_config("surrogate").diagnose_settings(seed=5)["seed"] == 5
    with pytest.raises(ConfigError, match=r"seed: expected an integer >= 0; got -1"):
        diagnose(_design(), _simulator, base={"cohesion_energy_density": 1e7}, seed=-1,
                 effects=[_EFFECT])
