"""The engine and LIGGGHTS validations whose twin records are committed (docs/records) score
as docs/records/README.md lists them and docs/diagnose-validation.md quotes the current ones.

Those validations take hours of engine runs; their records are what the documented numbers
rest on. Scoring them again guards the scoring code and the documents against drifting
apart (a changed metric definition, a row edited by hand).
"""

from __future__ import annotations

import json
import pathlib

import pytest

from bedstruct.diagnose import catalogue
from bedstruct.diagnose.validation.scores import score_twins

RECORDS = pathlib.Path(__file__).resolve().parents[2] / "docs" / "records"

#: folder -> (number of records, top-1, null false attribution, out-of-catalogue
#: unexplained, median held-out shrink, interval coverage), as the rows of
#: docs/records/README.md's table
DOCUMENTED = {
    # LIGGGHTS 3.8, tiny (revision fit 10): 2 of 3, 0 of 1, 3 of 3, shrink 0.90 and 1.0, 1 of 1
    "liggghts-tiny-fit10": (7, 2 / 3, 0.0, 1.0, (0.90 + 1.0) / 2, 1.0),
    # LIGGGHTS 3.8, tiny (fit 11): 2 of 3, 0 of 1 (the null twin `unexplained`), 3 of 3,
    # shrink 1.0 and 1.0, 1 of 1
    "liggghts-tiny-fit11": (7, 2 / 3, 0.0, 1.0, 1.0, 1.0),
    # the fit-11 run rescored at fit 13 (current LIGGGHTS result): the same
    "liggghts-tiny-fit13": (7, 2 / 3, 0.0, 1.0, 1.0, 1.0),
    # DEM engine, tiny, full campaign (twin 5, fit 9; current tiny result): 2 of 8, 0 of 2,
    # 5 of 8, 0.03, 2 of 2
    "tiny-engine-rule5-fit9": (18, 2 / 8, 0.0, 5 / 8, 0.03, 1.0),
    # DEM engine, tiny, fingerprints topped up to four seeds: 3 of 8, 0 of 2, 5 of 8, 0.53,
    # 3 of 3
    "tiny-engine-top-up-2": (18, 3 / 8, 0.0, 5 / 8, 0.53, 1.0),
    # DEM engine, small, full campaign, 3 repeats (twin 6, fit 12): 9 of 10, 0 of 4, 7 of 10,
    # 0.73 (2 twins with a held-out gap), 5 of 9
    "small-engine-fit12": (24, 9 / 10, 0.0, 7 / 10, 0.73, 5 / 9),
    # ... rescored at fit 13 (profile intervals): the same but intervals 7 of 9
    "small-engine-fit13": (24, 9 / 10, 0.0, 7 / 10, 0.73, 7 / 9),
    # ... rescored at twin 7 / fit 14 (trials without a reading weighed; current small
    # result): the same but out of the catalogue 8 of 10
    "small-engine-fit14": (24, 9 / 10, 0.0, 8 / 10, 0.73, 7 / 9),
}


def _records(folder):
    return [json.loads(line) for f in sorted((RECORDS / folder).glob("*.jsonl"))
            for line in f.read_text(encoding="utf-8").splitlines() if line.strip()]


def test_every_committed_record_set_is_checked():
    # a folder with twin records (JSON lines); a validation's engine cache may sit beside them
    sets = [p.name for p in RECORDS.iterdir() if p.is_dir() and any(p.glob("*.jsonl"))]
    assert sorted(sets) == sorted(DOCUMENTED)


@pytest.mark.parametrize("folder", sorted(DOCUMENTED))
def test_committed_records_score_as_documented(folder):
    n, top1, null, ooc, shrink, cover = DOCUMENTED[folder]
    recs = _records(folder)
    assert len(recs) == n
    s = score_twins(recs, [e.name for e in catalogue()])
    assert s["top1_accuracy"] == pytest.approx(top1)
    assert s["null_false_attribution"] == pytest.approx(null)
    assert s["out_of_catalogue_unexplained"] == pytest.approx(ooc)
    # the documents round the shrink to two decimals
    assert s["median_gap_shrink"] == pytest.approx(shrink, abs=0.006)
    assert s["magnitude_coverage"] == pytest.approx(cover)


