"""In-sample rerun of a committed blind LIGGGHTS record with the engine bridge's effect probes.

Usage (from the repository root):
    python docs/records/blind-liggghts-detectable-2026-12-04/rerun_probed.py RECORD [PROBE_RUNS [OUT]]

Each twin file of RECORD is diagnosed again, as the benchmark did, on the emulator of the
record's own run library (read as committed, without the code-version check: it is the
library the twins were diagnosed on), with the bridge of
data/measurements/blind-engine-tiny-probed.sim.toml: the record's six LIGGGHTS base runs
and the LIGGGHTS probe runs kept in docs/records/blind-liggghts-probed-2026-12-05/library/bridge
(the first PROBE_RUNS seeds, default 6). Writes RECORD/OUT (default rerun-probed.json) with
the commit it ran at. In sample: the probes (and the partial explanations of
rerun-partial.json) were added to the method after these twins were seen.
"""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from bedstruct._json import write_json_atomic
from bedstruct.diagnose import Observations
from bedstruct.diagnose.blind import _sim_config, diagnose_file, score_benchmark
from bedstruct.diagnose.blind_twins import benchmark_design
from bedstruct.diagnose.bridge import engine_bridge
from bedstruct.diagnose.emulator import EmulatedSimulator
from bedstruct.diagnose.emulator_fit import fit_emulator
from bedstruct.diagnose.run_library import load_library

SIM = "data/measurements/blind-engine-tiny-probed.sim.toml"
PROBES = Path("docs/records/blind-liggghts-probed-2026-12-05/library/bridge")


def _runs(folders):
    out = {}
    for folder in folders:
        for f in sorted(Path(folder).glob("*.json")):
            d = json.loads(f.read_text())
            key = (int(d["meta"]["seed"]), json.dumps(d["meta"]["effects"], sort_keys=True))
            out.setdefault(key, Observations(
                {v["name"]: np.asarray([np.nan if a is None else a for a in v["value"]], float)
                 for v in d["observables"].values()}, source="liggghts"))
    return out


def main(record: str, probe_runs: int = 6, out: str = "rerun-probed.json") -> None:
    rec = Path(record)
    runs = _runs([rec / "library" / "bridge", PROBES])

    def liggghts(base, effects, seed):
        on = {k: float(v) for k, v in effects.items() if float(v) != 0.0}
        return runs[(int(seed), json.dumps(on, sort_keys=True))]

    cfg = _sim_config(SIM, None)
    emu = fit_emulator(load_library(rec / "library"), reuse=False)
    table = dict(cfg.bridge, probe_runs=int(probe_runs))
    bridge = engine_bridge(benchmark_design("liggghts"), EmulatedSimulator(emu), base=cfg.base,
                           bridge=table, engine=cfg.engine, engine_simulator=liggghts,
                           effects=cfg.effects)
    truth = json.loads((rec / "truth.json").read_text())
    results = {t: diagnose_file(rec / "twins" / f"{t}.toml", SIM, emulator=emu, bridge=bridge)
               for t in sorted(truth["twins"])}
    s = score_benchmark(truth, results)
    commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip()
    keys = ("top1_count", "top1_ci", "top1_detected_count", "null_false_count", "null_false_ci",
            "ooc_count", "ooc_ci", "ooc_detected_count", "coverage_count", "shrink_median",
            "shrink_ci", "shrink_n", "confusion")
    write_json_atomic(rec / out, {
        "what": "in-sample rerun with the engine bridge's effect probes, by the code of "
                "the commit below", "commit": commit,
        "sim": SIM, "probe_runs": int(probe_runs), "bridge": bridge.as_dict(),
        "scores": {k: s[k] for k in keys + ("top1_partial_count",) if k in s},
        "answers": {t: {"answer": r["answer"], "partial": r.get("partial", False),
                        "magnitude": r["magnitude"],
                        "interval": r["interval"], "shrink": r["shrink"]}
                    for t, r in results.items()}})
    print(json.dumps({k: s[k] for k in ("top1_count", "null_false_count", "ooc_count",
                                        "shrink_median", "shrink_n", "coverage_count")}))


if __name__ == "__main__":
    main(sys.argv[1], *(int(a) for a in sys.argv[2:3]), *sys.argv[3:4])
