"""summary.html of a workflow run: its numbers, the pile or last layer pictured, and the
`bedstruct run` command saying where it wrote it."""

from __future__ import annotations

import json
import pathlib
import re
import shutil
import types

import pytest

from bedstruct.cli import main
from bedstruct.report import _picture, write_run_summary

SAMPLES = pathlib.Path(__file__).resolve().parents[2] / "data" / "samples"


@pytest.fixture(autouse=True)
def _no_3d_render(monkeypatch):
    """The 3-D view (a child process, seconds) is tested in test_report.py."""
    monkeypatch.setattr(_picture, "render_3d",
                        lambda frame, **kw: (None, "3-D view not drawn (left out in the tests)"))


def _text(page: str) -> str:
    page = re.sub(r"<style>.*?</style>|data:image/png;base64,[A-Za-z0-9+/=]+", "", page, flags=re.S)
    return re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", page))


REPOSE = {"workflow": "repose", "angle_deg": 31.25, "angle_std_deg": 0.75, "spread_deg": 1.5,
          "cohesion": 3000.0, "n_measured": 2, "unmeasured": {},
          "replicates": [{"stage": f"rep0{k}", "seed": k + 1, "angle_deg": a, "angle_std_deg": 2.0,
                          "left_deg": a - 1, "right_deg": a + 1, "n_remaining": 600 + k,
                          "pile_height": 4.5e-4} for k, a in enumerate((30.25, 32.25))]}


def _repose_folder(out: pathlib.Path) -> pathlib.Path:
    for k in (0, 1):
        (out / f"rep0{k}").mkdir(parents=True)
        shutil.copy(SAMPLES / "repose" / "pile.dump.gz", out / f"rep0{k}" / "pile.dump.gz")
    shutil.copy(SAMPLES / "repose" / "contacts.dump.gz", out / "rep00" / "pile_contacts.dump.gz")
    (out / "results.json").write_text(json.dumps(REPOSE))
    return out


def test_repose_summary_has_the_numbers_and_the_first_pile(tmp_path):
    out = _repose_folder(tmp_path / "run")
    path = write_run_summary(out, view_3d=False)
    assert path == out / "summary.html"
    page = path.read_text()
    text = _text(page)
    assert "bedstruct run repose" in text
    assert re.search(r"angle_deg 31\.25 deg", text) and re.search(r"angle_std_deg 0\.75 deg", text)
    assert "rep00 1 30.25 2 29.25 31.25 600 450" in text     # the pile height in um
    assert "bed pictured rep00/pile.dump.gz" in text
    assert f"bedstruct report {out}/rep00/pile.dump.gz --contacts {out}/rep00/pile_contacts.dump.gz" in text
    assert page.count("data:image/png;base64,") == 1 and "Side view of the bed" in text
    assert "3-D view not drawn (turned off)" in text


def test_spread_summary_pictures_the_last_layer(tmp_path):
    out = tmp_path / "run"
    for k in (1, 2):
        (out / f"layer0{k}").mkdir(parents=True)
        shutil.copy(SAMPLES / "spread" / "bed.dump.gz", out / f"layer0{k}" / "bed.dump.gz")
    layers = [{"index": k, "nominal_height": 1e-4 * k, "bed_height_m": 0.9e-4 * k,
               "roughness_sa_m": 1.5e-5, "packing_fraction": [0.5, 0.55, 0.6],
               "mean_dynamic_angle_deg": None, "n_bed": 1000 * k} for k in (1, 2)]
    results = {"workflow": "spread", "tool": "blade", "speed": 0.05,
               "regions": ["start", "centre", "end"], "layers": layers}
    path = write_run_summary(out, results=results)
    text = _text(path.read_text())
    assert "bed pictured layer02/bed.dump.gz" in text
    assert ("layer nominal height (µm) bed height (µm) roughness Sa (µm) packing start packing "
            "centre packing end dynamic angle (deg) particles") in text
    assert "2 200 180 15 0.5 0.55 0.6 n/a 2000" in text          # heights in um
    assert "3-D view not drawn (left out in the tests)" in text


def test_summary_of_another_workflow_or_without_a_bed(tmp_path):
    with pytest.raises(ValueError, match="'repose' and 'spread'"):
        write_run_summary(tmp_path, results={"workflow": "calibrate"})
    path = write_run_summary(tmp_path, results=REPOSE)
    assert "No bed dump found in the run folder" in path.read_text()


def test_run_prints_where_it_wrote_the_summary(tmp_path, capsys, monkeypatch):
    import bedstruct.workflows as wf
    seen = {}

    def fake(cfg, *, out, **kw):
        seen["out"] = out
        _repose_folder(pathlib.Path(out))
        reps = [types.SimpleNamespace(**r) for r in REPOSE["replicates"]]
        return types.SimpleNamespace(to_dict=lambda: REPOSE, replicates=reps,
                                     **{k: REPOSE[k] for k in ("angle_deg", "angle_std_deg",
                                                               "spread_deg", "cohesion", "n_measured",
                                                               "unmeasured")})
    monkeypatch.setattr(wf, "run_repose", fake)
    out = tmp_path / "run"
    assert main(["run", "repose", "--preset", "tiny", "--out", str(out), "--no-3d"]) == 0
    captured = capsys.readouterr()
    assert f"summary: {out}/summary.html" in captured.err.splitlines()
    assert (out / "summary.html").is_file() and "summary" not in captured.out
    # a page that cannot be written is a warning: the run succeeded

    def broken(cfg, *, out, **kw):
        res = fake(cfg, out=out)
        (pathlib.Path(out) / "results.json").write_text("{not json")
        return res
    monkeypatch.setattr(wf, "run_repose", broken)
    assert main(["run", "repose", "--preset", "tiny", "--out", str(tmp_path / "b")]) == 0
    assert "bedstruct run: warning: no summary page" in capsys.readouterr().err
