"""Usage: python docs/scripts/twin_refine_rounds.py CACHE K PRESET TWIN_SEED TOP_UP ROUNDS

Reruns the in-catalogue diagnosis of twin K of `validate(PRESET, simulator="engine",
campaign="full", twin_seed=TWIN_SEED, top_up=TOP_UP)` (three repeated experiments per twin at
small, one at tiny) with ROUNDS refinement rounds instead of the validation's, and prints
the verdict, reason, ranking, best models, the refined effects' nodes, the held-out shrink
and the rerun checks. The twin's own runs and fingerprints come from the cache; the
refinement nodes and the reruns are new engine calls unless cached.
"""
import importlib
import sys

import numpy as np

V = importlib.import_module("bedstruct.diagnose.validation.validate")
D = importlib.import_module("bedstruct.diagnose.diagnosis")


def main(cache, k, preset, twin_seed, top_up, rounds):
    run_diagnosis = V.diagnose
    record = V.twin_record
    captured = []
    cfg = V.ENGINE_PRESETS[preset]
    n_twins = len(V._twin_plan(cfg["effects"], cfg, in_turn=True))

    def diagnose(*args, **kw):
        if len(kw["effects"]) != len(cfg["effects"]):
            raise ValueError("the out-of-catalogue diagnosis is not replayed")
        return run_diagnosis(*args, **dict(kw, refine=rounds))

    def grab(diag, i, kind, signature, truth, **kw):
        captured.append((kind, diag, truth))
        return record(diag, i, kind, signature, truth, **kw)

    V.diagnose, V.twin_record = diagnose, grab
    try:
        V.validate(preset, simulator="engine", campaign="full", twin_seed=twin_seed,
                   twin_repeats=3 if preset == "small" else 1, top_up=top_up,
                   shard=(k, n_twins), engine={"preset": preset, "cache": cache})
    finally:
        V.diagnose, V.twin_record = run_diagnosis, record
    for kind, d, truth in captured:
        att, s = d.attribution, d.shrink
        print(f"twin {k} ({kind}, truth {truth['true_effect']} {truth['true_magnitude']:.4g}), "
              f"{rounds} refinement round(s): {d.verdict}: {att.reason}")
        for r in att.ranking[:3]:
            print(f"    {r.effect:18s} chi2 decrease {r.delta_chi2:7.2f} at {r.magnitude:.3g} "
                  f"({r.interval[0]:.3g}-{r.interval[1]:.3g})")
        fps = d.fingerprints
        residual = D._residual(d.measurements, fps)
        comp = fps.design.component_names()
        labels = fps.design.component_labels()
        cal = np.flatnonzero(fps.rows_calibrate)
        for m in att.models[:3]:
            print(f"    model {m.label}: chi2 {m.chi2:.1f} on {m.dof} dof, p_fit {m.p_fit:.2g}, "
                  f"magnitudes {np.round(m.magnitudes, 3).tolist()}")
            # where the model misses: its largest calibration residuals, in sigma
            pred = fps.sensitivities @ m.nuisance if len(m.nuisance) else 0.0
            for e, a in zip(m.effects, m.magnitudes):
                pred = pred + fps[e].predict(float(a))
            r = (residual - pred) / fps.sigma
            worst = cal[np.argsort(-np.abs(r[cal]))][:3]
            print("        misses: " + ", ".join(f"{comp[i]} [{labels[i]}] {r[i]:+.1f}"
                                                for i in worst))
        for f in d.fingerprints.fingerprints:
            print(f"    {f.name} nodes: {np.round(f.nodes, 4).tolist()}")
        print(f"    held-out shrink {s.fraction:.2f} (excess gap {s.before_excess:.2f} -> "
              f"{s.after_excess:.2f}); rerun p calibration {s.p_rerun_calibration}, "
              f"held out {s.p_rerun_heldout}")
        for w in s.rerun_worst:
            print(f"    rerun departs: {w['observable']} [{w['component']}] ({w['role']}) "
                  f"{w['z']:+.2f} sigma")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), sys.argv[3], int(sys.argv[4]), int(sys.argv[5]),
         int(sys.argv[6]))
