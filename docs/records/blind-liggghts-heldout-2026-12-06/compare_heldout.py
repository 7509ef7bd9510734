"""The ninth LIGGGHTS blind batch's twins diagnosed again with the held-out check at 0.01.

Run from a checkout of the batch's frozen commit (the run library's keys need its engine
code), after the batch was scored; nothing is tuned on it:

    git worktree add /tmp/frozen ac52df9
    cd /tmp/frozen && PYTHONPATH=/tmp/frozen python \
        /work/main/docs/records/blind-liggghts-heldout-2026-12-06/compare_heldout.py OUT.json

Every twin file is diagnosed on the batch's own run library and LIGGGHTS bridge, as the
benchmark diagnosed it, with ``heldout_alpha = 0.01`` (the calibration check's level, which
the held-out check had before it got its own) instead of the default 0.1, and scored with
``score_benchmark``; the batch's own results (at 0.1) are scored beside them.
"""
import json
import subprocess
import sys
from pathlib import Path

from bedstruct.diagnose.validation.blind import (_benchmark_bridge, _emulator, diagnose_file,
                                                 score_benchmark)
from bedstruct.diagnose.validation.blind_twins import benchmark_design

HERE = Path(__file__).resolve().parent
SIM = "data/measurements/blind-engine-tiny-probed2.sim.toml"
KEYS = ("top1_count", "top1_partial_count", "null_false_count", "ooc_count",
        "ooc_detected_count", "shrink_median", "shrink_n", "coverage_count")


def main(out: str) -> None:
    commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                            cwd=Path(sys.modules["bedstruct"].__file__).parent).stdout.strip()
    truth = json.loads((HERE / "truth.json").read_text())
    design = benchmark_design("liggghts")
    emu = _emulator(SIM, None, design, HERE / "library", 1, None, False)
    bridge = _benchmark_bridge(SIM, None, design, emu, HERE / "library", False, 1)
    blind = {p.stem: json.loads(p.read_text()) for p in (HERE / "results").glob("*.json")}
    res = {t: diagnose_file(HERE / "twins" / f"{t}.toml", SIM, emulator=emu, bridge=bridge,
                            settings={"heldout_alpha": 0.01})
           for t in sorted(truth["twins"])}
    doc = {"what": "the ninth blind batch's twins diagnosed with heldout_alpha = 0.01, beside "
                   "the batch's own results at 0.1 (after scoring; nothing tuned on them)",
           "checkout": commit, "sim": SIM}
    for label, r in (("0.1", blind), ("0.01", res)):
        s = score_benchmark(truth, r)
        doc[label] = {"scores": {k: s[k] for k in KEYS},
                      "answers": {t: {"answer": x["answer"], "verdict": x["verdict"],
                                      "partial": x["partial"], "shrink": x["shrink"]}
                                  for t, x in sorted(r.items())}}
        print(label, json.dumps(doc[label]["scores"]), flush=True)
    Path(out).write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main(*sys.argv[1:])
