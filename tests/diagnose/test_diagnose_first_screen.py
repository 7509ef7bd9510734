"""The report's first screen for each verdict: the figure and the answer's words.

The first figure is measured against simulated, before and after the effect.

A noiseless linear toy simulator gives the simulated values in closed form (the base
response plus the recalibration shift times the sensitivity, plus the effect's response
times its magnitude), so the figure's plotted points are checked against that, and against
the result's own numbers, for each verdict: attributed, none and unexplained. The answer's
words carry no statistics (p-values, chi-square) and claim no separation the design lacks.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from bedstruct.diagnose import Observations, compute_fingerprints, diagnose, diagnosis_report
from bedstruct.diagnose.answer import answer, answer_lines, gap_rows
from bedstruct.diagnose.figures import plot_gaps
from diagnose_helpers import ToySimulator, toy_design, toy_effect

N = 12
SENS = {"k": np.linspace(1.0, 2.0, N)}
RESP = {"A": np.r_[3, -3, 3, -3, 3, -3, 0, 0, 0, 3, -3, 0] * 1.0}


@pytest.fixture(scope="module")
def toy():
    design = toy_design(N, n_validate=3)
    sim = ToySimulator(design, sens=SENS, effects=RESP, noise_sd=0.0)
    fps = compute_fingerprints(sim, design, {"k": 1.0}, [toy_effect("A")], nuisance=("k",),
                               replicates=3, alpha=0.01)
    return design, sim, fps


def _diagnose(toy, y):
    design, sim, fps = toy
    real = design.with_values(Observations({f"o{i}": [v] for i, v in enumerate(y)}))
    return diagnose(real, sim, base={"k": 1.0}, effects=[toy_effect("A")], fingerprints=fps,
                    refine=0)


def _series(ax) -> dict:
    """Plotted x, y and horizontal half-widths of each errorbar series, by legend label."""
    out = {}
    for c in ax.containers:
        line, _, (bars,) = c.lines[0], c.lines[1], c.lines[2]
        x = np.asarray(line.get_xdata(), float)
        half = np.array([abs(seg[1, 0] - seg[0, 0]) / 2 for seg in bars.get_segments()])
        out[c.get_label()] = (x, np.asarray(line.get_ydata(), float), half)
    return out


def _plain(text):
    """No statistics and no float noise in the answer's words."""
    import re
    for word in ("p = ", "chi2", "sigma", "dof", "weight", "confidence"):
        assert word not in text, word
    assert not re.search(r"\d\.\d{6,}|e-0\d|\bnan\b", text, re.IGNORECASE)


def _check_against_rows(d, ax):
    rows = gap_rows(d)
    s = _series(ax)
    x, y, half = s["measured"]
    assert np.all(x == 0) and np.allclose(half, 1.0) and len(x) == len(rows)
    x, _, half = s["before: recalibrated"]
    assert np.allclose(x, [r["gap_before"] for r in rows])
    assert np.allclose(half, [r["before_sd"] / r["sigma"] for r in rows])
    # the row labels state the same numbers in the observable's unit
    labels = [t.get_text() for t in ax.get_yticklabels()]
    assert [lab.split(":")[0] for lab in labels] == [r["what"] for r in rows]
    return rows, s


def test_attributed_figure_plots_the_closed_form_before_and_after(toy):
    rng = np.random.default_rng(5)     # a draw whose rerun passes every check
    y = RESP["A"] * 0.6 + SENS["k"] * 0.4 + rng.normal(0.0, 1.0, N)
    d = _diagnose(toy, y)
    assert d.verdict == "attributed"
    fig, ax = plot_gaps(d)
    rows, s = _check_against_rows(d, ax)
    label = "after: recalibrated + A"
    x_after, _, half = s[label]
    assert np.allclose(x_after, [r["gap_after"] for r in rows])
    # independent of the result's numbers: the toy's response at the fitted points (before:
    # the shift recalibration alone fits; after: the shift fitted with the effect)
    shift0 = float(d.attribution.null.nuisance[0])
    shift, mag = d.shrink.nuisance["k"], d.shrink.magnitudes["A"]
    idx = [int(r["what"][1:]) for r in rows]
    expect_before = SENS["k"][idx] * shift0 - y[idx]
    expect_after = SENS["k"][idx] * shift + RESP["A"][idx] * mag - y[idx]
    assert np.allclose(s["before: recalibrated"][0], expect_before, atol=1e-9)
    assert np.allclose(x_after, expect_after, atol=1e-9)
    assert np.allclose(half, 0.0)            # a noiseless simulator scatters by nothing
    # the figure is on the report's first screen
    answer_sec = diagnosis_report(d).sections[0]
    assert answer_sec.key == "answer" and len(answer_sec.figures) == 1
    assert answer(d).gaps == rows


