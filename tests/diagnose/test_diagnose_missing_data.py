"""Missing data: a simulator run or an 'experiment' that cannot observe an observable.

A small DEM scale model sometimes leaves no heap to fit (NaN dynamic angle). The
diagnosis treats such a value as missing: means and paired differences use the
replicates that observed it, an observable some parameter point never observed is
dropped (and said so), and a measurement file without an observable is diagnosed on
the rest.
"""

from __future__ import annotations

import numpy as np
import pytest

from bedstruct.diagnose import (MeasurementSet, Observations, compute_fingerprints, diagnose,
                                diagnosis_report, standardised_residuals)
from bedstruct.diagnose.confirm import gap_size
from bedstruct.diagnose.fingerprints import selection_threshold
from bedstruct.diagnose.validation.twins import _twin_measurements
from diagnose_helpers import ToySimulator, toy_design, toy_effect

N = 10
SENS = {"k": np.linspace(1.0, 2.0, N)}
RESP = {"A": np.r_[3, -3, 3, -3, 3, -3, 0, 3, -3, 0] * 1.0,
        "B": np.r_[0, 0, 4, 4, 4, -4, -4, 0, 4, -4] * 1.0}
EFFECTS = [toy_effect("A"), toy_effect("B")]


class Holes:
    """Wrap a simulator: NaN for ``name`` where ``lost(base, effects, seed)`` is true."""

    def __init__(self, sim, name, lost):
        self.sim, self.name, self.lost = sim, name, lost

    def __call__(self, base, effects, seed):
        obs = self.sim(base, effects, seed)
        vals = dict(obs.values)
        if self.lost(base, effects, seed):
            vals[self.name] = np.full_like(vals[self.name], np.nan)
        return Observations(vals, source=obs.source)


def _toy(noise_sd=0.3):
    design = toy_design(N, n_validate=3)
    return design, ToySimulator(design, sens=SENS, effects=RESP, noise_sd=noise_sd)


def test_standardised_residuals_average_each_component_over_its_finite_replicates():
    sims = np.array([[1.0, 2.0], [3.0, np.nan], [5.0, 4.0]])
    z, sigma, mu = standardised_residuals([3.0, 3.0], [1.0, 1.0], sims, sim_var=[4.0, 4.0])
    np.testing.assert_allclose(mu, [3.0, 3.0])
    np.testing.assert_allclose(sigma, [np.sqrt(1 + 4 / 3), np.sqrt(1 + 4 / 2)])
    z, sigma, mu = standardised_residuals([3.0, 3.0], [1.0, 1.0], [[1.0, np.nan], [2.0, np.nan]])
    assert np.isfinite(z[0]) and np.isnan(z[1])
    assert gap_size([3.0, np.nan, 1.0, 1.0, 1.0]) == gap_size([3.0, 1.0, 1.0, 1.0])


def test_one_lost_replicate_leaves_the_fingerprint_of_the_others():
    design, sim = _toy()
    # o4 lost in replicate seed 1 of the base and of the A runs (a run without a heap)
    holes = Holes(sim, "o4", lambda b, e, s: s == 1 and b["k"] == 1.0 and "B" not in e)
    full = compute_fingerprints(sim, design, {"k": 1.0}, EFFECTS, nuisance=("k",), replicates=3)
    part = compute_fingerprints(holes, design, {"k": 1.0}, EFFECTS, nuisance=("k",), replicates=3)
    assert "o4" in part.names and part.meta["missing_runs"] == {"o4": 3}
    real = design.with_values(sim({"k": 1.0}, {}, 999))
    d = diagnose(real, holes, base={"k": 1.0}, effects=EFFECTS, fingerprints=part, refine=0)
    assert d.data_notes() == ["o4: not observed in 3 fingerprint run(s); averaged over the runs "
                              "that did"]
    assert not part.meta["unobservable"]
    i = list(part.names).index("o4")
    keep = [0, 2]  # the seeds that observed o4 in both runs of each pair
    base = np.stack([sim({"k": 1.0}, {}, s).vector(design.names) for s in (0, 1, 2)])
    plus_a = np.stack([sim({"k": 1.0}, {"A": 1.0}, s).vector(design.names) for s in (0, 1, 2)])
    np.testing.assert_allclose(part["A"].delta[1][i], (plus_a - base)[keep, i].mean())
    np.testing.assert_allclose(part.base_mean[i], base[keep, i].mean())
    # the other components are untouched, and the pooled scatter stays close
    other = np.arange(N) != i
    np.testing.assert_allclose(part["A"].delta[:, other], full["A"].delta[:, other])
    np.testing.assert_allclose(part.sigma[other], full.sigma[other])
    assert part.sigma[i] > full.sigma[i] * 0.5 and np.isfinite(part.sim_var[i])


