"""Reference trajectories of the engine: small deterministic runs whose final state is
compared bit for bit across changes to the kernels (``test_kernel_identity.py``).

Each case builds a small bed (about 300 polydisperse spheres), settles it (10000 steps, at 5 g), then
runs a short stretch (800 steps) with walls moving: a settled bed at rest (``bed``), a blade
spreading over it (``spread``) or the floor plate of a repose box sliding out
(``repose``); every rolling model with and without cohesion, and each diagnosis
extension. :func:`run_case` returns the state after the run, the contact forces
the output path computes and the wall contacts (all arrays).

The runs use the engine's single-loop pair pass, which carries the extensions; without
them the blocked pass (the engine's default) gives the same bits
(``test_engine_speedpaths.py``).

Run this module as a script to record the digests of this machine's results into
``data/reference_trajectories.json`` (and, with ``--npz DIR``, the arrays); ``--cases``
re-records only the cases named:

    PYTHONPATH=. python tests/dem/reference_trajectories.py [--npz DIR] [--cases NAME ...]
"""

from __future__ import annotations

import hashlib
import json
import platform
import sys
from pathlib import Path

import numpy as np

from bedstruct import Box
from bedstruct.dem import Blade, ContactModel, Material, Plane, Simulation, repose_box

E, NU, RHO = 1e7, 0.3, 2500.0
R = 40e-6
JSON = Path(__file__).with_name("data") / "reference_trajectories.json"

_ROLLING = ("none", "cdt", "epsd", "epsd2")
SETTLE = 10000


def _cases() -> dict[str, tuple[str, dict]]:
    out = {}
    for scene in ("bed", "spread", "repose"):
        for rm in _ROLLING:
            for coh in (0.0, 2e4):
                out[f"{scene}-{rm}-coh{int(coh > 0)}"] = (scene, dict(rolling_model=rm,
                                                                     cohesion=coh))
    cap = dict(capillary=True, capillary_film_thickness=2e-8)
    age = dict(contact_ageing=True, ageing_bond_ratio=1.0, ageing_break_slip=2e-7)
    for scene in ("bed", "spread"):
        out[f"{scene}-epsd2-cap"] = (scene, dict(rolling_model="epsd2", cohesion=2e4, **cap))
        out[f"{scene}-epsd2-age"] = (scene, dict(rolling_model="epsd2", cohesion=2e4, **age))
        out[f"{scene}-cdt-cap-age"] = (scene, dict(rolling_model="cdt", cohesion=2e4, **cap, **age))
        out[f"{scene}-epsd-krf3"] = (scene, dict(rolling_model="epsd", cohesion=2e4,
                                                 rolling_stiffness_factor=3.0))
        out[f"{scene}-epsd-cap"] = (scene, dict(rolling_model="epsd", cohesion=2e4, **cap))
    out["bed-none-cap-nocoh"] = ("bed", dict(rolling_model="none", cohesion=0.0, **cap))
    return out


CASES = _cases()


