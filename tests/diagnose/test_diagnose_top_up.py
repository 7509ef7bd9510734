"""Fingerprint top-up: more seeds for the effects whose identifiability is marginal."""

from __future__ import annotations

import numpy as np
import pytest

from bedstruct.diagnose import compute_fingerprints, diagnose, diagnosis_report, nuisance_projector
from bedstruct.diagnose.config import load_sim_config
from bedstruct.diagnose.fingerprints import selection_threshold
from bedstruct.errors import ConfigError
from diagnose_helpers import ToySimulator, toy_design, toy_effect

N = 12
J = {"k": np.linspace(1.0, 2.0, N)}
F = {"A": np.r_[3, -3, 3, -3, 3, -3, 0, 0, 0, 3, -3, 0] * 1.0,    # far above the threshold
     "M": np.r_[1, 0, -1, 0, 1, 0, -1, 0, 1, 0, 0, 0] * 1.45,     # close to it
     "Z": np.zeros(N)}                                            # nothing to see
EFFECTS = [toy_effect(n) for n in F]


class _Recorder:
    """The toy simulator, with every call recorded."""

    name = "toy"

    def __init__(self, sim):
        self.sim, self.calls = sim, []

    def __call__(self, base, effects, seed):
        self.calls.append((dict(base), dict(effects), int(seed)))
        return self.sim(base, effects, seed)


def _toy(noise_sd=0.3):
    design = toy_design(N, n_validate=3)
    return design, ToySimulator(design, sens=J, effects=F, noise_sd=noise_sd)


def test_only_the_marginal_effect_and_the_base_run_on_the_added_seeds_paired_by_seed():
    design, toy = _toy()
    before = compute_fingerprints(toy, design, {"k": 1.0}, EFFECTS, nuisance=("k",), replicates=3,
                                  alpha=0.01)
    assert before.marginal() == ("M",)   # the toy is built so; A and Z are decided
    assert before["A"].identifiable and not before["Z"].identifiable
    sim = _Recorder(toy)
    fps = compute_fingerprints(sim, design, {"k": 1.0}, EFFECTS, nuisance=("k",), replicates=3,
                               top_up=4, alpha=0.01)
    assert fps.topped_up == ("M",) and fps.top_up_seeds == (3, 4, 5, 6)
    assert fps.seeds == (0, 1, 2, 3, 4, 5, 6) and fps.n_replicates == 3
    added = [(b["k"], tuple(sorted(e.items()))) for b, e, s in sim.calls if s >= 3]
    m1, m2 = EFFECTS[1].reference_magnitudes
    assert sorted(set(added)) == sorted({(1.0, ()), (1.0, (("M", m1),)), (1.0, (("M", m2),))})
    assert len(added) == 3 * 4
    assert fps.n_runs == 3 * (1 + 1 + 2 * 3) + 3 * 4
    # M's change is the mean of its seven paired differences, A's of its three (unchanged)
    base_runs = np.array([toy({"k": 1.0}, {}, s).vector(fps.names) for s in fps.seeds])
    m_runs = np.array([toy({"k": 1.0}, {"M": m2}, s).vector(fps.names) for s in fps.seeds])
    np.testing.assert_allclose(fps["M"].delta[1], (m_runs - base_runs).mean(axis=0), atol=1e-12)
    np.testing.assert_allclose(fps["A"].delta, before["A"].delta, atol=1e-12)
    np.testing.assert_allclose(fps.base_samples, base_runs, atol=1e-12)
    # the judgement before the top-up is kept beside the new one
    assert fps.meta["top_up"]["M"]["signal"] == pytest.approx(before["M"].signal)
    assert fps["M"].signal_se < before["M"].signal_se


def test_no_top_up_when_nothing_is_marginal_or_it_is_off():
    design, toy = _toy()
    effects = [EFFECTS[0], EFFECTS[2]]
    sim = _Recorder(toy)
    fps = compute_fingerprints(sim, design, {"k": 1.0}, effects, nuisance=("k",), replicates=3,
                               top_up=4, alpha=0.01)
    assert fps.topped_up == () and fps.top_up_seeds == () and fps.n_replicates == 3
    assert max(s for _, _, s in sim.calls) == 2
    off = compute_fingerprints(toy, design, {"k": 1.0}, EFFECTS, nuisance=("k",), replicates=3,
                               alpha=0.01)
    assert off.topped_up == () and off.base_samples.shape[0] == 3
    with pytest.raises(ConfigError, match="top_up"):
        compute_fingerprints(toy, design, {"k": 1.0}, EFFECTS, nuisance=("k",), replicates=3,
                             top_up=-1)


