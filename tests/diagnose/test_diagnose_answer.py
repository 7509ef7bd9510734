"""The answer a process engineer reads: the CLI's default output, the report's first screen
and the one-line JSON, in plain words and natural units, the statistics in an appendix."""

from __future__ import annotations

import json
import pathlib
import re
from dataclasses import replace

import numpy as np
import pytest

from bedstruct.cli import main
from bedstruct.diagnose import diagnosis_report, load_measurements
from bedstruct.diagnose.answer import (answer, answer_lines, compact_answer, conditions_text,
                                       quantity_text)
from bedstruct.diagnose.confirm import shrink_interval

SEED = pathlib.Path(__file__).resolve().parents[2] / "data" / "measurements" / "seed.toml"
_FLOAT_NOISE = re.compile(r"\d\.\d{6,}|e-0\d|\bnan\b", re.IGNORECASE)


@pytest.fixture(scope="module")
def seed_run(tmp_path_factory):
    """The seed's measurements diagnosed on the surrogate through the CLI (default output)."""
    import contextlib
    import io
    out = tmp_path_factory.mktemp("seed")
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["diagnose", "--sim", "surrogate", "--real", str(SEED),
                     "--out", str(out)]) == 0
    return buf.getvalue(), out


def test_cli_default_output_answers_in_plain_words_and_natural_units(seed_run):
    text, out = seed_run
    assert text.startswith("The gap between the measurements and the analytic surrogate")
    assert "explained by fines missing from the simulated PSD" in text
    # where: measured against simulated, in µm and deg, the gap in words
    assert "psd before, d10" in text and "measured 29.8 ± 0.6 µm, simulated 35 µm" in text
    assert "5.1 µm below the simulation, 8.5× the uncertainty" in text
    assert "dynamic angle x1 early, 0-10 % of the stroke" in text
    assert " s  measured" not in text and "0.1 s" not in text
    assert "measured 33 ± 4 deg" in text and "within noise" in text
    # which, with its physical magnitude and interval
    assert "Which effect: Fines missing from the simulated PSD: mass fraction of fines " \
           "missing 8.53 % (95 % interval 6.78 to 9.71 %)." in text
    # how far: the seed's held-out observables had no gap beyond noise to shrink
    assert "How far: The 3 held-out observable components showed no gap beyond noise " \
           "before, so there is no gap to shrink" in text
    assert "Recalibrated: cohesion energy density 34 MJ/m³ (was 36 MJ/m³)." in text
    assert "What next: measure avalanche angle rest600 (after 600 s at rest, box 30 mm " \
           "wide)" in text
    assert not _FLOAT_NOISE.search(text), _FLOAT_NOISE.search(text)
    # the statistics are in the appendix: no z, chi-square, p-value or model weight here
    assert "{" not in text and "sigma" not in text and "chi2" not in text
    assert "p = " not in text and "confidence" not in text and "weight" not in text


def test_report_first_screen_is_the_answer_and_the_statistics_an_appendix(seed_run):
    _, out = seed_run
    html = (out / "report.html").read_text(encoding="utf-8")
    first = html.index('<section id="answer">')
    assert first < html.index('<section id="summary">') < html.index('<section id="where">')
    rep = json.loads((out / "report.json").read_text())
    sections = rep["sections"]
    assert list(sections)[0] == "answer"
    assert all(v["title"].startswith("Appendix") for k, v in sections.items() if k != "answer")
    answer_html = html[first:html.index("</section>", first)]
    answer_html = re.sub(r'src="data:[^"]*"', 'src=""', answer_html)   # the figure's bytes
    assert "29.8 ± 0.6 µm" in answer_html and "How far" in answer_html
    assert "<img" in answer_html or "<svg" in answer_html     # the figure of the gaps
    assert "p = " not in answer_html and "confidence" not in answer_html
    assert not _FLOAT_NOISE.search(answer_html)
    # no number shown as NaN beside an "ok", no raw dict in any text
    for key, sec in sections.items():
        for name, q in sec["numbers"].items():
            assert q["value"] is not None, (key, name)
        assert "{'" not in sec.get("text", ""), key


def test_help_is_short():
    import contextlib
    import io
    buf = io.StringIO()
    with pytest.raises(SystemExit), contextlib.redirect_stdout(buf):
        main(["diagnose", "--help"])
    text = buf.getvalue()
    description = text[text.index("Diagnose"):text.index("positional arguments")]
    assert len(description.strip().splitlines()) <= 10
    assert "docs/diagnose.md" in description
    options = text[text.index("options:"):]
    # one sentence per option: no option's help runs past two printed lines
    helps = re.split(r"\n  (?=-)", options)[1:]
    assert helps and all(len(h.strip().splitlines()) <= 3 for h in helps), helps