def test_null_answer_figure_has_no_after(toy):
    rng = np.random.default_rng(4)
    y = SENS["k"] * 3.0 + rng.normal(0.0, 1.0, N)      # recalibration alone closes the gap
    d = _diagnose(toy, y)
    assert d.verdict == "none"
    fig, ax = plot_gaps(d)
    _, s = _check_against_rows(d, ax)
    assert set(s) == {"measured", "before: recalibrated"}
    text = "\n".join(answer_lines(d))
    _plain(text)
    assert "What next: nothing further is needed: recalibration alone closes the gap" in text
    assert "no effect added" in ax.get_title()
    assert np.allclose(s["before: recalibrated"][0],
                       [SENS["k"][int(r["what"][1:])] * d.shrink.nuisance["k"]
                        - y[int(r["what"][1:])] for r in gap_rows(d)], atol=1e-9)


def test_unexplained_figure_renders(toy):
    rng = np.random.default_rng(5)
    y = SENS["k"] * 3.0 + rng.normal(0.0, 1.0, N)
    y[-3:] += np.r_[6.0, -6.0, 6.0]                     # held out only: nothing explains it
    d = _diagnose(toy, y)
    assert d.verdict == "unexplained"
    fig, ax = plot_gaps(d)
    _, s = _check_against_rows(d, ax)
    assert ax.get_title().startswith("Measured against simulated (unexplained")
    assert all(lab == "measured" or lab.startswith("before") or "rejected" in lab for lab in s)
    text = "\n".join(answer_lines(d))
    _plain(text)
    assert "Which effect: No effect is named: after recalibration a gap beyond noise remains" in text
    # the design cannot separate the two leading explanations: said so, not "it tells them apart"
    assert "a measurement of another kind is needed" in text and "tells them apart" not in text
    import io
    fig.savefig(io.BytesIO(), format="png")             # it renders


def test_gap_rows_are_in_natural_units():
    import pathlib

    import bedstruct.diagnose as dg
    ms = dg.load_measurements(pathlib.Path(dg.__file__).parents[2] / "data/measurements/seed.toml")
    effects = dg.catalogue(["missing_fines"])
    sim = dg.SurrogateSimulator(dg.diagnosis_design(ms, effects))
    d = dg.diagnose(ms, sim, base=dg.BASE_PARAMETERS, effects=effects, replicates=2, refine=0)
    rows = {r["what"]: r for r in gap_rows(d)}
    comps = {(c["observable"], c["component"]): c for c in d.shrink.components}
    d10, c = rows["psd before, d10"], comps[("psd_before", "d10")]
    assert d10["unit"] == "µm" and d10["measured"] == pytest.approx(c["measured"] * 1e6)
    assert d10["after"] == pytest.approx(c["after"] * 1e6)
    assert rows["static angle"]["unit"] == "deg"
    # the rerun with the effect closes the d10 gap the recalibrated base leaves
    assert abs(d10["gap_after"]) < 2 < abs(d10["gap_before"])
    # the simulated mean of the rerun is the mean of its runs: its sd is the run scatter / sqrt(R)
    assert d10["before_sd"] == pytest.approx(np.sqrt(d.fingerprints.sim_var[
        list(d.fingerprints.design.component_names()).index("psd_before")] / 2) * 1e6)