def test_top_up_brings_the_judgement_closer_to_that_of_many_seeds():
    """With many seeds an effect is identifiable when its projected, whitened response
    exceeds the bound sqrt(threshold). Over independent seed sets, an effect 25 % above that
    bound is judged identifiable far more often with the top-up, one 20 % below it stays
    rarely so."""
    design, _ = _toy()
    cal = design.roles() == "calibrate"
    effect = EFFECTS[1]
    unit = F["M"] / 1.45
    per_unit = np.linalg.norm(nuisance_projector(J["k"][cal, None]) @ unit[cal]) \
        * effect.reference_magnitudes[1]
    bound = np.sqrt(selection_threshold(0.01, 1))
    rate = {}
    for ratio in (1.25, 0.8):
        toy = ToySimulator(design, sens=J, effects={"M": unit * ratio * bound / per_unit},
                           noise_sd=0.6)
        for top_up in (0, 9):
            rate[ratio, top_up] = np.mean([
                compute_fingerprints(toy, design, {"k": 1.0}, [effect], nuisance=("k",),
                                     replicates=3, top_up=top_up, seed=100 * r,
                                     alpha=0.01)["M"].identifiable for r in range(40)])
    assert rate[1.25, 9] > rate[1.25, 0] + 0.3, rate
    assert rate[0.8, 9] <= max(rate[0.8, 0], 0.1), rate


def test_a_topped_up_set_diagnoses_and_refines_on_its_seeds():
    design, toy = _toy()
    fps = compute_fingerprints(toy, design, {"k": 1.0}, EFFECTS, nuisance=("k",), replicates=3,
                               top_up=4, alpha=0.01)
    assert fps.topped_up == ("M",)
    real = design.with_values(toy({"k": 1.05}, {"A": 0.6}, 999))
    diag = diagnose(real, toy, base={"k": 1.0}, effects=EFFECTS, nuisance=("k",), replicates=3,
                    top_up=4, refine=1)
    assert diag.verdict == "attributed"
    assert diag.attribution.selected[0].effect == "A"
    assert diag.settings["top_up"] == {"effects": ["M"], "seeds": [3, 4, 5, 6]}
    assert diag.settings["replicates"] == 3
    # the report names the topped-up effect and gives each effect's seeds
    section = diagnosis_report(diag).section("fingerprints")
    assert "M: identifiability marginal on the 3 shared seeds" in section.text
    seeds = {row[0]: row[5] for row in section.tables[0].rows}
    assert seeds == {"A": 3, "M": 7, "Z": 3}


def test_config_top_up(tmp_path):
    path = tmp_path / "sim.toml"
    path.write_text('[simulator]\nkind = "surrogate"\ntop_up = 3\n')
    assert load_sim_config(path).top_up == 3
    assert load_sim_config(path).as_dict()["top_up"] == 3
    path.write_text('[simulator]\nkind = "surrogate"\ntop_up = -1\n')
    with pytest.raises(ConfigError, match=r"sim.toml \[simulator\]: key 'top_up'"):
        load_sim_config(path)


class _LossyToy(ToySimulator):
    """At A's prior top, seeds 1 and 2 cannot observe the first six components (NaN), as
    a pile that stands as a block leaves no flank to fit."""

    def __call__(self, base, effects, seed):
        from bedstruct.diagnose import Observations
        y = super().__call__(base, effects, seed)
        if effects.get("A", 0.0) >= EFFECTS[0].reference_magnitudes[1] and seed in (1, 2):
            return Observations({m.name: [np.nan] if i < 6 else y[m.name]
                                 for i, m in enumerate(self.design)}, source="toy")
        return y


def test_an_effect_whose_signal_rests_on_one_run_is_topped_up():
    design = toy_design(N, n_validate=3)
    toy = _LossyToy(design, sens=J, effects=F, noise_sd=0.3)
    effects = [EFFECTS[0], EFFECTS[2]]
    before = compute_fingerprints(toy, design, {"k": 1.0}, effects, nuisance=("k",), replicates=3,
                                  alpha=0.01)
    a = before["A"]
    # far above the bound by its standard error, yet most of it lies on one run per component
    bound = np.sqrt(before.threshold + a.noise ** 2)
    assert a.identifiable and a.signal - bound > 2 * a.signal_se
    assert (a.delta_n[1][:6] == 1).all() and (a.delta_n[1][6:9] == 3).all()
    assert a.single_run_share > 0.5 and before["Z"].single_run_share == 0.0
    assert before.marginal() == ("A",) and before.marginal(single_run=1.0) == ()
    assert before.table()[0]["single_run_share"] == pytest.approx(a.single_run_share)
    sim = _Recorder(toy)
    fps = compute_fingerprints(sim, design, {"k": 1.0}, effects, nuisance=("k",), replicates=3,
                               top_up=2, alpha=0.01)
    assert fps.topped_up == ("A",) and (fps["A"].delta_n[1][:6] == 3).all()
    assert fps["A"].single_run_share == 0.0 and fps.marginal() == ()
    # the restricted set keeps the counts of the rows it keeps
    kept = fps.restrict([m.name for m in design][3:])
    assert kept["A"].delta_n.shape == (2, N - 3)
