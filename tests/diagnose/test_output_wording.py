"""What the diagnosis's output says beside the answer: the report's section badges, the
words of a gap in a quantity shown in %, and the command line's help and ``--json``.

A badge must not contradict the verdict, a difference of two percentages is in
percentage points (not a relative change), and the help and docs say what the command
does.
"""

from __future__ import annotations

import contextlib
import io
import json
import pathlib
import re

import numpy as np
import pytest

from bedstruct.cli import build_parser, main
from bedstruct.diagnose.answer import _gap_words, difference_text
from bedstruct.report._model import Report, run_section
from bedstruct.report._render import render_html

ROOT = pathlib.Path(__file__).resolve().parents[2]
SEED = ROOT / "data" / "measurements" / "seed.toml"


def _headings(html: str) -> dict[str, str]:
    """Each section's ``<h2>`` content by section id."""
    return dict(re.findall(r'<section id="([^"]+)"><h2>(.*?)</h2>', html))


def test_unexplained_diagnosis_report_has_no_ok_badge():
    pytest.importorskip("matplotlib")
    from bedstruct.diagnose import Observations, compute_fingerprints, diagnose, diagnosis_report
    from diagnose_helpers import ToySimulator, toy_design, toy_effect

    n = 12
    sens = {"k": np.linspace(1.0, 2.0, n)}
    resp = {"A": np.r_[3, -3, 3, -3, 3, -3, 0, 0, 0, 3, -3, 0] * 1.0}
    design = toy_design(n, n_validate=3)
    sim = ToySimulator(design, sens=sens, effects=resp, noise_sd=0.0)
    fps = compute_fingerprints(sim, design, {"k": 1.0}, [toy_effect("A")], nuisance=("k",),
                               replicates=3, alpha=0.01)
    y = sens["k"] * 3.0 + np.random.default_rng(5).normal(0.0, 1.0, n)
    y[-3:] += np.r_[6.0, -6.0, 6.0]                     # held out only: nothing explains it
    real = design.with_values(Observations({f"o{i}": [v] for i, v in enumerate(y)}))
    d = diagnose(real, sim, base={"k": 1.0}, effects=[toy_effect("A")], fingerprints=fps,
                 refine=0)
    assert d.verdict == "unexplained"
    rep = diagnosis_report(d)
    html = render_html(rep)
    heads = _headings(html)
    assert heads["answer"] == "The answer", heads["answer"]
    assert 'class="status ok"' not in html
    # a section that did not run still says so
    for s in rep.sections:
        if s.status != "ok":
            assert f'<span class="status {s.status.replace(" ", "-")}">' in heads[s.key]
    # the machine-readable status is unchanged
    assert rep.to_json()["sections"]["answer"]["status"] == "ok"


def test_sections_keep_their_badges_by_default():
    """A bed report's sections (run_section's default) show ok, failed and skipped."""
    from bedstruct.report._model import skip

    def fails(s):
        raise ValueError("no frame")

    def skips(s):
        skip("no pile")

    rep = Report("bed", inputs={}, settings={},
                 sections=[run_section("a", "A", lambda s: s.add_number("x", 1.0, "1", "x")),
                           run_section("b", "B", fails), run_section("c", "C", skips),
                           run_section("d", "D", fails, ok_badge=False)])
    heads = _headings(render_html(rep))
    assert heads["a"] == 'A<span class="status ok">ok</span>'
    assert heads["b"] == 'B<span class="status failed">failed</span>'
    assert heads["c"] == 'C<span class="status skipped">skipped</span>'
    assert heads["d"] == 'D<span class="status failed">failed</span>'


@pytest.mark.parametrize("real, sim, z, words", [
    (0.55, 0.5324, 3.0, "1.8 percentage points above the simulation, 3.0× the uncertainty"),
    (0.405, 0.482, -5.4, "7.7 percentage points below the simulation, 5.4× the uncertainty"),
])
def test_gap_in_a_percentage_is_in_percentage_points(real, sim, z, words):
    row = dict(z=z, real=real, simulated=sim, unit="1", kind="packing_fraction")
    assert _gap_words(row) == words


def test_gap_in_other_units_keeps_its_unit():
    assert _gap_words(dict(z=-8.5, real=29.8e-6, simulated=35e-6, unit="m", kind="psd")) \
        == "5.2 µm below the simulation, 8.5× the uncertainty"
    assert _gap_words(dict(z=2.5, real=33.0, simulated=30.0, unit="deg",
                           kind="static_angle")).startswith("3 deg above")


def test_difference_of_percentages_is_in_percentage_points():
    assert difference_text(0.018, 0.55, "1", "packing_fraction") == "+1.8 percentage points"
    assert difference_text(0.46, 30.0, "deg") == "+0.46 deg"


def _help(argv) -> str:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pytest.raises(SystemExit) as exc:
        build_parser().parse_args(argv)
    assert exc.value.code == 0
    return buf.getvalue()


def test_diagnose_usage_shows_the_mode_as_optional():
    text = _help(["diagnose", "--help"])
    usage = text.split("\n\n")[0]
    assert "[MODE ...]" in usage, usage
    assert not re.search(r"(?<!\[)MODE \.\.\.", usage), usage
    # without a mode the plain diagnosis is parsed
    args = build_parser().parse_args(["diagnose", "--sim", "surrogate"])
    assert args.action is None and args.sim == "surrogate"


def test_diagnose_setting_is_hidden_from_help_but_works():
    assert "--diagnose-setting" not in _help(["diagnose", "benchmark", "--help"])
    assert "--diagnose-setting" not in _help(["diagnose", "--help"])
    args = build_parser().parse_args(["diagnose", "benchmark", "--diagnose-setting", "alpha=0.01",
                                      "--diagnose-setting", "refine=0"])
    assert args.action == "benchmark" and args.diagnose_setting == ["alpha=0.01", "refine=0"]


def test_json_output_is_the_one_line_the_docs_describe(tmp_path):
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["diagnose", "--sim", "surrogate", "--real", str(SEED),
                     "--out", str(tmp_path), "--json"]) == 0
    lines = buf.getvalue().splitlines()
    assert len(lines) == 1
    assert json.loads(lines[0])["verdict"] == "attributed"
    docs = (ROOT / "docs" / "diagnose.md").read_text(encoding="utf-8")
    assert "also the last line" not in docs and "the last line printed" not in docs
    assert "With `--json` the command prints one line, a JSON object" in docs
