"""Usage: python docs/scripts/small_twin_gof_noise.py CACHE K [K ...]  (the --cache of the
small full-campaign validation, in which the calls of twins K are already cached; K as in
--shard K/14).

Replays twins K of `validate("small", simulator="engine", campaign="full", twin_repeats=3)`
from the cache (no new runs) and prints, for each diagnosis whose fit selects a model, that
model's goodness of fit on the calibration observables twice: as the attribution computes
it (chi-square and the largest residual, Sidak over the rows, in the experiment's noise),
and counting the fingerprint's own estimation noise at the fitted magnitudes
(`Fingerprint.predict_se`, effective variance: z = res / sqrt(sigma^2 + se(a)^2)). The
second is not what the diagnosis does; it measures what that change would do. The largest
residual is taken without the leverage correction in both, so the first p is at or above the
attribution's own p_fit (which divides each residual by sqrt(1 - leverage)).
"""
import importlib
import sys

import numpy as np
from scipy import stats

V = importlib.import_module("bedstruct.diagnose.validation.validate")


def _p_fit(z, dof):
    n = z.size
    p1 = min(2.0 * stats.norm.sf(np.max(np.abs(z))), 1.0 - 1e-16)
    p_max = float(-np.expm1(n * np.log1p(-p1)))
    return min(1.0, 2.0 * min(float(stats.chi2.sf(z @ z, dof)), p_max))


def main(cache, shards):
    captured = []
    record = V.twin_record

    def grab(diag, i, kind, *args, **kw):
        captured.append((i, kind, diag))
        return record(diag, i, kind, *args, **kw)

    V.twin_record = grab
    for k in shards:
        V.validate("small", simulator="engine", campaign="full", twin_repeats=3, shard=(k, 14),
                   engine={"preset": "small", "cache": cache})
    for i, kind, d in captured:
        model = d.attribution.best
        if not model.effects:
            print(f"twin {i} ({kind}): {d.verdict}, no effect selected")
            continue
        fps = d.fingerprints
        cal = fps.rows_calibrate
        sig = fps.sigma[cal]
        pairs = list(zip(model.effects, model.magnitudes))
        pred = sum(fps[e].predict(a)[cal] for e, a in pairs)
        se2 = sum(fps[e].predict_se(a)[cal] ** 2 for e, a in pairs)
        res = (d.residual[cal] - pred - fps.sensitivities[cal] @ model.nuisance) / sig
        ok = np.isfinite(res)
        z_plain = res[ok]
        z_eff = (res / np.sqrt(1.0 + se2 / sig ** 2))[ok]
        mags = ", ".join(f"{e} {a:.3g}" for e, a in pairs)
        print(f"twin {i} ({kind}): {d.verdict}; selected {mags}: chi2 {z_plain @ z_plain:.1f} on "
              f"{model.dof} dof, p {_p_fit(z_plain, model.dof):.2g} | with the fingerprint's "
              f"noise: chi2 {z_eff @ z_eff:.1f}, largest |z| {np.max(np.abs(z_eff)):.2f}, "
              f"p {_p_fit(z_eff, model.dof):.2g}")


if __name__ == "__main__":
    main(sys.argv[1], [int(k) for k in sys.argv[2:]])
