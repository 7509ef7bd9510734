"""The verdict when recalibration alone closes a significant gap.

A cohesion calibrated elsewhere gives a large gap that recalibrating it closes on every
observable, held-out ones included: the answer is ``none`` (no effect needed), said so.
A gap that recalibration absorbs on the calibration observables but that the held-out
observables still show stays ``unexplained``. An attribution that closes most of the held-out
gap but leaves a remainder beyond noise is named as partial. The rerun's check on the
held-out observables has its own level (``heldout_alpha``): true models fail it at about
that rate, and a held-out gap the model does not make is caught by it.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from bedstruct.diagnose import compute_fingerprints, diagnose, diagnosis_report
from diagnose_helpers import ToySimulator, toy_design, toy_effect

N = 12
SENS = {"k": np.linspace(1.0, 2.0, N)}
RESP = {"A": np.r_[3, -3, 3, -3, 3, -3, 0, 0, 0, 3, -3, 0] * 1.0}


def _setup():
    design = toy_design(N, n_validate=3)
    sim = ToySimulator(design, sens=SENS, effects=RESP, noise_sd=0.0)
    fps = compute_fingerprints(sim, design, {"k": 1.0}, [toy_effect("A")], nuisance=("k",),
                               replicates=3, alpha=0.01)
    return design, sim, fps


def _real(design, values):
    from bedstruct.diagnose import Observations
    return design.with_values(Observations({f"o{i}": [v] for i, v in enumerate(values)}))


def test_a_gap_that_recalibration_closes_everywhere_is_none_and_says_so():
    design, sim, fps = _setup()
    rng = np.random.default_rng(4)
    y = SENS["k"] * 3.0 + rng.normal(0.0, 1.0, N)       # cohesion off by +3: a 10-sigma gap
    d = diagnose(_real(design, y), sim, base={"k": 1.0}, effects=[toy_effect("A")], fingerprints=fps,
                 refine=0)
    assert d.where.significant and d.where.max_abs_z > 5
    assert d.verdict == "none"
    assert "recalibration alone closes the gap" in d.attribution.reason
    assert d.shrink.recalibrated_excess < 0.5 * d.shrink.before_excess


def test_a_gap_left_on_the_held_out_observables_stays_unexplained():
    design, sim, fps = _setup()
    rng = np.random.default_rng(5)
    y = SENS["k"] * 3.0 + rng.normal(0.0, 1.0, N)
    y[-3:] += np.r_[6.0, -6.0, 6.0]                      # something the model lacks, held out only
    d = diagnose(_real(design, y), sim, base={"k": 1.0}, effects=[toy_effect("A")], fingerprints=fps,
                 refine=0)
    assert d.where.significant
    assert d.verdict == "unexplained"
    assert "inconsistent" in d.attribution.reason


class _BumpSimulator(ToySimulator):
    """Effect A's response is F * (m + c sin(2 pi m)): exactly linear at the fingerprint's
    magnitudes (0.5 and 1 of its prior), twice the linear value at a = 0.25."""

    def __call__(self, base, effects, seed):
        bent = dict(effects)
        if "A" in bent:
            bent["A"] = bent["A"] + 0.25 * np.sin(2.0 * np.pi * bent["A"])
        return super().__call__(base, bent, seed)


def _bump_setup():
    design = toy_design(N, n_validate=3)
    sim = _BumpSimulator(design, sens=SENS, effects={"A": 8.0 * RESP["A"] / 3.0}, noise_sd=0.0)
    fps = compute_fingerprints(sim, design, {"k": 1.0}, [toy_effect("A")], nuisance=("k",),
                               replicates=3, alpha=0.01)
    return design, sim, fps


def test_an_attribution_its_rerun_contradicts_on_the_calibration_observables_is_not_confirmed():
    design, sim, fps = _bump_setup()
    # the interpolation between the simulated magnitudes cannot see the bump
    np.testing.assert_allclose(fps["A"].predict(0.25), 0.25 * 8.0 * RESP["A"] / 3.0, atol=0.1)
    rng = np.random.default_rng(6)
    # a gap shaped like A's linear interpolation at 0.25, which A itself cannot make there
    y = 0.25 * 8.0 * RESP["A"] / 3.0 + rng.normal(0.0, 1.0, N)
    d = diagnose(_real(design, y), sim, base={"k": 1.0}, effects=[toy_effect("A")], fingerprints=fps,
                 refine=0, confirm_rounds=0)
    assert d.attribution.best.effects == ("A",) and d.attribution.best.p_fit > 0.05
    assert d.shrink.p_rerun_calibration < 0.01 and d.shrink.refits == ()
    assert d.verdict == "unexplained"
    assert "calibration observables (p =" in d.attribution.reason
    assert "not confirmed" in d.attribution.reason
    # the reason names where the rerun departs: the bump doubles A's response, so the
    # largest calibration departures lie where A responds (o0-o5), none where it does not
    worst = [w for w in d.shrink.rerun_worst if w["role"] == "calibrate"]
    assert worst and abs(worst[0]["z"]) > 2.0
    assert all(int(w["observable"][1:]) <= 5 for w in worst if abs(w["z"]) > 2.0)
    assert f"largest {worst[0]['observable']} [value] {worst[0]['z']:+.1f} sigma" in d.attribution.reason
    assert d.shrink.as_dict()["rerun_worst"][0] == worst[0]


def test_a_rerun_that_contradicts_the_interpolation_becomes_a_node_and_the_refit_is_confirmed():
    design, sim, fps = _bump_setup()
    rng = np.random.default_rng(6)
    y = 0.25 * 8.0 * RESP["A"] / 3.0 + rng.normal(0.0, 1.0, N)
    d = diagnose(_real(design, y), sim, base={"k": 1.0}, effects=[toy_effect("A")], fingerprints=fps,
                 refine=0)
    # A makes this gap where a + 0.25 sin(2 pi a) = 0.25 (a = 0.10): the first rerun, at the
    # interpolation's magnitude, says the bump is there; refitted through it, A lands below
    (first,) = d.shrink.refits
    assert first["p_rerun_calibration"] < 0.01 and first["seeds"] == [1000, 1001, 1002]
    assert d.verdict == "attributed" and d.attribution.best.effects == ("A",)
    a_fit = d.attribution.best.magnitudes[0]
    assert a_fit < 0.75 * first["magnitudes"]["A"]
    assert abs(a_fit + 0.25 * np.sin(2 * np.pi * a_fit) - 0.25) < 0.1   # A at a_fit makes the gap
    assert d.shrink.p_rerun_calibration > 0.01 and d.shrink.magnitudes["A"] == a_fit
    assert "became a fingerprint node" in d.attribution.reason
    assert np.isclose(d.fingerprints["A"].nodes, first["magnitudes"]["A"]).sum() == 1
    # recalibrated rerun, two reruns of A, and the base at the fitted shift of k (beyond the
    # finite-difference step; linear here, so it changed nothing and A's node was refitted)
    assert d.settings["simulator_runs"] == 12 and "recalibration" not in first
    assert d.to_json()["shrink"]["refits"][0]["model"] == "A"
    rep = diagnosis_report(d)
    assert rep.failed == []
    (how_far,) = [s for s in rep.sections if s.key == "shrink"]
    assert any("refitted" in (t.caption or "") for t in how_far.tables)
    # the response figure marks the rerun's node apart from the fingerprint's magnitudes
    import matplotlib
    matplotlib.use("Agg")
    from bedstruct.diagnose.figures import plot_effect_response
    fig, ax = plot_effect_response(d)
    diamonds = [ln for ln in ax.get_lines() if ln.get_marker() == "D"]
    assert diamonds and np.isclose(diamonds[0].get_xdata(), first["magnitudes"]["A"]).all()
    assert ax.patches or any(isinstance(c, matplotlib.patches.Polygon) for c in ax.get_children())


class _TwistSimulator(ToySimulator):
    """Effect A adds, between its fingerprint magnitudes, a pattern it has nowhere else."""

    twist = np.r_[0, 0, 0, 0, 0, 0, 1, -1, 1, 0, 0, 0] * 6.0

    def __call__(self, base, effects, seed):
        from bedstruct.diagnose import Observations
        out = super().__call__(base, effects, seed)
        a = effects.get("A", 0.0)
        v = out.vector([m.name for m in self.design]) + np.sin(2.0 * np.pi * a) * self.twist
        return Observations({m.name: [v[i]] for i, m in enumerate(self.design)}, source="toy")


def test_a_model_its_rerun_contradicts_in_shape_is_refitted_and_left_unexplained():
    design = toy_design(N, n_validate=3)
    sim = _TwistSimulator(design, sens=SENS, effects={"A": 8.0 * RESP["A"] / 3.0}, noise_sd=0.0)
    fps = compute_fingerprints(sim, design, {"k": 1.0}, [toy_effect("A")], nuisance=("k",),
                               replicates=3, alpha=0.01)
    y = 0.25 * 8.0 * RESP["A"] / 3.0 + np.random.default_rng(6).normal(0.0, 1.0, N)
    d = diagnose(_real(design, y), sim, base={"k": 1.0}, effects=[toy_effect("A")], fingerprints=fps,
                 refine=0)
    # no magnitude of A makes this gap: through the rerun's node, A no longer fits at all
    assert len(d.shrink.refits) == 1 and d.verdict == "unexplained"
    assert "became a fingerprint node" in d.attribution.reason
    assert not d.attribution.selected and np.isnan(d.shrink.p_rerun_calibration)
    assert d.settings["simulator_runs"] == 9         # no rerun after the refit failed


def test_an_attribution_its_rerun_reproduces_stays_attributed():
    design, sim, fps = _bump_setup()
    rng = np.random.default_rng(6)
    y = 0.5 * 8.0 * RESP["A"] / 3.0 + rng.normal(0.0, 1.0, N)   # A at a simulated magnitude
    d = diagnose(_real(design, y), sim, base={"k": 1.0}, effects=[toy_effect("A")], fingerprints=fps,
                 refine=0)
    assert d.verdict == "attributed"
    assert d.shrink.p_rerun_calibration > 0.01 and d.shrink.p_rerun_heldout > 0.01
    assert "p_rerun_calibration" in d.to_json()["shrink"]


def test_the_rerun_check_rejects_a_true_model_at_about_its_level():
    # runs scatter (common seeds within a point, as on the engine); the data state that
    # scatter on top of their reading noise, so the true model should fail ~gof_alpha
    noise = 1.0
    design = toy_design(N, n_validate=3, sigma=float(np.sqrt(1.0 + 2.0 * noise ** 2)))
    sim = ToySimulator(design, sens=SENS, effects={"A": 3.0 * RESP["A"]}, noise_sd=noise)
    fps = compute_fingerprints(sim, design, {"k": 1.0}, [toy_effect("A")], nuisance=("k",),
                               replicates=3, alpha=0.01)
    rng = np.random.default_rng(9)
    p_cal, n = [], 150
    for i in range(n):
        y = sim({"k": 1.0}, {"A": 0.7}, 50_000 + i).vector(fps.names) + rng.standard_normal(N)
        d = diagnose(_real(design, y), sim, base={"k": 1.0}, effects=[toy_effect("A")],
                     fingerprints=fps, refine=0, confirm_rounds=0, seed=100 + i)
        if d.attribution.best.effects == ("A",):
            p_cal.append(d.shrink.p_rerun_calibration)
    p_cal = np.asarray(p_cal)
    assert len(p_cal) > 0.8 * n and np.all(np.isfinite(p_cal))
    assert np.mean(p_cal < 0.01) <= 0.04                 # its level, with room for 150 draws
    # conservative (the stated noise holds one run's scatter at its upper bound, the rerun's
    # mean adds its own, and so does the noise of the runs the fit reads through
    # too), but its p-values are not stuck at 1
    assert np.mean(p_cal < 0.9) > 0.15


def test_a_pair_whose_rerun_contradicts_it_is_not_refitted():
    # a pair's rerun cannot be split between its two effects: it stays "not confirmed"
    resp_b = np.r_[0, 0, 0, 3, 3, -3, 3, -3, 3, 0, 3, 3] * 1.0
    design = toy_design(N, n_validate=3)
    sim = _BumpSimulator(design, sens=SENS, effects={"A": 8.0 * RESP["A"] / 3.0,
                                                     "B": 8.0 * resp_b / 3.0}, noise_sd=0.0)
    effects = [toy_effect("A"), toy_effect("B")]
    fps = compute_fingerprints(sim, design, {"k": 1.0}, effects, nuisance=("k",), replicates=3,
                               alpha=0.01)
    y = (0.25 * 8.0 * RESP["A"] / 3.0 + 0.5 * 8.0 * resp_b / 3.0
         + np.random.default_rng(0).normal(0.0, 1.0, N))
    d = diagnose(_real(design, y), sim, base={"k": 1.0}, effects=effects, fingerprints=fps, refine=0)
    assert d.attribution.best.effects == ("A", "B")
    assert d.shrink.p_rerun_calibration < 0.01 and d.shrink.refits == ()
    assert d.verdict == "unexplained" and "not confirmed" in d.attribution.reason
    assert d.settings["simulator_runs"] == 9         # with the base at the fitted shift of k
    # the answer says so in words, and the first figure shows the rejected rerun as such
    from bedstruct.diagnose.answer import answer
    from bedstruct.diagnose.figures import plot_gaps
    which = answer(d).which
    assert which.startswith("No effect is named: the best candidate, A (A magnitude 0.")
    assert ") together with B (B magnitude 0." in which
    assert "the simulation rerun with it does not reproduce the measurements" in which
    assert "p = " not in which
    _, ax = plot_gaps(d)
    assert [c.get_label() for c in ax.containers][-1] == "recalibrated + A + B (rejected by its rerun)"


class _CurvedNuisanceSimulator(ToySimulator):
    """The observables bend with k: a 5 % finite difference underestimates a 20 % shift."""

    def __call__(self, base, effects, seed):
        dk = base["k"] - 1.0
        return super().__call__({"k": 1.0 + dk * (1.0 + 2.5 * dk)}, effects, seed)


def test_a_recalibration_beyond_the_finite_difference_step_is_resimulated():
    design = toy_design(N, n_validate=3)
    sim = _CurvedNuisanceSimulator(design, sens={"k": np.linspace(10.0, 20.0, N)},
                                   effects={"A": 8.0 * RESP["A"] / 3.0}, noise_sd=0.0)
    fps = compute_fingerprints(sim, design, {"k": 1.0}, [toy_effect("A")], nuisance=("k",),
                               replicates=3, alpha=0.01)
    assert fps.meta["sensitivity_steps"] == {"k": pytest.approx(0.05)}
    y = sim({"k": 1.2}, {"A": 0.5}, 0).vector(fps.names) + np.random.default_rng(0).normal(0, 1, N)
    d = diagnose(_real(design, y), sim, base={"k": 1.0}, effects=[toy_effect("A")], fingerprints=fps,
                 refine=0)
    (first,) = d.shrink.refits
    # the linear fit through the 5 % step overshot the shift (0.28 for 0.2): its rerun failed
    assert first["recalibration"]["k"] > 0.25 and first["p_rerun_calibration"] < 1e-4
    assert "node" not in first
    assert d.verdict == "attributed" and d.attribution.best.effects == ("A",)
    assert abs(d.shrink.nuisance["k"] - 0.2) < 0.03 and abs(d.shrink.magnitudes["A"] - 0.5) < 0.05
    assert d.shrink.p_rerun_calibration > 0.01
    assert "extrapolated the finite-difference sensitivities" in d.attribution.reason
    # recalibrated rerun, first rerun, the base at the fitted shift (base seeds), second rerun
    assert d.settings["simulator_runs"] == 12


def test_the_reruns_show_progress(capsys):
    design, sim, fps = _bump_setup()
    y = 0.25 * 8.0 * RESP["A"] / 3.0 + np.random.default_rng(6).normal(0.0, 1.0, N)
    d = diagnose(_real(design, y), sim, base={"k": 1.0}, effects=[toy_effect("A")], fingerprints=fps,
                 refine=0, progress=True)
    err = capsys.readouterr().err
    assert "reruns" in err and f"{d.settings['simulator_runs']}run" in err.replace(" ", "")


def _calibration_check_p(n_draws: int) -> np.ndarray:
    """The calibration check's p-values of true models (effect A and a recalibration shift
    of 1.5 finite-difference steps), with data more precise than one run.
    Four calibration observables, each parameter read mostly from one or two: the noise of
    the runs a parameter is fitted through passes whole into it. Each draw has its own
    fingerprints, so that their noise varies too."""
    n = 6
    design = toy_design(n, n_validate=2, sigma=0.3)
    sens = {"k": np.r_[0.0, 40.0, 60.0, 0.0, 50.0, 30.0]}     # one 5 % step: 2-3 on o1, o2
    resp = {"A": np.r_[6.0, 0.0, 0.0, 2.0, 4.0, 0.0]}
    sim = ToySimulator(design, sens=sens, effects=resp, noise_sd=1.0)   # one run: sd 1.4
    exact = ToySimulator(design, sens=sens, effects=resp)
    rng = np.random.default_rng(12)
    p = []
    for i in range(n_draws):
        fps = compute_fingerprints(sim, design, {"k": 1.0}, [toy_effect("A")], nuisance=("k",),
                                   replicates=3, alpha=0.01, seed=10_000 * (i + 1))
        y = exact({"k": 1.075}, {"A": 0.7}, 0).vector(fps.names) + rng.normal(0.0, 0.3, n)
        d = diagnose(_real(design, y), sim, base={"k": 1.0}, effects=[toy_effect("A")],
                     fingerprints=fps, refine=0, confirm_rounds=0, seed=10_000 * (i + 1) + 500)
        if d.attribution.best.effects == ("A",) and np.isfinite(d.shrink.p_rerun_calibration):
            p.append(d.shrink.p_rerun_calibration)   # (NaN: recalibration alone closed it)
    return np.asarray(p)


def _without_the_fits_error(monkeypatch):
    """The calibration check without the variance from the error of the
    fitted magnitudes and shifts."""
    import importlib
    dmod = importlib.import_module("bedstruct.diagnose.diagnosis")
    real_confirm = dmod.confirm_attribution

    def confirm(att, *a, **k):   # a fit that does not state its runs' share
        older = replace(att.best, stderr_runs=np.zeros(0), nuisance_stderr_runs=np.zeros(0))
        return real_confirm(replace(att, best=older), *a, **k)
    monkeypatch.setattr(dmod, "confirm_attribution", confirm)


def test_the_calibration_check_carries_the_fits_own_noise(monkeypatch):
    # The rerun departs from the data by the error of the fitted magnitude and shift. The
    # data's noise cancels from it (they were fitted to these data); the noise of the runs
    # the fit reads them through (base, finite-difference point, A's nodes) does not. With
    # that variance true models seldom fail; without it more often,
    # and never less (same runs, a smaller variance).
    p = _calibration_check_p(40)
    assert len(p) >= 25 and np.mean(p < 0.05) <= 0.1
    _without_the_fits_error(monkeypatch)
    p_before = _calibration_check_p(40)
    assert len(p_before) == len(p) and np.all(p_before <= p + 1e-12)
    assert np.sum(p_before < 0.05) > np.sum(p < 0.05)


@pytest.mark.slow
def test_the_calibration_check_holds_its_level_for_true_models(monkeypatch):
    p = _calibration_check_p(150)
    assert len(p) >= 100
    assert np.mean(p < 0.01) <= 0.03 and np.mean(p < 0.05) <= 0.06
    _without_the_fits_error(monkeypatch)
    p_before = _calibration_check_p(150)
    assert np.mean(p_before < 0.05) >= 0.09          # about 14 %: almost three times its level


def _held_out_remainder_case(extra: float, seed: int):
    """Effect A at 0.6 with a held-out response ``1 + extra`` times A's own: A explains
    the calibration observables fully and the held-out ones in part."""
    from bedstruct.diagnose import Observations

    resp = np.r_[3, -3, 3, -3, 3, -3, 0, 0, 0, 3, -3, 3] * 3.0
    design = toy_design(N, n_validate=3)
    sim = ToySimulator(design, sens=SENS, effects={"A": resp}, noise_sd=0.0)
    fps = compute_fingerprints(sim, design, {"k": 1.0}, [toy_effect("A")], nuisance=("k",),
                               replicates=3, alpha=0.01)
    y = 0.6 * resp + np.random.default_rng(seed).normal(0.0, 1.0, N)
    y[-3:] += extra * 0.6 * resp[-3:]
    real = design.with_values(Observations({f"o{i}": [v] for i, v in enumerate(y)}))
    return real, sim, fps


@pytest.mark.parametrize("seed", [0, 1])
def test_an_effect_that_closes_most_of_the_held_out_gap_is_named_as_partial(seed):
    from bedstruct.diagnose.answer import answer, compact_answer

    real, sim, fps = _held_out_remainder_case(0.7, seed)
    d = diagnose(real, sim, base={"k": 1.0}, effects=[toy_effect("A")], fingerprints=fps,
                 refine=0)
    sh = d.shrink
    assert sh.p_rerun_calibration >= 0.01 and sh.p_rerun_heldout < 0.01
    assert sh.fraction_interval[0] > 0.5 and sh.fraction < 0.9
    assert d.verdict == "attributed" and d.attribution.partial
    assert d.attribution.selected[0].effect == "A"
    assert "a partial explanation, something else remains" in d.attribution.reason
    assert "something else remains" in answer(d).headline
    assert "a partial explanation" in answer(d).which
    assert compact_answer(d)["partial"] is True and compact_answer(d)["effect"] == "A"
    assert d.to_json()["partial"] is True
    # with partial explanations turned off the same rerun is not confirmed
    off = diagnose(real, sim, base={"k": 1.0}, effects=[toy_effect("A")], fingerprints=fps,
                   refine=0, partial_shrink=1.0)
    assert off.verdict == "unexplained" and not off.attribution.partial
    assert "not confirmed" in off.attribution.reason


def test_an_effect_that_closes_less_than_half_of_the_held_out_gap_is_not_confirmed():
    real, sim, fps = _held_out_remainder_case(3.0, 0)
    d = diagnose(real, sim, base={"k": 1.0}, effects=[toy_effect("A")], fingerprints=fps,
                 refine=0)
    assert d.shrink.fraction_interval[1] < 0.5
    assert d.verdict == "unexplained" and not d.attribution.partial
    assert "not confirmed" in d.attribution.reason


def _held_out_offset_case(seed: int, offset: float = 2.0, held_response: float = 0.3):
    """Effect A at 0.6 with a held-out response of ``1.8 * held_response`` per component
    (noise 1) plus a held-out ``offset`` that no catalogue effect makes."""
    from bedstruct.diagnose import Observations

    h = held_response
    resp = np.r_[3, -3, 3, -3, 3, -3, 0, 0, 0, h, -h, h] * 3.0
    design = toy_design(N, n_validate=3)
    sim = ToySimulator(design, sens=SENS, effects={"A": resp}, noise_sd=0.0)
    fps = compute_fingerprints(sim, design, {"k": 1.0}, [toy_effect("A")], nuisance=("k",),
                               replicates=3, alpha=0.01)
    y = 0.6 * resp + np.random.default_rng(seed).normal(0.0, 1.0, N)
    y[-3:] += np.r_[offset, -offset, offset]
    real = design.with_values(Observations({f"o{i}": [v] for i, v in enumerate(y)}))
    return real, sim, fps


@pytest.mark.parametrize("seed", [0, 1])
def test_a_held_out_departure_at_the_held_out_level_is_not_confirmed(seed):
    # A fits the calibration observables; the held-out ones depart from A's rerun by more
    # than noise at 10 % but not at 1 %
    real, sim, fps = _held_out_offset_case(seed)
    kw = dict(base={"k": 1.0}, effects=[toy_effect("A")], fingerprints=fps, refine=0)
    d = diagnose(real, sim, **kw)
    sh = d.shrink
    assert sh.p_rerun_calibration >= 0.01 and 0.01 <= sh.p_rerun_heldout < 0.1
    assert d.verdict == "unexplained" and not d.attribution.partial
    assert f"the held-out observables (p = {sh.p_rerun_heldout:.2g} < 0.1" in d.attribution.reason
    assert "not confirmed" in d.attribution.reason
    assert d.settings["heldout_alpha"] == 0.1
    # at the calibration check's level the same rerun passes and A is named
    loose = diagnose(real, sim, heldout_alpha=0.01, **kw)
    assert loose.verdict == "attributed" and loose.attribution.selected[0].effect == "A"


def test_the_held_out_check_fails_true_models_at_about_its_level_and_catches_an_offset():
    # 40 draws each: the true model (A alone, held-out response 1.8 sigma per component)
    # is not confirmed in about 10 % of draws at most; with a held-out offset A does not
    # make, in most
    true_fail = 0
    for s in range(40):
        real, sim, fps = _held_out_offset_case(s, 0.0, 1.0)
        true_fail += diagnose(real, sim, base={"k": 1.0}, effects=[toy_effect("A")],
                              fingerprints=fps, refine=0).verdict != "attributed"
    _, sim, fps = _held_out_offset_case(0)
    caught = 0
    for s in range(40):
        real, _, _ = _held_out_offset_case(s)
        caught += diagnose(real, sim, base={"k": 1.0}, effects=[toy_effect("A")],
                           fingerprints=fps, refine=0).verdict == "unexplained"
    assert true_fail <= 8            # 40 x 0.1 = 4 expected; 8 is beyond its 95 % range
    assert caught >= 24


def test_recalibration_whose_rerun_departs_from_the_held_out_observables_is_not_none():
    design, sim, fps = _setup()
    rng = np.random.default_rng(7)
    y = SENS["k"] * 0.9 + rng.normal(0.0, 1.0, N)       # a cohesion gap...
    y[-3:] += np.r_[2.0, -2.0, 2.0]                      # ...and a held-out one besides
    kw = dict(base={"k": 1.0}, effects=[toy_effect("A")], fingerprints=fps, refine=0)
    d = diagnose(_real(design, y), sim, **kw)
    assert d.where.significant
    assert d.verdict == "unexplained"
    assert "the rerun at the recalibrated base leaves the measured observables inconsistent" \
        in d.attribution.reason
    loose = diagnose(_real(design, y), sim, heldout_alpha=0.01, **kw)
    assert loose.verdict == "none"
    assert "recalibration alone closes the gap" in loose.attribution.reason


def test_a_fully_confirmed_attribution_is_not_partial():
    real, sim, fps = _held_out_remainder_case(0.0, 1)
    d = diagnose(real, sim, base={"k": 1.0}, effects=[toy_effect("A")], fingerprints=fps,
                 refine=0)
    assert d.verdict == "attributed" and not d.attribution.partial
    assert d.shrink.p_rerun_heldout >= 0.01