def test_an_observable_never_seen_at_one_parameter_point_is_dropped_and_said_so():
    design, sim = _toy()
    holes = Holes(sim, "o8", lambda b, e, s: e.get("B", 0.0) > 0.0)   # o8: a validate row
    fps = compute_fingerprints(holes, design, {"k": 1.0}, EFFECTS, nuisance=("k",), replicates=2)
    assert "o8" not in fps.names and "o8" in fps.meta["unobservable"]
    assert "4 of 12" in fps.meta["unobservable"]["o8"]
    assert all(np.all(np.isfinite(f.delta)) for f in fps.fingerprints)
    # a measurement file that has o8 is diagnosed on the rest, with a note
    real = design.with_values(sim({"k": 1.05}, {"A": 0.7}, 999))
    d = diagnose(real, holes, base={"k": 1.0}, effects=EFFECTS, fingerprints=fps, refine=1)
    assert d.attribution.selected[0].effect == "A"
    assert any("o8" in n and "not used" in n for n in d.settings["data_notes"])
    assert any("o8" in n and "not used" in n for n in d.data_notes())
    fp_text = [s for s in diagnosis_report(d).sections if s.key == "fingerprints"][0].text
    assert "o8: measured but not used" in fp_text


def test_precomputed_fingerprints_restricted_to_a_file_without_an_observable():
    design, sim = _toy()
    fps = compute_fingerprints(sim, design, {"k": 1.0}, EFFECTS, nuisance=("k",), replicates=3)
    smaller = MeasurementSet(tuple(m for m in design if m.name != "o1"), title="without o1")
    fresh = compute_fingerprints(sim, smaller, {"k": 1.0}, EFFECTS, nuisance=("k",), replicates=3)
    restricted = fps.restrict(smaller.names)
    assert restricted.names == fresh.names
    for a, b in zip(restricted.fingerprints, fresh.fingerprints):
        np.testing.assert_allclose(a.delta, b.delta)
        assert a.signal == pytest.approx(b.signal) and a.identifiable == b.identifiable
    np.testing.assert_allclose(restricted.sigma, fresh.sigma)
    np.testing.assert_allclose(restricted.sensitivities, fresh.sensitivities)
    # the diagnosis of the smaller file with the big set equals the one with its own set
    truth = sim({"k": 1.1}, {"B": 0.6}, 999)
    real = smaller.with_values(Observations({n: truth[n] for n in smaller.names}))
    d_big = diagnose(real, sim, base={"k": 1.0}, effects=EFFECTS, fingerprints=fps, refine=0)
    d_own = diagnose(real, sim, base={"k": 1.0}, effects=EFFECTS, fingerprints=fresh, refine=0)
    assert d_big.attribution.selected[0].effect == "B" == d_own.attribution.selected[0].effect
    assert d_big.attribution.selected[0].magnitude == pytest.approx(
        d_own.attribution.selected[0].magnitude)
    assert any("o1" in n for n in d_big.settings["data_notes"])


def test_a_twin_leaves_out_what_its_run_could_not_observe(tmp_path):
    design, sim = _toy()
    holes = Holes(sim, "o3", lambda b, e, s: True)
    intrinsic = Observations({m.name: [0.3] for m in design})
    twin = _twin_measurements(design, holes, {"k": 1.0}, {}, 5, tmp_path, 0, intrinsic)
    assert "o3" not in twin.names and len(twin.names) == N - 1
    assert "o3" in twin.notes


