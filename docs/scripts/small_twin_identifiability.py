"""Usage: python docs/scripts/small_twin_identifiability.py CACHE  (the --cache of the small
full-campaign validation; every fingerprint call must be in it).

Identifiability of each effect in each small full-campaign twin's stated noise.

Before commit 5d37dac a twin's diagnosis kept the identifiability the reused fingerprints
had in the design's reading noise; since, it is judged in the twin file's noise and for
the catalogue in use. This replays the twin plan of
`validate("small", simulator="engine", campaign="full", twin_repeats=3)` (validation seed 0,
twin seed 0) from the cached fingerprints and compares both judgements, assuming every
repeated experiment observed every observable (seen = 3) and, as a bound, the x5 dynamic
angle observed once (seen = 1).
"""
import sys
from dataclasses import replace

import numpy as np

from bedstruct.diagnose.catalogue import catalogue
from bedstruct.diagnose.diagnosis import diagnosis_design
from bedstruct.diagnose.identifiability import assess_fingerprints
from bedstruct.diagnose.fingerprint_runs import compute_fingerprints
from bedstruct.diagnose.fingerprints import selection_threshold
from bedstruct.diagnose.surrogate import BASE_PARAMETERS
import importlib
V = importlib.import_module("bedstruct.diagnose.validation.validate")
T = importlib.import_module("bedstruct.diagnose.validation.twins")
from bedstruct.diagnose.engine_simulator import diagnosis_simulator

cache = sys.argv[1]
cfg = dict(V.ENGINE_PRESETS["small"])
effects = tuple(catalogue(cfg["effects"]))
names = [e.name for e in effects]
base = dict(BASE_PARAMETERS)
measured = V.engine_twin_design("full")
design = diagnosis_design(measured, catalogue())
sim = diagnosis_simulator(design, {"preset": "small", "cache": cache})
fps = compute_fingerprints(sim, design, base, effects, replicates=cfg["replicates"], seed=0,
                           top_up=cfg.get("top_up", 0),
                           alpha=0.01, simulator_name="engine")
print("design noise (fingerprints as computed):")
for f in fps.fingerprints:
    print(f"  {f.name:18s} signal {f.signal:6.2f} +- {f.signal_se:4.2f} noise {f.noise:5.2f} "
          f"bound {np.sqrt(fps.threshold + f.noise ** 2):5.2f} identifiable {f.identifiable}")
for name in fps.topped_up:
    before = fps.meta["top_up"][name]
    print(f"  {name} topped up on seeds {fps.top_up_seeds}: before signal {before['signal']:.2f} "
          f"+- {before['signal_se']:.2f}, identifiable {before['identifiable']}")
comp = fps.design.component_names()
rows_meas = ~fps.rows_candidate
twin_repeats = 3
rng = np.random.default_rng([0, 2024])
plan = T._twin_plan(names, cfg, in_turn=True)
for i, (kind, name) in enumerate(plan):
    rng.uniform(-0.02, 0.02)
    mag = None
    if name is not None:
        snr = float(rng.uniform(5.0, 10.0))
        own = lambda a, e=name: T._twin_sigma(fps, T._intrinsic_sd(fps, e, a), twin_repeats)
        mag = T._magnitude_for_snr(fps, name, snr, own)
    intr = T._intrinsic_sd(fps, name, mag)
    for variant in ("x5 seen 3x", "x5 seen 1x", "x5 absent"):
        base_f = fps
        if variant == "x5 absent":
            base_f = fps.restrict([n for n in fps.names if not n.startswith("dynamic_angle_x5")])
        cn = base_f.design.component_names()
        sm = base_f.sigma_meas.copy()
        for n in base_f.names:
            m = base_f.design[n]
            if m.role == "candidate":
                continue
            seen = 1 if (variant == "x5 seen 1x" and n.startswith("dynamic_angle_x5")) else 3
            sm[cn == n] = np.sqrt((m.uncertainty ** 2 + np.asarray(intr[n]) ** 2) / seen)
        out = []
        for cat in ([names] + ([[x for x in names if x != name]] if name else [])):
            before = base_f.subset(cat)  # as reused before 5d37dac: the design's judgement
            after = assess_fingerprints(replace(before, sigma_meas=sm,
                                                threshold=selection_threshold(0.01, len(cat))))
            cells = []
            for fb, fa in zip(before.fingerprints, after.fingerprints):
                flag = "" if fb.identifiable == fa.identifiable else (
                    " LOST" if fb.identifiable else " GAINED")
                cells.append(f"{fa.name[:6]}:{fb.signal:4.1f}->{fa.signal:4.1f}"
                             f"{'' if fa.identifiable else '(NI)'}{flag}")
            out.append(" ".join(cells))
        print(f"twin {i:2d} {kind:6s} {str(name):17s} mag {str(None if mag is None else round(mag, 4)):7s} "
              f"{variant}: " + " || ".join(out))