def test_json_answer_is_compact(seed_run):
    _, out = seed_run
    full = json.loads((out / "diagnosis.json").read_text())
    assert full["verdict"] == "attributed"
    # the data notes in full, as the docs' table of diagnosis.json says: the unit conversions
    assert "bed_height_layer1, bed_height_layer2 and 3 more observables: um -> m (x1e-06)" \
        in full["settings"]["data_notes"]


def test_docs_worked_example_is_what_the_command_prints(seed_run):
    """docs/diagnose.md, "Worked example: the seed file", shows the command's output."""
    text, out = seed_run
    doc = (SEED.parents[2] / "docs" / "diagnose.md").read_text(encoding="utf-8")
    block = doc[doc.index("takes a few seconds and prints\n\n```\n") + 36:]
    block = block[:block.index("```")]
    assert block.strip() == text.replace(str(out), "diag").strip()


def test_docs_python_names_exist():
    """The functions and methods docs/diagnose.md's "From Python" paragraph names exist."""
    import bedstruct.diagnose as dg
    doc = (SEED.parents[2] / "docs" / "diagnose.md").read_text(encoding="utf-8")
    part = doc[doc.index("From Python:"):doc.index("A simulator is any callable")]
    for name in set(re.findall(r"\bdg\.(\w+)", part)):
        assert hasattr(dg, name), name
    for name in set(re.findall(r"\bdiag\.(\w+)", part)):
        assert hasattr(dg.Diagnosis, name), name


@pytest.fixture(scope="module")
def seed_diag():
    """The seed diagnosed on the surrogate, cheaply (no refinement, three seeds)."""
    from bedstruct.diagnose import (BASE_PARAMETERS, SurrogateSimulator, catalogue, diagnose,
                                    diagnosis_design)
    ms = load_measurements(SEED)
    sim = SurrogateSimulator(diagnosis_design(ms, catalogue()))
    return diagnose(ms, sim, base=BASE_PARAMETERS, refine=0, confirm_rounds=0, replicates=3)


def test_compact_answer_and_how_far_with_a_held_out_gap(seed_diag):
    d = seed_diag
    j = compact_answer(d)
    assert set(j) == {"verdict", "partial", "effect", "magnitude", "magnitudes", "shrink",
                      "where", "at_bound"}
    assert len(j["where"]) == 3 and j["where"][0]["observable"] == "psd_before"
    assert j["magnitude"]["name"] == "fines_mass_fraction"
    assert j["magnitudes"] == [{"effect": "missing_fines", **j["magnitude"]}]
    # a pair: each effect's magnitude
    first = d.attribution.selected[0]
    second = replace(first, effect="wall_friction", magnitude=0.21, interval=(0.1, 0.3))
    pair = compact_answer(replace(d, attribution=replace(d.attribution,
                                                         selected=(first, second))))
    assert pair["effect"] == "missing_fines+wall_friction"
    assert [m["effect"] for m in pair["magnitudes"]] == ["missing_fines", "wall_friction"]
    assert pair["magnitudes"][1]["value"] == 0.21 and pair["magnitudes"][1]["interval"] == [0.1, 0.3]
    assert pair["magnitude"] == j["magnitude"]
    assert j["shrink"]["value"] is None and j["shrink"]["n_heldout"] == 3
    json.dumps(j, allow_nan=False)
    # a held-out gap that shrinks: the fraction and its interval in words
    gapped = replace(d, shrink=replace(d.shrink, fraction=0.7, fraction_interval=(0.52, 0.9),
                                       p_before=0.001))
    how = answer(gapped).how_far
    assert "the gap beyond noise shrinks by 70 % once missing fines is added " \
           "(90 % interval 52 to 90 %)" in how
    assert compact_answer(gapped)["shrink"]["interval"] == [0.52, 0.9]
    lines = answer_lines(gapped)
    assert any(line.startswith("How far: On the 3 held-out") for line in lines)