def run_case(name: str, *, blocked: bool = False) -> dict[str, np.ndarray]:
    """The arrays of one case after its run (see the module docstring).

    The digests are those of the engine's single-loop pair pass; ``blocked`` runs the
    blocked (vectorised) pair pass instead, equal bit for bit without the extensions.
    """
    scene, kw = CASES[name]
    model = ContactModel(Material(E, NU, RHO), restitution=0.4, friction=0.5,
                         rolling_friction=0.1, limit_force=(scene == "repose"), **kw)
    rng = np.random.default_rng(11)
    radii = rng.uniform(0.8 * R, 1.2 * R, 400)
    if scene == "repose":
        lo, hi = (0.0, 0.0, 0.0), (0.6e-3, 0.6e-3, 2e-3)
        sim = Simulation(Box(lo, hi, boundary="ff ff ff"), model,
                         walls=repose_box(lo, (0.6e-3, 0.6e-3, 1.6e-3)), n_threads=2, seed=3, gravity=(0.0, 0.0, -50.0))
        region = ((0, 0, 0), (0.6e-3, 0.6e-3, 0.9e-3))
    else:
        box = Box((0, 0, 0), (0.6e-3, 0.5e-3, 2e-3), boundary="pp pp ff")
        walls = [Plane((0, 0, 0), (0, 0, 1), name="floor")]
        if scene == "spread":
            walls.append(Blade(gap=200e-6, speed=0.0, x0=-0.3e-3))
        sim = Simulation(box, model, walls=walls, n_threads=2, seed=3, gravity=(0.0, 0.0, -50.0))
        region = ((0, 0, 0), (0.6e-3, 0.5e-3, 0.9e-3))
    sim.blocked_pairs = blocked
    sim.insert_raindrop(300, radii, region=region, velocity=(0.05, 0.0, -0.5))
    sim.run(SETTLE)
    if model.contact_ageing:
        sim.age_contacts(30.0)
    if scene == "spread":
        sim.set_wall_motion("blade", velocity=(1.0, 0.0, 0.0))
    elif scene == "repose":
        sim.set_wall_motion("plate", velocity=(0.3, 0.0, 0.0))
    sim.run(800)
    fn, ft, wslot, wfn, wdel, wnrm, f, tq = sim._evaluate()
    out = dict(ids=sim.ids, x=sim.x, v=sim.v, om=sim.om, f=sim.f, tq=sim.tq, pi=sim.pi,
               pj=sim.pj, ht=sim.ht, hr=sim.hr, hx=sim.hx, whist=sim.whist, wslot=sim.wslot,
               fn=fn, ft=ft, wfn=wfn, wdel=wdel, wnrm=wnrm, f_eval=f, tq_eval=tq,
               time=np.array([sim.time]), n_rebuilds=np.array([sim.n_rebuilds]))
    return {k: np.ascontiguousarray(v) for k, v in out.items()}


def digest(arrays: dict[str, np.ndarray]) -> str:
    """SHA-256 of the arrays' names, dtypes, shapes and bytes (equal digests: equal bits)."""
    h = hashlib.sha256()
    for k in sorted(arrays):
        a = np.ascontiguousarray(arrays[k])
        h.update(f"{k}:{a.dtype.str}:{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def machine() -> dict[str, str]:
    """What the bits depend on besides the code: CPU (its name and LLVM's name for its
    instruction set), numba/llvmlite/NumPy versions."""
    import llvmlite
    import numba
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    from llvmlite import binding
    # the model name alone does not say which instructions LLVM compiles for ("AMD EPYC"
    # covers several generations): its host CPU name does
    return dict(cpu=cpu, llvm_cpu=binding.get_host_cpu_name(), numba=numba.__version__,
                llvmlite=llvmlite.__version__, numpy=np.__version__)


def main(argv=None) -> int:
    import argparse
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--npz", help="also write each case's arrays to DIR/<case>.npz")
    p.add_argument("--cases", nargs="*", default=list(CASES))
    a = p.parse_args(argv)
    digests = {}
    for name in a.cases:
        arrays = run_case(name)
        digests[name] = digest(arrays)
        if a.npz:
            Path(a.npz).mkdir(parents=True, exist_ok=True)
            np.savez(Path(a.npz) / f"{name}.npz", **arrays)
        print(name, digests[name][:16], int(arrays["n_rebuilds"][0]), len(arrays["pi"]),
              int((arrays["fn"] != 0).sum()), int((arrays["wfn"] != 0).sum()), flush=True)
    JSON.parent.mkdir(exist_ok=True)
    old = json.loads(JSON.read_text()) if JSON.exists() else {}
    if old.get("machine") == machine():  # re-recording some cases keeps the others
        digests = {**old.get("digests", {}), **digests}
    JSON.write_text(json.dumps(dict(machine=machine(), digests=dict(sorted(digests.items()))),
                               indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
