"""Diagnose every twin of a sealed record at the checked-out commit under this process's BLAS
kernel; write {twin: {answer, partial, magnitude, shrink}} to argv[2]."""
import json, sys, time
from pathlib import Path
import numpy, threadpoolctl
from bedstruct.diagnose.validation.blind import _benchmark_bridge, _emulator, diagnose_file
from bedstruct.diagnose.validation.blind_twins import benchmark_design
rec = Path(sys.argv[1]).resolve()
truth = json.loads((rec / "truth.json").read_text())
sim = truth["settings"]["sim"]
design = benchmark_design("liggghts")
emu = _emulator(sim, None, design, rec / "library", 1, None, False)
bridge = _benchmark_bridge(sim, None, design, emu, rec / "library", False, 1)
arch = [i.get("architecture") for i in threadpoolctl.threadpool_info() if i.get("internal_api") == "openblas"]
out = {}
for t in sorted(truth["twins"]):
    r = diagnose_file(rec / "twins" / f"{t}.toml", sim, emulator=emu, bridge=bridge)
    out[t] = {k: r.get(k) for k in ("answer", "partial", "magnitude", "shrink")}
Path(sys.argv[2]).write_text(json.dumps({"blas_architecture": arch[0] if arch else None,
                                          "numpy": numpy.__version__, "twins": out}, indent=1))
print("done", arch)