def test_an_effect_that_removes_an_observable_at_its_prior_top_is_scaled_from_half_top():
    design, sim = _toy(noise_sd=0.0)
    holes = Holes(sim, "o2", lambda b, e, s: e.get("A", 0.0) == 1.0)   # no heap at the top
    fps = compute_fingerprints(holes, design, {"k": 1.0}, EFFECTS, nuisance=("k",), replicates=2)
    assert "o2" in fps.names and not fps.meta["unobservable"]
    assert fps.meta["extrapolated"] == {"A": ["o2 at 1 (from 0.5)"]}
    np.testing.assert_allclose(fps["A"].delta[1], RESP["A"], atol=1e-12)   # linear toy: exact
    assert fps["A"].linear


def test_null_data_are_not_flagged_when_the_run_scatter_rests_on_few_replicates():
    """Two seeds per point pool only 4 degrees of freedom per component: with the point
    estimate of the scatter a third of null twins were flagged; with its 84 % upper bound
    (what the fingerprints keep) the rate is near the nominal 5 %."""
    from bedstruct.diagnose import where
    n = 8
    design = toy_design(n, n_validate=2, sigma=0.1)
    rng = np.random.default_rng(0)
    flagged, trials = 0, 400
    for t in range(trials):
        sim = ToySimulator(design, sens={"k": np.linspace(1, 2, n)},
                           effects={"A": np.r_[3, -3, 3, -3, 0, 0, 3, -3.0]}, noise_sd=0.7)
        fps = compute_fingerprints(sim, design, {"k": 1.0}, [toy_effect("A")], nuisance=("k",),
                                   replicates=2, seed=1000 * t)
        assert fps.sim_dof.tolist() == [4] * n
        run = np.sqrt(2) * 0.7 * rng.standard_normal(n)      # one run's scatter (toy: two parts)
        stated = np.sqrt(0.1 ** 2 + fps.sim_var)             # as a twin states it
        real = design.with_values(
            Observations({f"o{i}": [run[i] + 0.1 * rng.standard_normal()] for i in range(n)}),
            uncertainty=Observations({f"o{i}": [stated[i]] for i in range(n)}))
        flagged += where(real, fps.base_samples, sim_var=fps.sim_var).significant
    assert flagged / trials < 0.13       # ~0.08 expected


def test_reused_fingerprints_are_judged_in_the_files_noise():
    # fingerprints of a design read to 1 unit, reused for a file that states 8 units (as the
    # validation reuses its design's for every twin): identifiability as if computed for the file
    design, sim = _toy()
    fps = compute_fingerprints(sim, design, {"k": 1.0}, EFFECTS, nuisance=("k",), replicates=3)
    noisy = toy_design(N, n_validate=3, sigma=8.0)
    fresh = compute_fingerprints(sim, noisy, {"k": 1.0}, EFFECTS, nuisance=("k",), replicates=3)
    assert all(f.identifiable for f in fps.fingerprints)            # the premise: noise matters
    assert not any(f.identifiable for f in fresh.fingerprints)
    real = noisy.with_values(sim({"k": 1.05}, {}, 999))
    reused = diagnose(real, sim, base={"k": 1.0}, effects=EFFECTS, fingerprints=fps, refine=0)
    for a, b in zip(reused.fingerprints.fingerprints, fresh.fingerprints):
        assert a.identifiable == b.identifiable
        assert a.signal == pytest.approx(b.signal, rel=1e-9)
    # with one effect withheld the selection threshold is the smaller catalogue's
    one = diagnose(real, sim, base={"k": 1.0}, effects=EFFECTS[:1], fingerprints=fps, refine=0)
    assert one.fingerprints.threshold == pytest.approx(selection_threshold(0.01, 1))   # select_alpha
    assert fps.threshold == pytest.approx(selection_threshold(0.05, 2))
