"""The verdict when recalibration alone closes a significant gap.

A cohesion calibrated elsewhere gives a large gap that recalibrating it closes on every
observable, held-out ones included: the answer is ``none`` (no effect needed), said so.
A gap that recalibration absorbs on the calibration observables but that the held-out
observables still show stays ``unexplained``.
"""

from __future__ import annotations

import numpy as np

from bedstruct.diagnose import compute_fingerprints, diagnose
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