def test_a_held_out_gap_within_noise_is_not_said_to_shrink(seed_diag):
    """A held-out gap whose test against noise does not reject (p = 0.31) has an excess of
    a fraction of a sigma; the ratio of excesses is then noise (-1421 %, outside its own
    interval) and is not said, in words or in the JSON line."""
    d = seed_diag
    noisy = replace(d, shrink=replace(d.shrink, fraction=-14.2, fraction_interval=(-7.6, 1.0),
                                      p_before=0.31, before_excess=0.16, after=2.6,
                                      after_excess=2.4, n_heldout=1))
    how = answer(noisy).how_far
    assert "%" not in how, how
    assert how.startswith("The 1 held-out observable component showed no gap beyond noise "
                          "before") and "it departs by 2.6× the noise" in how, how
    j = compact_answer(noisy)["shrink"]
    assert j["value"] is None and j["interval"] == [None, None]
    assert j["p_heldout_gap_before"] == 0.31


def test_simulated_value_is_shown_in_the_measurement_s_unit_and_precision(tmp_path):
    """A bed of about 1 mm: the simulated value is shown in the measured value's unit, and
    both to the digit the uncertainty needs (not 990 µm against 1 mm, nor 1 ± 0.002 mm for
    1.004 mm)."""
    from bedstruct.diagnose import (BASE_PARAMETERS, SurrogateSimulator, catalogue, diagnose,
                                    diagnosis_design)
    assert quantity_text(1.004e-3, "m", "bed_height", sigma=2e-6,
                         resolution=2e-6) == "1.004 ± 0.002 mm"
    assert quantity_text(1.5e-3, "m", "bed_height", like=9.9e-4, resolution=1e-5) == "1500 µm"
    assert quantity_text(29.84e-6, "m", "psd", sigma=0.6e-6, resolution=0.6e-6) == "29.8 ± 0.6 µm"
    f = tmp_path / "beds.toml"
    f.write_text('[[observable]]\nname = "static_angle"\nkind = "static_angle"\n'
                 'value = 33.0\nuncertainty = 1.0\n\n'
                 '[[observable]]\nname = "h6"\nkind = "bed_height"\nunit = "um"\n'
                 'value = 990\nuncertainty = 10\n[observable.conditions]\nlayer = 6\n',
                 encoding="utf-8")
    ms = load_measurements(f)
    sim = SurrogateSimulator(diagnosis_design(ms, catalogue()))
    d = diagnose(ms, sim, base=BASE_PARAMETERS, refine=0, confirm_rounds=0, replicates=2,
                 max_effects=1)
    row = next(r for r in answer(d).where if r["what"] == "h6")
    assert row["measured"] == "990 ± 10 µm" and row["simulated"].endswith(" µm"), row
    # a measurement finer than three digits: 1.004 ± 0.002 mm, not 1 ± 0.002 mm
    fine = replace(ms["h6"], values=np.array([1.004e-3]),
                   uncertainty=np.array([2e-6]))
    ms = replace(ms, measurements=(ms.measurements[0], fine))
    d = diagnose(ms, sim, base=BASE_PARAMETERS, refine=0, confirm_rounds=0, replicates=2,
                 max_effects=1)
    row = next(r for r in answer(d).where if r["what"] == "h6")
    assert row["measured"] == "1.004 ± 0.002 mm" and row["simulated"].endswith(" mm"), row
    assert len(row["simulated"].split()[0].split(".")[-1]) == 3, row


def test_shrink_interval_brackets_the_shrink():
    zb = np.array([4.0, -3.0, 5.0, 3.5])
    za = np.array([1.5, -0.5, 1.8, 0.4])
    lo, hi = shrink_interval(zb, za, seed=1)
    from bedstruct.diagnose.confirm import gap_size
    frac = 1 - gap_size(za)[1] / gap_size(zb)[1]
    assert lo < frac < hi <= 1.0
    assert shrink_interval(zb, za, seed=1) == (lo, hi)           # reproducible
    assert np.isnan(shrink_interval([0.3, -0.5], [0.1, 0.1])[0])  # no gap before: none


def test_time_windows_are_said_as_fractions_of_the_stroke(seed_run):
    """A window ``t=0-0.1`` is the first 10 % of the stroke, not 0 to 0.1 s: the answer's
    rows say it as the conditions label does, in the text and on the report's first screen."""
    from bedstruct.diagnose.answer import _component_words
    assert _component_words("t=0-0.1") == "0-10 % of the stroke"
    assert _component_words("t=0.1-1") == "10-100 % of the stroke"
    assert _component_words("t=0.25-0.5") == "25-50 % of the stroke"
    assert _component_words("d10") == "d10" and _component_words("value") == "value"
    _, out = seed_run
    html = (out / "report.html").read_text(encoding="utf-8")
    answer_html = html[html.index('<section id="answer">'):]
    answer_html = answer_html[:answer_html.index("</section>")]
    assert "dynamic angle x1 early, 0-10 % of the stroke" in answer_html
    assert not re.search(r"\d to \d+(\.\d+)? s\b", answer_html)


