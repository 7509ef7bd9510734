"""Helpers of the diagnosis tests: heaps of known angle and small designs."""

from __future__ import annotations

import numpy as np

from bedstruct.diagnose import MeasurementSet, measurement_from_dict


def heap_particles(angle_deg, *, n=4000, length=3e-3, width=1e-3, height=1.2e-3, seed=0,
                   r_range=(14e-6, 50e-6)):
    """Spheres filling a wedge whose free surface falls at ``angle_deg`` (flat top at 90 %)."""
    rng = np.random.default_rng(seed)
    t = np.tan(np.radians(angle_deg))
    pts = []
    while sum(len(p) for p in pts) < n:
        x = rng.uniform(0, length, 4 * n)
        y = rng.uniform(0, width, 4 * n)
        z = rng.uniform(0, height, 4 * n)
        ok = z < np.minimum(0.9 * height, t * (length - x))
        pts.append(np.column_stack([x, y, z])[ok])
    return np.concatenate(pts)[:n], rng.uniform(*r_range, n)


def small_design(roles=("calibrate", "calibrate", "validate")):
    """Three scalar observables of different kinds (values 0: a design)."""
    specs = [
        dict(name="aor", kind="static_angle", value=0.0, uncertainty=0.5),
        dict(name="dyn", kind="dynamic_angle_series", windows=[[0, 0.1], [0.1, 1]], value=[0.0, 0.0],
             uncertainty=[1.0, 0.5], conditions=dict(speed=0.0254, layer=3)),
        dict(name="pf", kind="packing_fraction", value=0.0, uncertainty=0.005,
             conditions=dict(speed=0.0254, layer=1, region="center")),
    ]
    return MeasurementSet(tuple(measurement_from_dict(dict(s, role=r)) for s, r in zip(specs, roles)))


def cubic_positions(n=6, spacing=1.0):
    """Centres of an n^3 simple cubic lattice filling [0, n*spacing)^3."""
    g = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 3)
    return (g + 0.5) * spacing


def toy_effect(name, prior=(0.0, 1.0)):
    """A catalogue-like effect for toy simulators."""
    from bedstruct.diagnose import Effect
    return Effect(name=name, title=name, magnitude=f"{name}_magnitude", unit="1", prior=prior,
                  physics="toy", signature="toy", sources=(), engine_map=((name, "linear", 1.0, 0.0),))


def toy_design(n=12, n_validate=3, n_candidate=0, sigma=1.0):
    """n scalar observables (static angles) of uncertainty ``sigma``; the last ones held out/candidate."""
    ms = []
    for i in range(n + n_candidate):
        role = ("candidate" if i >= n else "validate" if i >= n - n_validate else "calibrate")
        d = dict(name=f"o{i}", kind="static_angle", uncertainty=sigma, role=role)
        if role != "candidate":
            d["value"] = 0.0
        ms.append(measurement_from_dict(d))
    return MeasurementSet(tuple(ms), title="toy design")


def _stable_hash(params) -> int:
    """A hash of a parameter mapping that is the same in every process (``hash`` of a str
    is salted per process, which made the toys' noise, and a rate test, vary run to run)."""
    import zlib
    return zlib.crc32(repr(sorted(params.items())).encode())


class ToySimulator:
    """Linear(+quadratic) toy: y = J (p - p0) + sum_e F_e m_e + Q_e m_e^2 + noise_sd * xi."""

    name = "toy"

    def __init__(self, design, *, sens, effects, curvature=None, noise_sd=0.0, base0=None):
        self.design = design
        self.sens = {k: np.asarray(v, float) for k, v in sens.items()}
        self.F = {k: np.asarray(v, float) for k, v in effects.items()}
        self.Q = {k: np.asarray(v, float) for k, v in (curvature or {}).items()}
        self.noise_sd = noise_sd
        self.base0 = dict(base0 or {k: 1.0 for k in sens})

    def __call__(self, base, effects, seed):
        from bedstruct.diagnose import Observations
        n = sum(m.n_components for m in self.design)
        y = np.zeros(n)
        for k, v in self.sens.items():
            y += v * (base[k] - self.base0[k])
        for e, m in effects.items():
            y += self.F[e] * m + self.Q.get(e, 0.0) * m * m
        if self.noise_sd:
            y += self.noise_sd * np.random.default_rng([seed, 17]).standard_normal(n) \
                + self.noise_sd * np.random.default_rng([seed, _stable_hash(effects),
                                                        _stable_hash(base)]).standard_normal(n)
        return Observations({m.name: [y[i]] for i, m in enumerate(self.design)}, source="toy")


#: The BLAS kernel family the rediagnosis checks of committed records run on: numpy's
#: OpenBLAS is pinned to it in a child process, so that the check does not depend on the
#: host's own kernels (borderline answers move with them; docs/records/blas-kernels).
REFERENCE_KERNEL = "Haswell"


def rediagnose_on_reference_kernel(folder, twins, sim) -> dict:
    """``rediagnose_benchmark(folder, twins=twins, sim=sim)["results"]`` computed in a child
    process with ``OPENBLAS_CORETYPE`` = :data:`REFERENCE_KERNEL`; skips the calling test
    where OpenBLAS cannot run that kernel family here (a CPU without AVX2 and FMA, not x86)."""
    import json
    import os
    import subprocess
    import sys

    import pytest

    code = (
        "import json, sys, threadpoolctl\n"
        "from bedstruct.diagnose.validation.blind import rediagnose_benchmark\n"
        "arch = [i.get('architecture') for i in threadpoolctl.threadpool_info()\n"
        "        if i.get('internal_api') == 'openblas']\n"
        f"r = rediagnose_benchmark({str(folder)!r}, twins={list(twins)!r}, sim={str(sim)!r})\n"
        "print(json.dumps({'arch': arch[0] if arch else None, 'results': r['results']}))\n")
    env = dict(os.environ, OPENBLAS_CORETYPE=REFERENCE_KERNEL)
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        if proc.returncode < 0 or "Illegal instruction" in proc.stderr:
            pytest.skip(f"OpenBLAS cannot run its {REFERENCE_KERNEL} kernels on this machine")
        raise AssertionError(proc.stderr[-3000:])
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    if out["arch"] != REFERENCE_KERNEL:
        pytest.skip(f"numpy's OpenBLAS runs {out['arch']} here, not {REFERENCE_KERNEL}")
    return out["results"]
