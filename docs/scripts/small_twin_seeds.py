"""Usage: python docs/scripts/small_twin_seeds.py CACHE K [PRESET [TWIN_SEED [TOP_UP]]]  (as
small_twin_sizing.py).

Where a twin's gap goes between its sizing and its diagnosis, seed by seed. For twin
K of `validate(PRESET, simulator="engine", campaign="full", twin_repeats=3)` (sized by the
current twin rule) it prints, all in the twin's own noise with the part recalibration
absorbs projected out, on the calibration observables:
- the gap the sizing's node carried (its mean over the fingerprint's seeds, paired with the
  base run of each seed), each seed's own paired response (one run, not a mean) and the
  mean with each seed left out in turn;
- the gap the twin's three runs carry before reading noise (their mean minus the base
  runs' mean), its cosine with the node's, and the gap estimated without the fingerprint's
  own estimation noise (`twin_gap_debiased_sigma`);
- the gap the diagnosis sees in the twin's file (reading noise added; the file's stated
  uncertainties), with the fingerprint's prediction at the twin's magnitude;
- the components that carry the node's gap: the node's and the twin's projected values and
  the raw runs (base, node, twin) on the leading one.
No engine calls beyond small_twin_sizing.py's (all cached once it has run).
"""
import sys

import numpy as np

from small_twin_sizing import T, capture, diagnosis_view, settings


def _vector(fps, obs):
    comp = fps.design.component_names()
    out = np.full(len(comp), np.nan)
    for n in fps.names:
        out[comp == n] = np.asarray(obs[n], dtype=float)
    return out


def _projector(fps, sigma):
    from bedstruct.diagnose.identifiability import nuisance_projector
    cal = fps.rows_calibrate
    P = nuisance_projector(fps.sensitivities[cal] / sigma[cal][:, None])
    return lambda d: P @ (d[cal] / sigma[cal])


def main(cache, k):
    got = capture(cache, k)
    fps, own, sim, name, a = got["fps"], got["own"], got["sim"], got["name"], got["magnitude"]
    first = got["node"]["twin_node_magnitude"] or a
    comp = fps.design.component_names()
    cal_names = comp[fps.rows_calibrate]
    base = fps.base_samples
    node = np.array([_vector(fps, sim(fps.base, {name: first}, s)) for s in fps.seeds])
    twin = np.array([_vector(fps, sim(got["base_true"], got["effects"], T._repeat_seed(got["seed"], j)))
                     for j in range(got["repeats"])])
    sigma = np.asarray(got["noise"](own, a), dtype=float)
    proj = _projector(fps, sigma)
    with np.errstate(invalid="ignore"):
        node_mean = proj(np.nanmean(node - base, axis=0))
        per_seed = [np.linalg.norm(proj(np.where(np.isfinite(r - b), r - b, 0.0)))
                    for r, b in zip(node, base)]
        twin_mean = proj(np.nanmean(twin, axis=0) - np.nanmean(base, axis=0))
        keep = np.ones(len(base), dtype=bool)
        left_out = []
        for j in range(len(base)):  # the node's gap with one seed left out
            keep[:] = True
            keep[j] = False
            left_out.append(np.linalg.norm(proj(np.nanmean(node[keep] - base[keep], axis=0))))
    print(f"twin {k} ({name}) at {a:.4g}; node at {first:.4g} on seeds {list(fps.seeds)}")
    print(f"node: mean paired response {np.linalg.norm(node_mean):.2f} sigma; one seed's each "
          f"(unobserved components as none): {np.round(per_seed, 2).tolist()}")
    print(f"node with one seed left out (seed by seed): {np.round(left_out, 2).tolist()}")
    cos = float(node_mean @ twin_mean / np.linalg.norm(node_mean) / np.linalg.norm(twin_mean))
    debiased = T._projected_gap(own, name, lambda x: got["noise"](own, x), debias=True)(a)
    print(f"twin's runs (before reading noise): {np.linalg.norm(twin_mean):.2f} sigma, cosine "
          f"{cos:.2f} with the node's; the gap without the fingerprint's estimation noise "
          f"{debiased:.2f} sigma")
    dfps, _, _, residual = diagnosis_view(got)
    dproj = _projector(dfps, dfps.sigma)
    seen = dproj(residual)
    print(f"the diagnosis's view of the file: {np.linalg.norm(seen):.2f} sigma "
          f"(chi2 {seen @ seen:.1f}); the fingerprint predicts "
          f"{np.linalg.norm(dproj(dfps[name].predict(a))):.2f} at {a:.4g}")
    print(f"{'component':34s} {'node':>6s} {'twin':>6s}")
    for j in np.argsort(-np.abs(node_mean))[:5]:
        print(f"{cal_names[j]:34s} {node_mean[j]:6.2f} {twin_mean[j]:6.2f}")
    lead = np.flatnonzero(fps.rows_calibrate)[int(np.argmax(np.abs(node_mean)))]
    print(f"raw runs of {comp[lead]}:")
    for label, runs in (("base", base), ("node", node), ("twin", twin)):
        print(f"    {label}: {np.round(runs[:, lead], 3).tolist()}")


if __name__ == "__main__":
    settings(sys.argv)
    main(sys.argv[1], int(sys.argv[2]))