def test_report_appendix_numbers_are_readable_and_carry_units(seed_run):
    """The appendix shows significant digits, p-values in scientific notation, fits that are
    0 up to rounding noise as 0, and every measured value in its natural unit (µm, mm,
    deg) with a unit column."""
    _, out = seed_run
    html = (out / "report.html").read_text(encoding="utf-8")
    text = re.sub(r'src="data:[^"]*"', 'src=""', html)
    assert not re.search(r"0\.0000\d", text), re.search(r".{80}0\.0000\d.{20}", text)
    assert not re.search(r"\d\.\d{9,}", text)
    rep = json.loads((out / "report.json").read_text())
    where = rep["sections"]["where"]["tables"][0]
    assert "unit" in where["columns"]
    rows = {(r[0], r[1]): dict(zip(where["columns"], r)) for r in where["rows"]}
    d10 = rows[("psd_before", "d10")]
    assert d10["unit"] == "µm" and d10["real"] == pytest.approx(29.84)
    assert d10["sigma"] == pytest.approx(0.605, rel=0.01)
    assert rows[("static_angle", "value")]["unit"] == "deg"
    assert {r["unit"] for r in rows.values()} <= {"µm", "mm", "deg"}
    early = rows[("dynamic_angle_x1_early", "0-10 % of the stroke")]
    assert early["unit"] == "deg" and early["real"] == pytest.approx(33.0)
    which = rep["sections"]["which"]["tables"][0]
    mags = {r[0]: dict(zip(which["columns"], r)) for r in which["rows"]}
    fines = mags["missing_fines"]
    assert fines["unit"] == "%" and fines["magnitude"] == pytest.approx(8.53, abs=0.01)
    assert fines["95 % CI"] == "[6.78, 9.71]"
    # the p-values: scientific notation, not 0.0000000000000000162
    which_html = text[text.index('<section id="which">'):]
    assert re.search(r'<td class="num">\d(\.\d+)?e-1\d</td>', which_html)
    # magnitudes that are 0 up to rounding noise are 0, in the JSON and on the page
    for name in ("non_sphericity", "capillary_bridges"):
        assert mags[name]["magnitude"] == 0.0 and mags[name]["scale"] == 0.0, mags[name]
        assert mags[name]["dchi2"] == 0.0
    assert rep["sections"]["summary"]["numbers"]["magnitude.missing_fines"]["unit"] == "%"


def test_natural_units():
    assert quantity_text(4.0e-4, "m", "bed_height") == "400 µm"
    assert quantity_text(2.5e-3, "m", "bed_height") == "2.5 mm"
    assert quantity_text(0.55, "1", "packing_fraction", sigma=0.012) == "55 ± 1.2 %"
    assert quantity_text(1.2, "1", "coordination") == "1.2"
    assert conditions_text("relative_humidity=0.3") == "RH 30 %"
    assert conditions_text("-") == ""


def test_an_effect_the_bridged_engine_does_not_realise_is_said_unchecked():
    """Named through a bridge whose engine cannot realise it, an effect's response is the
    diagnosing simulator's alone: the answer says so; a probed effect carries no such words."""
    from bedstruct.diagnose import (BASE_PARAMETERS, SurrogateSimulator, catalogue, diagnose,
                                    diagnosis_design)
    ms = load_measurements(SEED)
    sim = SurrogateSimulator(diagnosis_design(ms, catalogue()))
    d = diagnose(ms, sim, base=BASE_PARAMETERS, refine=0, confirm_rounds=0, replicates=2)
    assert d.attribution.verdict == "attributed"
    named = d.attribution.selected[0].effect
    plain = answer(d).which
    unprobed = replace(d, settings={**d.settings, "bridge": {"engine": "liggghts",
                                                             "unprobed": [named]}})
    which = answer(unprobed).which
    assert which.startswith(plain[:-1])
    assert "LIGGGHTS does not realise it" in which and "not checked against your LIGGGHTS" in which
    probed = replace(d, settings={**d.settings, "bridge": {"engine": "liggghts",
                                                           "unprobed": ["blade_startup"]}})
    assert answer(probed).which == plain
