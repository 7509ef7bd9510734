"""Usage: python docs/scripts/small_twin_replay.py CACHE K  (the --cache of the small
full-campaign validation, in which twin K's calls are already cached; K as in --shard K/14).

Replays twin K of `validate("small", simulator="engine", campaign="full", twin_repeats=3)`
(validation seed 0, twin seed 0) from the cache and prints, for its diagnosis with the full
catalogue:
- the ranking: each single effect's chi-square decrease and fitted magnitude, against the
  selection threshold;
- the components where the true effect's fingerprint predicts more than 0.7 sigma at the
  twin's magnitude, or the residual exceeds 1.5 sigma: residual, prediction, and the
  fingerprint's standard error there, all in sigma;
- for each effect, the profile of the fit over its magnitude (the recalibration fitted at
  each magnitude) with the comparison weighted by the experiment's noise alone (as the
  attribution does) and by that noise plus the fingerprint's own estimation noise at the
  magnitude (effective variance, with its log-determinant), and with the fingerprint's
  components below 2 standard errors set to zero.
"""
import importlib
import sys

import numpy as np

V = importlib.import_module("bedstruct.diagnose.validation.validate")


def main(cache, k):
    captured = []
    record = V.twin_record

    def grab(diag, i, kind, signature, truth, **kw):
        captured.append((kind, diag, truth))
        return record(diag, i, kind, signature, truth, **kw)

    V.twin_record = grab
    V.validate("small", simulator="engine", campaign="full", twin_repeats=3, shard=(k, 14),
               engine={"preset": "small", "cache": cache})
    for kind, d, truth in captured:
        att = d.attribution
        print(f"twin {k} ({kind}, truth {truth['true_effect']} {truth['true_magnitude']}): "
              f"{d.verdict}; null chi2 {att.null.chi2:.2f} on {att.null.dof} dof; "
              f"selection threshold {att.threshold:.2f}")
        for r in att.ranking:
            print(f"    {r.effect:18s} chi2 decrease {r.delta_chi2:6.2f}  magnitude {r.magnitude:.3f}")
    kind, d, truth = captured[0]
    fps, name, a_true = d.fingerprints, truth["true_effect"], truth["true_magnitude"]
    if name is None:
        return
    rows = ~fps.rows_candidate
    comp, lab = fps.design.component_names()[rows], fps.design.component_labels()[rows]
    sig, res = fps.sigma[rows], d.residual[rows]
    f = fps[name]
    pred, se = f.predict(a_true)[rows] / sig, f.delta_se[1][rows] / sig
    print(f"components ({name} at {a_true:.3f}; in sigma):")
    for j in np.argsort(-np.abs(pred)):
        if abs(pred[j]) > 0.7 or abs(res[j] / sig[j]) > 1.5:
            print(f"    {comp[j]:28s} {lab[j]:8s} calibrate {str(fps.rows_calibrate[rows][j]):5s} "
                  f"residual {res[j] / sig[j]:6.2f}  predicted {pred[j]:6.2f}  "
                  f"fingerprint s.e. {se[j]:5.2f}")
    cal = fps.rows_calibrate
    r, s_cal, S = d.residual[cal], fps.sigma[cal], fps.sensitivities[cal]
    print("profile over each magnitude (recalibration fitted at each):")
    for e in fps.fingerprints:
        m2, se2 = e.magnitudes[1], e.delta_se[1][cal]
        keep = np.abs(e.delta[1][cal]) >= 2.0 * se2
        out = {}
        for mode in ("noise", "effective variance", "components > 2 s.e."):
            stats = []
            for a in np.linspace(0.0, e.effect.prior[1], 81):
                p = e.predict(a)[cal]
                v = s_cal ** 2
                if mode == "effective variance":
                    v = v + ((a / m2) * se2) ** 2
                if mode == "components > 2 s.e.":
                    p = np.where(keep, p, 0.0)
                w = 1.0 / np.sqrt(v)
                b = np.linalg.lstsq(S * w[:, None], (r - p) * w, rcond=None)[0]
                stat = float(np.sum(((r - p - S @ b) * w) ** 2) + np.sum(np.log(v / s_cal ** 2)))
                stats.append((stat, a))
            best = min(stats)
            out[mode] = (stats[0][0] - best[0], best[1])
        print(f"    {e.name:18s} " + "  ".join(f"{m}: decrease {v[0]:5.2f} at {v[1]:.3f}"
                                                for m, v in out.items()))


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]))
