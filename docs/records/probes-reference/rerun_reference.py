"""In-sample rerun of committed blind LIGGGHTS records with probes at both reference magnitudes.

Usage (from the repository root):
    python docs/records/probes-reference/rerun_reference.py LIB RECORD [RECORD ...]

LIB is a copy of a blind record's run library (its ``bridge/`` folder holds LIGGGHTS' base
and top-probe runs; the probes at half the prior's top are run into it, 6 per realised
effect, on two processes). The bridge is that of
data/measurements/blind-engine-tiny-probed.sim.toml with ``probes = "reference"``. Each twin
file of each RECORD is diagnosed again on the emulator of LIB's library, as the benchmark
did, and RECORD/rerun-reference.json is written with the commit it ran at. In sample: the
two-probe correction was added after these twins were seen.
"""
import json
import subprocess
import sys
from pathlib import Path

from bedstruct._json import write_json_atomic
from bedstruct.diagnose.blind import _sim_config, diagnose_file, score_benchmark
from bedstruct.diagnose.blind_twins import benchmark_design
from bedstruct.diagnose.bridge import engine_bridge
from bedstruct.diagnose.emulator import EmulatedSimulator
from bedstruct.diagnose.emulator_fit import fit_emulator
from bedstruct.diagnose.run_library import load_library

SIM = "data/measurements/blind-engine-tiny-probed.sim.toml"


def main(lib: str, *records: str) -> None:
    lib = Path(lib)
    commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    cfg = _sim_config(SIM, None)
    emu = fit_emulator(load_library(lib), reuse=False)
    table = dict(cfg.bridge, probes="reference")
    bridge = engine_bridge(benchmark_design("liggghts"), EmulatedSimulator(emu), base=cfg.base,
                           bridge=table, engine=cfg.engine, cache=lib / "bridge",
                           effects=cfg.effects, workers=2, progress=True)
    keys = ("top1_count", "top1_ci", "top1_detected_count", "top1_partial_count",
            "null_false_count", "null_false_ci", "ooc_count", "ooc_ci", "ooc_detected_count",
            "coverage_count", "shrink_median", "shrink_ci", "shrink_n", "confusion")
    for record in records:
        rec = Path(record)
        truth = json.loads((rec / "truth.json").read_text())
        results = {t: diagnose_file(rec / "twins" / f"{t}.toml", SIM, emulator=emu,
                                    bridge=bridge) for t in sorted(truth["twins"])}
        s = score_benchmark(truth, results)
        write_json_atomic(rec / "rerun-reference.json", {
            "what": "in-sample rerun with the bridge probing each realised effect at both "
                    "reference magnitudes (probes = \"reference\"), by the code of the commit "
                    "below", "commit": commit, "sim": SIM, "bridge": bridge.as_dict(),
            "scores": {k: s[k] for k in keys if k in s},
            "answers": {t: {"answer": r["answer"], "partial": r.get("partial", False),
                            "magnitude": r["magnitude"], "interval": r["interval"],
                            "shrink": r["shrink"]} for t, r in results.items()}})
        print(rec.name, json.dumps({k: s[k] for k in ("top1_count", "top1_partial_count",
                                                      "null_false_count", "ooc_count",
                                                      "shrink_median", "shrink_n",
                                                      "coverage_count")}), flush=True)


if __name__ == "__main__":
    main(*sys.argv[1:])
