import math

import numpy as np
import pytest

from bedstruct.workflows import calibrate_cohesion, inverse_linear, load_config


def test_inverse_linear_against_numpy():
    rng = np.random.default_rng(3)
    x = np.array([1.0, 2.0, 3.0, 4.0])
    y = 10 + 2 * x + rng.normal(0, 0.1, 4)
    xs, sx, b = inverse_linear(x, y, np.full(4, 0.1), 15.0)
    bb, aa = np.polyfit(x, y, 1)
    assert b == pytest.approx(bb)
    assert xs == pytest.approx((15.0 - aa) / bb)
    assert 0 < sx < 0.2
    # far from the centroid the slope's error counts: the classical inverse prediction
    # sigma/|b| sqrt(1/n + (x* - mean x)^2 / Sxx) with sigma known
    xs, sx, b = inverse_linear(x, y, np.full(4, 0.1), 22.0)
    sxx = np.sum((x - x.mean()) ** 2)
    assert sx == pytest.approx(0.1 / abs(b) * np.sqrt(1 / 4 + (xs - x.mean()) ** 2 / sxx), rel=1e-10)


def test_bracketing_finds_a_nonlinear_root():
    cfg = load_config(preset="tiny")
    calls = []

    def model(k):   # saturating angle-cohesion curve, noise-free
        calls.append(k)
        return 20 + 20 * (1 - math.exp(-k / 1e4)), 0.3, ()
    res = calibrate_cohesion(cfg, target_deg=33.0, bracket=(1e3, 5e3), max_iter=12,
                             tolerance_deg=0.05, evaluate=model)
    exact = -1e4 * math.log(1 - 13 / 20)
    assert res.bracketed and res.converged
    assert res.cohesion == pytest.approx(exact, rel=0.02)
    assert 0 < res.cohesion_std < 0.1 * exact
    ks = [p.cohesion for p in res.curve]
    assert ks == sorted(ks) and len(ks) == len(set(calls))


def test_unbracketed_target_is_reported():
    cfg = load_config(preset="tiny")
    res = calibrate_cohesion(cfg, target_deg=80.0, bracket=(1e3, 2e3), max_iter=2,
                             evaluate=lambda k: (20 + 1e-3 * k, 0.5, ()))
    assert not res.bracketed and not res.converged


@pytest.mark.slow
def test_calibration_on_tiny_repose(tmp_path):
    cfg = load_config(preset="tiny", overrides=["calibrate.replicates=2"])
    res = calibrate_cohesion(cfg, target_deg=26.0, bracket=(0.0, 8e3), max_iter=3, out=tmp_path)
    assert res.n_runs >= 4
    assert (tmp_path / "results.json").is_file()


def test_angle_with_a_maximum_stops_widening():
    cfg = load_config(preset="tiny")
    seen = []

    def model(k):   # rises to 28 deg at 1.5e4, then falls (blocks break off)
        seen.append(k)
        return 28 - 1e-8 * (k - 1.5e4) ** 2, 0.5, ()
    res = calibrate_cohesion(cfg, target_deg=33.0, bracket=(5e3, 1.5e4), max_iter=6, evaluate=model)
    assert not res.bracketed and not res.converged
    assert res.cohesion == 1.5e4 and math.isnan(res.cohesion_std)
    assert len(seen) == 3      # widened once, saw the angle fall, stopped
