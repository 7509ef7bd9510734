"""Trials that give no reading: a heap that stands as a block, no heap left to fit.

A measurement file may state how many trials its values summarise (``trials``) and, per
component, how many of them gave no reading (``not_measured``). An observable read in no
trial has no value: it is kept apart (``MeasurementSet.unmeasured``), takes no part in the
fit and is reported as data. The twins of a validation state their trials the same way.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from bedstruct.diagnose import (Observations, compute_fingerprints, diagnose, diagnosis_report,
                                load_measurements)
from bedstruct.diagnose.measurement_io import write_measurements
from bedstruct.diagnose.validation.twins import _twin_measurements
from bedstruct.errors import ConfigError
from diagnose_helpers import ToySimulator, toy_design, toy_effect
from test_diagnose_missing_data import Holes

HEAD = '[meta]\ntitle = "trials"\n'
PILE = ('\n[[observable]]\nname = "aor"\nkind = "static_angle"\nunit = "deg"\n'
        'value = 33.0\nuncertainty = 1.0\ntrials = 5\nnot_measured = 2\n')
BLOCK = ('\n[[observable]]\nname = "aor_after_rest"\nkind = "static_angle"\nunit = "deg"\n'
         'trials = 3\nnot_measured = 3\nnote = "the heap stood as a block"\n')


def _write(tmp_path, text, name="m.toml"):
    p = tmp_path / name
    p.write_text(HEAD + text)
    return p


def test_trials_and_readings_in_no_trial_are_read_and_written_back(tmp_path):
    ms = load_measurements(_write(tmp_path, PILE + BLOCK))
    assert ms.names == ("aor",)
    aor = ms["aor"]
    assert aor.trials == 5 and aor.not_measured.tolist() == [2] and not aor.measured_in_no_trial
    (block,) = ms.unmeasured
    assert block.name == "aor_after_rest" and block.measured_in_no_trial
    assert block.not_measured.tolist() == [3] and np.all(np.isnan(block.values))
    back = load_measurements(write_measurements(ms, tmp_path / "back.toml"))
    assert back.names == ms.names and [m.name for m in back.unmeasured] == ["aor_after_rest"]
    assert back["aor"].trials == 5 and back["aor"].not_measured.tolist() == [2]
    np.testing.assert_allclose(back["aor"].values, aor.values)
    assert back.unmeasured[0].not_measured.tolist() == [3]


def test_a_series_read_in_no_trial_takes_its_components_from_its_windows(tmp_path):
    text = ('\n[[observable]]\nname = "dyn"\nkind = "dynamic_angle_series"\nunit = "deg"\n'
            'windows = [[0.0, 0.1], [0.1, 1.0]]\ntrials = 2\nnot_measured = [2, 2]\n')
    ms = load_measurements(_write(tmp_path, PILE + text))
    (dyn,) = ms.unmeasured
    assert dyn.n_components == 2 and dyn.not_measured.tolist() == [2, 2]


@pytest.mark.parametrize("extra, message", [
    ("not_measured = 1\n", "needs 'trials'"),
    ("trials = 3\nnot_measured = 4\n", "between 0 and trials = 3"),
    ("trials = 0\n", "whole number >= 1"),
    ("trials = 2.5\n", "whole number >= 1"),
    ("trials = 3\nnot_measured = \"two\"\n", "whole number or a list"),
    ("trials = 3\nnot_measured = 3\n", "no reading in any of its 3 trial(s)"),
])
def test_bad_trial_counts_are_named(tmp_path, extra, message):
    text = ('\n[[observable]]\nname = "aor"\nkind = "static_angle"\nunit = "deg"\n'
            'value = 33.0\nuncertainty = 1.0\n' + extra)
    with pytest.raises(ConfigError, match="observable #1 'aor'") as err:
        load_measurements(_write(tmp_path, text))
    assert message in str(err.value)


def test_components_read_in_no_trial_beside_read_ones_are_refused(tmp_path):
    text = ('\n[[observable]]\nname = "dyn"\nkind = "dynamic_angle_series"\nunit = "deg"\n'
            'windows = [[0.0, 0.1], [0.1, 1.0]]\nvalue = [40.0, 35.0]\nuncertainty = 2.0\n'
            'trials = 2\nnot_measured = [2, 0]\n')
    with pytest.raises(ConfigError, match="an observable of their own"):
        load_measurements(_write(tmp_path, text))


def test_replicates_must_be_the_trials_that_gave_a_reading(tmp_path):
    text = ('\n[[observable]]\nname = "aor"\nkind = "static_angle"\nunit = "deg"\n'
            'replicates = [32.0, 34.0, 33.0]\ntrials = 5\nnot_measured = 1\n')
    with pytest.raises(ConfigError, match="3 replicate readings"):
        load_measurements(_write(tmp_path, text))
    ok = text.replace("not_measured = 1", "not_measured = 2")
    assert load_measurements(_write(tmp_path, ok, "ok.toml"))["aor"].trials == 5


def test_a_candidate_has_no_trials(tmp_path):
    text = ('\n[[observable]]\nname = "dry"\nkind = "static_angle"\nunit = "deg"\n'
            'role = "candidate"\nuncertainty = 1.0\ntrials = 3\n')
    with pytest.raises(ConfigError, match="a candidate"):
        load_measurements(_write(tmp_path, PILE + text))


N = 10
SENS = {"k": np.linspace(1.0, 2.0, N)}
RESP = {"A": np.r_[3, -3, 3, -3, 3, -3, 0, 3, -3, 0] * 1.0,
        "B": np.r_[0, 0, 4, 4, 4, -4, -4, 0, 4, -4] * 1.0}
EFFECTS = [toy_effect("A"), toy_effect("B")]


def test_a_twin_states_its_trials_and_those_without_a_reading(tmp_path):
    design = toy_design(N, n_validate=3)
    sim = ToySimulator(design, sens=SENS, effects=RESP, noise_sd=0.3)
    # o3 is never read; o5 is lost in the second of three repeated experiments
    holes = Holes(Holes(sim, "o3", lambda b, e, s: True), "o5", lambda b, e, s: s == 5 + 7919)
    intrinsic = Observations({m.name: [0.3] for m in design})
    twin = _twin_measurements(design, holes, {"k": 1.0}, {}, 5, tmp_path, 0, intrinsic, 3)
    assert "o3" not in twin.names and [m.name for m in twin.unmeasured] == ["o3"]
    assert twin.unmeasured[0].not_measured.tolist() == [3]
    assert twin["o5"].trials == 3 and twin["o5"].not_measured.tolist() == [1]
    assert all(twin[n].not_measured.tolist() == [0] for n in twin.names if n != "o5")
    # the value of o5 is the mean of the two experiments that read it
    runs = [holes({"k": 1.0}, {}, s)["o5"][0] for s in (5, 5 + 7919 * 2)]
    assert abs(twin["o5"].values[0] - np.mean(runs)) < 4 * 0.3


def test_the_diagnosis_reports_trials_without_a_reading_and_fits_the_rest(tmp_path):
    design = toy_design(N, n_validate=3)
    sim = ToySimulator(design, sens=SENS, effects=RESP, noise_sd=0.3)
    holes = Holes(sim, "o3", lambda b, e, s: e.get("A", 0.0) > 0.6 and s >= 5)
    fps = compute_fingerprints(holes, design, {"k": 1.0}, EFFECTS, nuisance=("k",), replicates=3)
    intrinsic = Observations({m.name: [0.3] for m in design})
    twin = _twin_measurements(design, holes, {"k": 1.0}, {"A": 0.8}, 5, tmp_path, 0, intrinsic, 3)
    assert [m.name for m in twin.unmeasured] == ["o3"]
    d = diagnose(twin, holes, base={"k": 1.0}, effects=EFFECTS, fingerprints=fps, refine=0)
    assert d.attribution.selected[0].effect == "A"
    (row,) = d.to_json()["not_measured"]
    assert row["observable"] == "o3" and row["in_no_trial"] and row["not_measured"] == [3]
    assert row["fingerprint_runs"] == fps.n_runs
    assert row["fingerprint_runs_without_reading"] == 0   # the fingerprint seeds (0-2) read it
    notes = d.data_notes()
    assert any(n.startswith("o3: no reading in any of its 3 trial(s)") for n in notes)
    # without trials stated, the same data say nothing of it
    plain = type(twin)(twin.measurements, title="no trials")
    assert plain.unmeasured == () and \
        not diagnose(plain, holes, base={"k": 1.0}, effects=EFFECTS, fingerprints=fps,
                     refine=0).to_json()["not_measured"]


# ---- the trials without a reading are weighed against the model's runs

def _mimic():
    """A and B change the readings alike; only A makes o3 give no reading (above 0.6), as
    an aged pile that stands as a block does."""
    design = toy_design(N, n_validate=3)
    sim = ToySimulator(design, sens=SENS, effects={"A": RESP["A"], "B": RESP["A"]}, noise_sd=0.3)
    return design, Holes(sim, "o3", lambda b, e, s: e.get("A", 0.0) > 0.6)


def _twin_and_fingerprints(tmp_path, design, sim):
    effects = [toy_effect("A"), toy_effect("B")]
    fps = compute_fingerprints(sim, design, {"k": 1.0}, effects, nuisance=("k",), replicates=3)
    intrinsic = Observations({m.name: [0.3] for m in design})
    twin = _twin_measurements(design, sim, {"k": 1.0}, {"A": 0.8}, 5, tmp_path, 0, intrinsic, 3)
    assert [m.name for m in twin.unmeasured] == ["o3"]
    return effects, fps, twin


def test_a_model_that_never_gives_the_trials_without_a_reading_is_unexplained(tmp_path):
    design, sim = _mimic()
    effects, fps, twin = _twin_and_fingerprints(tmp_path, design, sim)
    b_only = [e for e in effects if e.name == "B"]
    d = diagnose(twin, sim, base={"k": 1.0}, effects=b_only, fingerprints=fps, refine=0)
    assert d.verdict == "unexplained"
    assert "trials without a reading" in d.attribution.reason and "o3" in d.attribution.reason
    sh = d.shrink
    assert sh.p_rerun_trials < 0.01 and sh.trial_rows[0]["observable"] == "o3"
    assert sh.trial_rows[0]["unread"] == 3 and all(k == 0 for k, _ in sh.trial_rows[0]["pools"])
    # its rerun (3 seeds) was topped up with twice its seeds: 9 runs at B in both pools, with
    # the base-like points (base and k step, 3 each) and B at 0.5 below, B at 1.0 above
    b = d.attribution.selected[0].magnitude if d.attribution.selected else \
        float(sh.magnitudes["B"])
    assert 0.5 < b < 1.0
    assert sh.trial_rows[0]["pools"] == [[0, 3 + 3 + 3 + 9], [0, 3 + 9]]
    # the report shows the check and its table
    secs = [x for x in diagnosis_report(d).sections if "p_rerun_trials" in x.numbers]
    assert secs and secs[0].numbers["p_rerun_trials"].value == pytest.approx(sh.p_rerun_trials,
                                                                          rel=5e-3)
    assert any("trials without a reading" in t.columns for t in secs[0].tables)
    # the same readings without the trials stated: B fits them and is named
    plain = type(twin)(tuple(replace(m, trials=None, not_measured=None) for m in twin.measurements),
                       title="trials not stated")
    d0 = diagnose(plain, sim, base={"k": 1.0}, effects=b_only, fingerprints=fps, refine=0)
    assert d0.verdict == "attributed" and d0.attribution.selected[0].effect == "B"
    assert np.isnan(d0.shrink.p_rerun_trials)


def test_fingerprints_made_for_the_file_simulate_what_it_read_in_no_trial(tmp_path):
    """Without fingerprints given, the diagnosis simulates the file's design: an observable
    read in no trial is in it (the trial check needs its runs) and not offered as a measurement
    to make next."""
    from bedstruct.diagnose import diagnosis_design
    design, sim = _mimic()
    effects, _, twin = _twin_and_fingerprints(tmp_path, design, sim)
    assert "o3" in diagnosis_design(twin, effects).names
    b_only = [e for e in effects if e.name == "B"]
    d = diagnose(twin, sim, base={"k": 1.0}, effects=b_only, nuisance=("k",), replicates=3,
                 refine=0)
    assert d.verdict == "unexplained" and "trials without a reading" in d.attribution.reason
    assert d.shrink.trial_rows[0]["observable"] == "o3" and d.shrink.p_rerun_trials < 0.01
    assert all(n.observable != "o3" for n in d.next)
    from bedstruct.diagnose import answer
    which = answer(d).which
    assert "not the trials that gave none" in which and "o3 gave no reading in 3 of your 3" in which
    a_only = [e for e in effects if e.name == "A"]
    d_a = diagnose(twin, sim, base={"k": 1.0}, effects=a_only, nuisance=("k",), replicates=3,
                   refine=0)
    assert d_a.verdict == "attributed" and d_a.shrink.p_rerun_trials >= 0.01


def test_the_model_that_gives_them_is_confirmed(tmp_path):
    design, sim = _mimic()
    effects, fps, twin = _twin_and_fingerprints(tmp_path, design, sim)
    a_only = [e for e in effects if e.name == "A"]
    d = diagnose(twin, sim, base={"k": 1.0}, effects=a_only, fingerprints=fps, refine=0)
    assert d.verdict == "attributed" and d.attribution.selected[0].effect == "A"
    assert d.shrink.p_rerun_trials >= 0.01
    assert d.to_json()["shrink"]["trial_rows"][0]["observable"] == "o3"


def test_null_data_with_a_trial_the_base_never_fails_are_unexplained(tmp_path):
    design, sim = _mimic()
    effects, fps, _ = _twin_and_fingerprints(tmp_path, design, sim)
    intrinsic = Observations({m.name: [0.3] for m in design})
    null = _twin_measurements(design, sim, {"k": 1.0}, {}, 7, tmp_path, 1, intrinsic, 3)
    m3 = null["o3"]
    blocked = type(null)(tuple(m for m in null.measurements if m.name != "o3"), title="o3 stood",
                         unmeasured=(replace(m3, values=np.full(1, np.nan),
                                             not_measured=np.array([3])),))
    d_null = diagnose(null, sim, base={"k": 1.0}, effects=effects, fingerprints=fps, refine=0)
    assert d_null.verdict == "none" and d_null.shrink.p_rerun_trials == 1.0
    d = diagnose(blocked, sim, base={"k": 1.0}, effects=effects, fingerprints=fps, refine=0)
    assert d.verdict == "unexplained" and "trials without a reading" in d.attribution.reason


def test_pools_and_the_p_value_follow_the_counts():
    from bedstruct.diagnose.trial_counts import model_pools, observable_p, trial_check
    pts = [{"effects": {}, "unread": 0, "runs": 6}, {"effects": {"e": 1.0}, "unread": 3, "runs": 3},
           {"effects": {"f": 1.0}, "unread": 0, "runs": 3}]
    # f's points are not e's; a pair is judged on its own rerun
    assert model_pools(pts, {"e": 0.5}, (1, 3)) == [(1, 9), (4, 6)]
    assert model_pools(pts, {"e": 0.4, "f": 0.2}, (1, 3)) == [(1, 3)]
    # the larger p of the two sides: the side whose rate is nearer the data's
    assert observable_p((3, 3), [(0, 15), (4, 6)]) == observable_p((3, 3), [(4, 6)])
    assert observable_p((0, 3), [(0, 9)]) == 1.0 and observable_p((3, 3), [(9, 9)]) == 1.0
    # Fisher's exact test by hand: 3 of 3 trials unread against 0 of n runs is the chance
    # that the three unread fall on the trials, 1 / C(n + 3, 3)
    assert observable_p((3, 3), [(0, 15)]) == pytest.approx(1 / 816)
    assert observable_p((3, 3), [(0, 12)]) == pytest.approx(1 / 455)
    # Sidak over the observables with a trial or a run without a reading only
    many = {f"o{i}": (0, 3) for i in range(10)} | {"x": (3, 3)}
    runs = {n: (0, 12) for n in many}
    chk = trial_check(many, {}, {}, runs)
    assert chk.n_tested == 1 and chk.p_value == pytest.approx(observable_p((3, 3), [(0, 12)]))
    two = trial_check({"x": (3, 3), "y": (2, 3), "z": (0, 3)}, {}, {},
                      {"x": (0, 12), "y": (0, 12), "z": (0, 12)})
    p0 = observable_p((3, 3), [(0, 12)])
    assert two.n_tested == 2 and two.p_value == pytest.approx(1 - (1 - p0) ** 2)
    assert [r["observable"] for r in two.rows] == ["x", "y"]


def test_trials_of_an_observable_the_simulation_does_not_give_are_not_tested(tmp_path):
    design, sim = _mimic()
    effects, fps, twin = _twin_and_fingerprints(tmp_path, design, sim)
    extra = replace(twin.unmeasured[0], name="not_simulated")
    both = replace(twin, unmeasured=twin.unmeasured + (extra,))
    d = diagnose(both, sim, base={"k": 1.0}, effects=effects[:1], fingerprints=fps, refine=0)
    rows = {r["observable"]: r for r in d.to_json()["not_measured"]}
    assert rows["o3"]["simulated"] and not rows["not_simulated"]["simulated"]
    assert any(n.startswith("not_simulated:") and "not tested" in n for n in d.data_notes())
    assert all(r["observable"] != "not_simulated" for r in d.shrink.trial_rows)


def test_the_trials_check_holds_its_level_for_a_true_model():
    """Data and runs drawn from one model: the check rejects at most at its level, also where
    the rate of a run without a reading grows with the magnitude and the pools straddle it."""
    from bedstruct.diagnose.trial_counts import trial_check
    rng = np.random.default_rng(7)
    alpha, n_draws = 0.05, 1500
    # flat; rising; and from never at the base to always at the prior top, where the smaller
    # of the two pools' p-values would reject a true model in about a third of the draws
    for rate in (lambda a: 0.3, lambda a: 0.1 + 0.6 * a, lambda a: a):
        a = 0.5
        rejected = 0
        for _ in range(n_draws):
            points = {"o": [{"effects": {}, "unread": int(rng.binomial(6, rate(0.0))), "runs": 6},
                            {"effects": {"e": 0.25}, "unread": int(rng.binomial(3, rate(0.25))),
                             "runs": 3},
                            {"effects": {"e": 1.0}, "unread": int(rng.binomial(3, rate(1.0))),
                             "runs": 3}]}
            data = {"o": (int(rng.binomial(3, rate(a))), 3)}
            rerun = {"o": (int(rng.binomial(9, rate(a))), 9)}
            rejected += trial_check(data, points, {"e": a}, rerun).p_value < alpha
        assert rejected / n_draws <= alpha + 3 * np.sqrt(alpha * (1 - alpha) / n_draws)


def test_a_file_read_in_no_trial_at_all_is_refused_by_name(tmp_path):
    design, sim = _mimic()
    effects, fps, twin = _twin_and_fingerprints(tmp_path, design, sim)
    nothing = type(twin)((), title="nothing read", unmeasured=twin.unmeasured)
    with pytest.raises(ConfigError, match="nothing read: no calibration observable gave a "
                                          "reading in any of its trials \\(o3\\)"):
        diagnose(nothing, sim, base={"k": 1.0}, effects=effects, fingerprints=fps, refine=0)
