"""Usage: python docs/scripts/small_twin_sizing.py CACHE K [PRESET [TWIN_SEED [TOP_UP]]]  (the
--cache of the full-campaign engine validation; K as in --shard K/14 at small, K/5 at tiny;
PRESET small, with three repeated experiments per twin, or tiny, with one; TWIN_SEED as
--twin-seed, default 0; TOP_UP as --top-up, default the preset's).

Sizes twin K of `validate(PRESET, simulator="engine", campaign="full", twin_repeats=3)`
by the current twin rule (4: the magnitude first solved on the fingerprint is simulated on
the fingerprint's seeds, added as a node, and the magnitude solved again), makes its
measurement file, and prints, before any rerun of its diagnosis (no refinement, no "how far"):
- the drawn gap, the first magnitude and the gap the simulated node carried there, the
  magnitude the twin is made at;
- the *where* test (significance, chi-square, the largest standardised residuals);
- the recalibrated null's chi-square, each single effect's chi-square decrease with its
  fitted magnitude and interval, the best models and the attribution's reason.
New engine calls: the node (six) and the twin's three repeated experiments, unless cached.
"""
import importlib
import sys
from dataclasses import replace

import numpy as np

V = importlib.import_module("bedstruct.diagnose.validation.validate")
D = importlib.import_module("bedstruct.diagnose.diagnosis")
T = importlib.import_module("bedstruct.diagnose.validation.twins")


#: The validation replayed: preset, repeated experiments per twin, twin seed (set by main).
RUN = {"preset": "small", "twin_repeats": 3, "twin_seed": None, "top_up": None}


def settings(argv):
    """``RUN`` from the command line's optional PRESET, TWIN_SEED and TOP_UP."""
    if len(argv) > 3:
        RUN.update(preset=argv[3], twin_repeats=3 if argv[3] == "small" else 1)
    if len(argv) > 4:
        RUN["twin_seed"] = int(argv[4])
    if len(argv) > 5:
        RUN["top_up"] = int(argv[5])
    return RUN


class _Stop(ValueError):
    """Raised once the twin's file is made (the validation records it as a failed twin)."""


def capture(cache, k):
    """Twin ``k``'s sizing and file, stopped before its diagnosis.

    Returns a dict: ``fps`` (the diagnosis's fingerprints), ``own`` (with the sizing's
    node), ``name``, ``snr``, ``magnitude``, ``node`` (the record's fields), ``sim``,
    ``noise`` (the twin's noise at a magnitude), the twin's ``base_true``, ``effects``,
    ``seed``, ``repeats`` and ``real`` (its measurement file).
    """
    got = {}
    make_file, size = V._twin_measurements, V._size_twin

    def twin_file(design, sim, base_true, effects, seed, folder, idx, intrinsic, repeats=1):
        got.update(base_true=base_true, effects=effects, seed=seed, repeats=repeats,
                   real=make_file(design, sim, base_true, effects, seed, folder, idx,
                                  intrinsic, repeats))
        raise _Stop("the twin's file is made")

    def sized(sim, fps, name, snr, noise):
        out = size(sim, fps, name, snr, noise)
        got.update(fps=fps, own=out[1], name=name, snr=snr, magnitude=out[0], node=out[2],
                   sim=sim, noise=noise)
        return out

    V._twin_measurements, V._size_twin = twin_file, sized
    try:
        cfg = V.ENGINE_PRESETS[RUN["preset"]]
        n_twins = len(V._twin_plan(cfg["effects"], cfg, in_turn=True))
        V.validate(RUN["preset"], simulator="engine", campaign="full",
                   twin_repeats=RUN["twin_repeats"], twin_seed=RUN["twin_seed"],
                   shard=(k, n_twins), refine=0, top_up=RUN["top_up"],
                   engine={"preset": RUN["preset"], "cache": cache})
    finally:
        V._twin_measurements, V._size_twin = make_file, size
    return got


def diagnosis_view(got):
    """The fingerprints as twin ``got``'s diagnosis sees them (its file's uncertainties, the
    catalogue's effects, the selection threshold at 1 %), the measured rows and names, and
    its residual."""
    from bedstruct.diagnose.identifiability import assess_fingerprints
    from bedstruct.diagnose.fingerprints import selection_threshold
    effects = V._catalogue(V.ENGINE_PRESETS[RUN["preset"]]["effects"])
    fps = replace(got["fps"].subset([e.name for e in effects]), alpha=0.01)
    fps, rows_meas, names, _, sm, _ = D._measured_vectors(got["real"], fps)
    sigma_meas = fps.sigma_meas.copy()
    sigma_meas[rows_meas] = sm
    fps = assess_fingerprints(replace(fps, sigma_meas=sigma_meas,
                                      threshold=selection_threshold(0.01, len(effects))))
    return fps, rows_meas, names, D._residual(got["real"], fps)


def main(cache, k):
    from bedstruct.diagnose.attribution import attribute
    from bedstruct.diagnose.where import where
    got = capture(cache, k)
    node = got.get("node") or {}
    if node.get("twin_node_magnitude") is not None:
        print(f"twin {k} ({got['name']}): drawn gap {got['snr']:.2f} sigma; first magnitude "
              f"{node['twin_node_magnitude']:.4g} carried {node['twin_node_gap_sigma']:.2f} sigma "
              f"when simulated; the twin is made at {got['magnitude']:.4g}")
    real = got["real"]
    fps, rows_meas, names, residual = diagnosis_view(got)
    measured = replace(real, measurements=tuple(real[n] for n in names))
    wh = where(measured, fps.base_samples[:, rows_meas], sim_var=fps.sim_var[rows_meas], alpha=0.05)
    print(f"where: significant {wh.significant}, chi2 {wh.chi2:.1f} on {wh.dof}")
    for line in wh.summary[:3]:
        print(f"    {line}")
    att = attribute(residual, fps, alpha=0.01, gof_alpha=0.01, max_effects=2)
    print(f"recalibrated null: chi2 {att.null.chi2:.1f} on {att.null.dof}; selection threshold "
          f"{att.threshold:.2f}")
    for r in att.ranking:
        print(f"    {r.effect:18s} chi2 decrease {r.delta_chi2:7.2f} at {r.magnitude:.3g} "
              f"({r.interval[0]:.3g}-{r.interval[1]:.3g})")
    for m in att.models[:3]:
        print(f"    model {m.label}: chi2 {m.chi2:.1f} on {m.dof} dof, p_fit {m.p_fit:.2g}, "
              f"magnitudes {np.round(m.magnitudes, 3).tolist()}")
    print(f"before reruns: {att.reason}")


if __name__ == "__main__":
    settings(sys.argv)
    main(sys.argv[1], int(sys.argv[2]))
