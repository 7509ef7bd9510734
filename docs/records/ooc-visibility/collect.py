"""Collect which out-of-catalogue twins of LIGGGHTS left a gap beyond noise.

Sources: the out-of-catalogue twins of the blind LIGGGHTS batches drawn before protocol 3
(the batches the visible ranges were read from) whose diagnoses record the "is there a gap"
test (``gap_significant``, ``p_gap``), and the visibility scan in this
folder (``scan.json``: twins made by ``scan.py`` at the ends of the ranges, diagnosed the
same way). Writes ``visibility.json``. Run from the repository root::

    python docs/records/ooc-visibility/collect.py
"""
import json
from pathlib import Path

HERE = Path(__file__).parent
RECORDS = HERE.parent
rows = []
for rec in sorted(RECORDS.glob("blind-liggghts-*")):
    truth = json.loads((rec / "truth.json").read_text())
    if truth["protocol"] >= "bedstruct.blind/3":  # drawn from the visible ranges
        continue
    for name, t in truth["twins"].items():
        if t["kind"] != "out_of_catalogue":
            continue
        r = json.loads((rec / "results" / f"{name}.json").read_text())
        if "gap_significant" not in r:  # the first batch's records predate the gap test
            continue
        rows.append({"engine": "liggghts", "change": t["change"], "magnitude": t["magnitude"],
                     "gap_significant": r["gap_significant"], "p_gap": r["p_gap"],
                     "source": f"{rec.name}/{name}"})
scan = HERE / "scan.json"
if scan.exists():
    for r in json.loads(scan.read_text()):
        rows.append({"engine": "liggghts", "change": r["change"], "magnitude": r["magnitude"],
                     "gap_significant": r["gap_significant"], "p_gap": r["p_gap"],
                     "source": f"ooc-visibility/twins/{r['twin']}"})
rows.sort(key=lambda r: (r["change"], r["magnitude"]))
(HERE / "visibility.json").write_text(json.dumps(
    {"preset": "tiny", "design": "the blind benchmark's (bedstruct.diagnose.blind_twins."
     "benchmark_design('liggghts'))", "test": "gap_significant: the diagnosis' 'is there a gap' "
     "test at 5 % against LIGGGHTS' baseline", "twins": rows}, indent=1) + "\n")
for r in rows:
    print(f"{r['change']:18s} {r['magnitude']:6.3f} {'seen' if r['gap_significant'] else '-':5s}"
          f" p={r['p_gap']:.4f}  {r['source']}")
