"""The engine's results are bit for bit those recorded in ``data/reference_trajectories.json``.

The runs use the single-loop pair pass (``reference_trajectories.run_case``); the blocked
pass, the default without capillary bridges and ageing, gives the same bits there
(``test_engine_speedpaths.py``, and :func:`test_default_pass_bit_identical` here).

The digests were recorded with ``reference_trajectories.py`` on the machine named in the
file (the bits depend on the CPU and the numba/llvmlite versions, not only on the code);
elsewhere the test is skipped. A change to the kernels that is meant to keep the model
(a refactoring, a speed-up) must keep every digest; one that changes the arithmetic on
purpose re-records them. With ``BEDSTRUCT_REFERENCE_NPZ=DIR`` (arrays written by
``reference_trajectories.py --npz DIR``) a failure names the arrays that differ and by
how much.
"""

import json
import os
from pathlib import Path

import numpy as np
import pytest

import reference_trajectories as rt

_REF = json.loads(rt.JSON.read_text())


def _differences(name, arrays):
    d = os.environ.get("BEDSTRUCT_REFERENCE_NPZ")
    if not d or not (Path(d) / f"{name}.npz").exists():
        return "set BEDSTRUCT_REFERENCE_NPZ to a folder of recorded arrays to see which differ"
    ref = np.load(Path(d) / f"{name}.npz")
    out = []
    for k in sorted(ref.files):
        a, b = ref[k], arrays[k]
        if a.shape != b.shape:
            out.append(f"{k}: shape {a.shape} -> {b.shape}")
        elif not np.array_equal(a, b):
            diff = np.abs(a.astype(float) - b.astype(float))
            out.append(f"{k}: {int((a != b).sum())} values differ, max |diff| {diff.max():.3g}")
    return "; ".join(out) or "arrays equal (digest inputs differ otherwise)"


#: Run by default: the seed's model in each scene, the model without rolling or cohesion,
#: capillary bridges and the rolling stiffness factor; the other cases are ``slow``. The
#: contact-ageing cases are slow too: after a whole test session their last bits depend on
#: which compiled variant of the pair kernel numba's dispatcher picks (one compiled earlier
#: for other argument types), so they are checked on their own (``-m slow -k age``).
DEFAULT_CASES = {"bed-epsd2-coh1", "spread-epsd2-coh1", "repose-epsd2-coh1", "bed-none-coh0",
                 "spread-cdt-coh0", "bed-epsd2-cap", "bed-epsd-krf3"}


@pytest.mark.parametrize("name", [n if n in DEFAULT_CASES else pytest.param(n, marks=pytest.mark.slow)
                                  for n in sorted(rt.CASES)])
def test_trajectory_bit_identical(name):
    if rt.machine() != _REF["machine"]:
        pytest.skip(f"digests recorded on {_REF['machine']}; this is {rt.machine()}")
    arrays = rt.run_case(name)
    assert rt.digest(arrays) == _REF["digests"][name], _differences(name, arrays)


#: Cases without the extensions, which the blocked pass (the engine's default) runs too.
BLOCKED_CASES = sorted(n for n, (_, kw) in rt.CASES.items()
                       if not kw.get("capillary") and not kw.get("contact_ageing"))


@pytest.mark.parametrize("name", [n if n == "bed-epsd2-coh1" else pytest.param(n, marks=pytest.mark.slow)
                                  for n in BLOCKED_CASES])
def test_default_pass_bit_identical(name):
    # the engine's default pass, run through the same case, gives the single loop's bits
    if rt.machine() != _REF["machine"]:
        pytest.skip(f"digests recorded on {_REF['machine']}; this is {rt.machine()}")
    arrays = rt.run_case(name, blocked=True)
    assert rt.digest(arrays) == _REF["digests"][name], _differences(name, arrays)
