"""Usage: python docs/scripts/small_point_scatter.py CACHE [COMPONENT]  (the --cache of the
small full-campaign validation after its fingerprints and the wall-friction top-up;
COMPONENT defaults to static_angle_narrow_box).

Prints one scalar observable's value in every fingerprint run of the small engine preset (the
base and wall friction on seeds 0-5, the other effects at both magnitudes on seeds 0-2), each
point's replicate standard deviation, and Bartlett's p-value over the points with two or more
finite values beside the level at which the fingerprints set a point aside (0.01 over the
design's components). All calls must be cached: an uncached one would run the engine.
"""
import importlib
import sys

import numpy as np
from scipy import stats

from bedstruct.diagnose.catalogue import catalogue
from bedstruct.diagnose.diagnosis import diagnosis_design
from bedstruct.diagnose.surrogate import BASE_PARAMETERS
from bedstruct.diagnose.engine_simulator import diagnosis_simulator

V = importlib.import_module("bedstruct.diagnose.validation.validate")

POINTS = ([({}, range(6))] + [({"wall_friction": m}, range(6)) for m in (0.2, 0.4)]
          + [({e: m}, range(3)) for e, ms in (("capillary_bridges", (0.4, 0.8)),
                                               ("contact_ageing", (1.0, 2.0)),
                                               ("blade_startup", (0.125, 0.25)),
                                               ("non_sphericity", (0.15, 0.3))) for m in ms])


def main(cache, component):
    design = diagnosis_design(V.engine_twin_design("full"), catalogue())
    sim = diagnosis_simulator(design, {"preset": "small", "cache": cache})
    groups = []
    for effect, seeds in POINTS:
        values = np.array([float(np.asarray(sim(dict(BASE_PARAMETERS), effect, s)[component],
                                            float)[0]) for s in seeds])
        finite = values[np.isfinite(values)]
        sd = f"{np.std(finite, ddof=1):.2f}" if finite.size > 1 else "-"
        label = ", ".join(f"{e} {m}" for e, m in effect.items()) or "base"
        print(f"{label:24s} {np.round(values, 1)}  sd {sd}")
        if finite.size > 1:
            groups.append(finite)
    n_components = len(design.component_names())
    print(f"Bartlett p over {len(groups)} points: {stats.bartlett(*groups).pvalue:.2g} "
          f"(a point is set aside below {0.01 / n_components:.2g})")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else "static_angle_narrow_box")
