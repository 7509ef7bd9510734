"""In-sample rerun of the LIGGGHTS blind batches 4-8 with the held-out check at 0.1 and at 0.01.

Usage, from a checkout of the frozen commit of the seventh and eighth batches (their run
library's keys need that commit's engine code) with the commit that gave the held-out check
its own level applied to its diagnosis (REQ: see README.md):

    git worktree add /tmp/frozen b32b725
    git show REQ -- bedstruct/diagnose/diagnosis.py bedstruct/diagnose/config.py \
        bedstruct/diagnose/confirm.py \
        | (cd /tmp/frozen && git apply)
    PYTHONPATH=/tmp/frozen python docs/records/heldout-requirement/rerun_heldout.py OUT.json

Every twin file of the five batches is diagnosed on the emulator of the seventh batch's run
library (the library and LIGGGHTS bridge runs all five batches share, with the half-top
probes), with the configuration data/measurements/blind-engine-tiny-probed2.sim.toml, once
with ``heldout_alpha = 0.1`` (the default) and once with ``0.01`` (the level of the
calibration check, which the held-out check had before), and scored with
``score_benchmark``. In sample: the level was chosen after these twins were seen.
"""
import json
import subprocess
import sys
from pathlib import Path

from bedstruct.diagnose.blind import _benchmark_bridge, _emulator, diagnose_file, score_benchmark
from bedstruct.diagnose.blind_twins import benchmark_design

REC = Path(__file__).resolve().parents[1]
SIM = "data/measurements/blind-engine-tiny-probed2.sim.toml"
BATCHES = ("blind-liggghts-probed-2026-12-05", "blind-liggghts-partial-2026-12-05",
           "blind-liggghts-visible-2026-12-05", "blind-liggghts-twoprobe-2026-12-05",
           "blind-liggghts-twoprobe2-2026-12-05")
KEYS = ("top1_count", "top1_partial_count", "null_false_count", "ooc_count", "shrink_median",
        "shrink_n", "coverage_count")


def main(out: str) -> None:
    commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                            cwd=Path(sys.modules["bedstruct"].__file__).parent).stdout.strip()
    lib = REC / "blind-liggghts-twoprobe-2026-12-05" / "library"
    design = benchmark_design("liggghts")
    emu = _emulator(SIM, None, design, lib, 1, None, False)
    bridge = _benchmark_bridge(SIM, None, design, emu, lib, False, 1)
    doc = {"what": "in-sample rerun of the LIGGGHTS blind batches 4-8 with the rerun's "
                   "held-out check at heldout_alpha = 0.1 and at 0.01",
           "checkout": commit, "sim": SIM, "batches": {}}
    for name in BATCHES:
        folder = REC / name
        truth = json.loads((folder / "truth.json").read_text())
        entry = {}
        for label, value in (("0.1", 0.1), ("0.01", 0.01)):
            res = {t: diagnose_file(folder / "twins" / f"{t}.toml", SIM, emulator=emu,
                                    bridge=bridge, settings={"heldout_alpha": value})
                   for t in sorted(truth["twins"])}
            s = score_benchmark(truth, res)
            entry[label] = {"scores": {k: s[k] for k in KEYS},
                            "answers": {t: {"answer": r["answer"], "partial": r["partial"],
                                            "shrink": r["shrink"],
                                            "p_heldout_before": r["p_heldout_before"]}
                                        for t, r in res.items()}}
            print(name, label, json.dumps(entry[label]["scores"]), flush=True)
        doc["batches"][name] = entry
    Path(out).write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main(*sys.argv[1:])