def test_every_record_set_is_listed_in_the_records_index():
    index = (RECORDS / "README.md").read_text(encoding="utf-8")
    for folder in DOCUMENTED:
        assert f"`{folder}`" in index, folder


def test_probe_shrinkage_rerun_reproduces_the_committed_answers_and_its_table():
    """`records/probe-shrinkage`: the rerun with the shrinkage gives every committed answer
    and magnitude of the four batches again, and the counts of its README's table follow
    from the two answer files."""
    rec = RECORDS / "probe-shrinkage"
    counts = {}
    for name in ("shrunk", "unshrunk"):
        doc = json.loads((rec / f"{name}.json").read_text())
        assert doc["shrink_probe_correction"] == (name == "shrunk")
        for batch, rows in doc["batches"].items():
            if name == "shrunk":
                for t, r in rows.items():
                    res = json.loads((RECORDS / batch / "results" / f"{t}.json").read_text())
                    assert (r["answer"], r["magnitude"]) == (res["answer"], res["magnitude"])
            eff = [r for r in rows.values() if r["kind"] == "effect"]
            top = [r for r in eff if r["answer"] == r["truth"]]
            cover = sum(r["interval"][0] <= r["truth_magnitude"] <= r["interval"][1]
                        for r in top if r["interval"])
            ooc = sum(r["answer"] == "unexplained" for r in rows.values()
                      if r["kind"] == "out_of_catalogue")
            null = sum(r["answer"] != "none" for r in rows.values() if r["kind"] == "null")
            counts[name, batch] = (len(top), ooc, cover, null)
    # (top-1 of 20, out of catalogue `unexplained` of 10, intervals covering, null attributed)
    tenth, eleventh = "blind-liggghts-protocol4-2026-12-06", "blind-liggghts-replicate-2026-12-06"
    lammps = "blind-lammps-2026-12-06"
    assert counts["shrunk", tenth] == (16, 9, 13, 0)
    assert counts["unshrunk", tenth] == (18, 8, 14, 0)
    assert counts["shrunk", eleventh] == (19, 7, 12, 0)
    assert counts["unshrunk", eleventh] == (20, 6, 16, 0)
    assert counts["shrunk", lammps] == (20, 2, 10, 0)
    assert counts["unshrunk", lammps] == (20, 1, 10, 0)
    twelfth = "blind-liggghts-replicate2-2026-12-06"
    assert counts["shrunk", twelfth] == (17, 10, 13, 0)
    assert counts["unshrunk", twelfth] == (18, 10, 16, 0)


def test_the_current_bridge_gives_the_unshrunk_answers_of_the_probe_shrinkage_record():
    """The current code keeps the bridge's probe correction unshrunk: diagnosing again the
    twelfth blind batch's files that the shrinkage changes (from the committed run library
    and bridge runs, no engine run) gives `probe-shrinkage/unshrunk.json`'s answers, and not
    the blind batch's."""
    from diagnose_helpers import rediagnose_on_reference_kernel

    batch = "blind-liggghts-replicate2-2026-12-06"
    here = RECORDS / batch
    truth = json.loads((here / "truth.json").read_text())
    sim = str(pathlib.Path(__file__).resolve().parents[2] / truth["settings"]["sim"])
    unshrunk = json.loads((RECORDS / "probe-shrinkage" / "unshrunk.json").read_text())
    # on the reference BLAS kernels (the record was made on other ones): twin-001's and
    # twin-002's answers, which the shrinkage also changed, move with the kernels there
    # (records/blas-kernels), twin-024's does not
    twins = ("twin-024",)
    now = rediagnose_on_reference_kernel(here, twins, sim)
    for twin in twins:
        r = now[twin]
        want = unshrunk["batches"][batch][twin]
        blind = json.loads((here / "results" / f"{twin}.json").read_text())
        assert (r["answer"], r["partial"]) == (want["answer"], want["partial"]), twin
        assert r["magnitude"] == pytest.approx(want["magnitude"], rel=5e-3), twin
        assert (r["answer"], r["partial"]) != (blind["answer"], blind["partial"]), twin
