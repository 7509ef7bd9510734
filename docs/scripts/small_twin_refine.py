"""Usage: python docs/scripts/small_twin_refine.py CACHE K  (the --cache of the small
full-campaign validation, in which twin K's calls are already cached; K as in --shard K/14).

Reruns the diagnosis of twin K of `validate("small", simulator="engine", campaign="full",
twin_repeats=3)` with one refinement round (`refine=1`: the leading effect simulated at its
fitted magnitude on the fingerprint's seeds, added as a node and the fit repeated) instead of
the validation's `refine=0`; the twin with its effect removed keeps `refine=0`. The twin's
own runs come from the cache; the refinement and the reruns are new engine calls (about an
hour on one core at small). Prints each diagnosis's verdict, reason, ranking, best models,
held-out shrink and the rerun checks, and the refined effect's nodes.
"""
import importlib
import sys

import numpy as np

V = importlib.import_module("bedstruct.diagnose.validate")


def main(cache, k):
    run_diagnosis = V.diagnose
    record = V.twin_record
    captured = []

    def diagnose(*args, **kw):
        truth_in_catalogue = len(kw["effects"]) == len(V.ENGINE_PRESETS["small"]["effects"])
        return run_diagnosis(*args, **dict(kw, refine=1 if truth_in_catalogue else kw["refine"]))

    def grab(diag, i, kind, signature, truth, **kw):
        captured.append((kind, diag, truth))
        return record(diag, i, kind, signature, truth, **kw)

    V.diagnose, V.twin_record = diagnose, grab
    V.validate("small", simulator="engine", campaign="full", twin_repeats=3, shard=(k, 14),
               engine={"preset": "small", "cache": cache})
    for kind, d, truth in captured:
        att, s = d.attribution, d.shrink
        print(f"twin {k} ({kind}, truth {truth['true_effect']} {truth['true_magnitude']:.4g}): "
              f"{d.verdict}: {att.reason}")
        for r in att.ranking[:3]:
            print(f"    {r.effect:18s} chi2 decrease {r.delta_chi2:7.2f} at {r.magnitude:.3g} "
                  f"({r.interval[0]:.3g}-{r.interval[1]:.3g})")
        for m in att.models[:3]:
            print(f"    model {m.label}: chi2 {m.chi2:.1f} on {m.dof} dof, p_fit {m.p_fit:.2g}, "
                  f"magnitudes {np.round(m.magnitudes, 3).tolist()}")
        print(f"    held-out shrink {s.fraction:.2f} (excess gap {s.before_excess:.2f} -> "
              f"{s.after_excess:.2f}); rerun p calibration {s.p_rerun_calibration:.2g}, "
              f"held out {s.p_rerun_heldout:.2g}")
        if kind == "effect":
            print(f"    {truth['true_effect']} nodes: {d.fingerprints[truth['true_effect']].nodes}")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]))
