"""Reports of validations: a validation on synthetic twins (:func:`validation_report`) and a
blind benchmark's figure and HTML page (:mod:`bedstruct.diagnose.validation.blind`).

.. versionadded:: 0.1
"""

from __future__ import annotations

import base64
import html
import io
import json

import numpy as np

from ..._version import __version__
from ..diagnosis_result import uneven_scatter_note
from .scores import capped_summary

__all__ = ["validation_report", "confusion_figure", "benchmark_html"]


def confusion_figure(confusion: dict):
    """The confusion matrix (truth rows x answer columns) as a matplotlib Figure.

    Parameters
    ----------
    confusion : dict
        ``rows``, ``columns`` and ``matrix`` (counts), as in ``summary.json``.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> fig = confusion_figure({"rows": ["a", "null"], "columns": ["a", "none"],
    ...                         "matrix": [[2, 0], [1, 3]]})
    >>> fig.axes[0].get_ylabel()
    'truth'
    """
    from matplotlib.figure import Figure
    mat = np.asarray(confusion["matrix"], dtype=int).reshape(len(confusion["rows"]),
                                                             len(confusion["columns"]))
    rows, cols = confusion["rows"], confusion["columns"]
    fig = Figure(figsize=(1.0 + 0.75 * len(cols), 1.0 + 0.45 * len(rows)), layout="constrained")
    ax = fig.add_subplot()
    ax.imshow(mat, cmap="Blues", vmin=0, vmax=max(int(mat.max()), 1), aspect="auto")
    ax.set_xticks(range(len(cols)), cols, rotation=40, ha="right")
    ax.set_yticks(range(len(rows)), rows)
    ax.set_xlabel("answer")
    ax.set_ylabel("truth")
    top = max(int(mat.max()), 1)
    for i in range(mat.shape[0]):
        for j in range(mat.shape[1]):
            if mat[i, j]:
                ax.text(j, i, str(mat[i, j]), ha="center", va="center",
                        color="white" if mat[i, j] > 0.6 * top else "black")
    ax.set_title("blind benchmark: truth x answer")
    return fig


def _png_base64(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _fmt(x, digits=3) -> str:
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "n/a"
    return f"{x:.{digits}g}" if isinstance(x, float) else str(x)


def benchmark_html(summary: dict, fig) -> str:
    """A self-contained HTML page of a benchmark's summary, the figure embedded as PNG."""
    e = html.escape
    rows = []
    for label, key, ci, count in (
            ("top-1 among effect twins", "top1", "top1_ci", "top1_count"),
            ("top-1 among effect twins with a significant gap", "top1_detected",
             "top1_detected_ci", "top1_detected_count"),
            ("false attribution among null twins", "null_false", "null_false_ci", "null_false_count"),
            ("unexplained among out-of-catalogue twins", "ooc_unexplained", "ooc_ci", "ooc_count"),
            ("unexplained among out-of-catalogue twins with a significant gap", "ooc_detected",
             "ooc_detected_ci", "ooc_detected_count"),
            ("magnitude interval coverage", "coverage", "coverage_ci", "coverage_count")):
        if count not in summary:   # a summary scored before this score existed
            continue
        lo, hi = summary[ci]
        k, n = summary[count]
        rows.append(f"<tr><td>{e(label)}</td><td>{k} / {n}</td><td>{_fmt(summary[key])}</td>"
                    f"<td>{_fmt(lo)} - {_fmt(hi)}</td></tr>")
    lo, hi = summary["shrink_ci"]
    rows.append(f"<tr><td>median held-out gap shrink (effect twins where measured)</td>"
                f"<td>{summary['shrink_n']} of {summary['counts']['effect']}</td>"
                f"<td>{_fmt(summary['shrink_median'])}</td><td>{_fmt(lo)} - {_fmt(hi)} "
                f"({e(summary['shrink_ci_method'])})</td></tr>")
    twin_rows = "".join(
        f"<tr><td>{e(t['twin'])}</td><td>{e(t['truth_label'])}</td>"
        f"<td>{_fmt(t['truth_magnitude'])}</td><td>{e(t['answer'])}{' (partial)' if t.get('partial') else ''}</td>"
        f"<td>{_fmt(t.get('magnitude'))}</td><td>{e(str(t.get('interval')))}</td>"
        f"<td>{_fmt(t.get('shrink'))}</td></tr>" for t in summary["twins"])
    settings = e(json.dumps({k: summary[k] for k in ("commit", "version", "settings")}, indent=1,
                            default=str))
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>bedstruct blind benchmark</title>
<style>body{{font-family:sans-serif;max-width:60em;margin:2em auto}}
table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:2px 6px}}</style></head>
<body><h1>Blind benchmark</h1>
<p>{summary['n']} twins ({summary['counts']['effect']} effect, {summary['counts']['null']} null,
{summary['counts']['out_of_catalogue']} out-of-catalogue) made on
<b>{e(summary['settings']['twins_engine'])}</b>, diagnosed on <b>{e(summary['settings']['sim'])}</b>,
truth sealed before the first diagnosis (SHA-256 {e(summary['truth_sha256'])}).
Intervals: Clopper-Pearson 95 % for counts.</p>
<table><tr><th>score</th><th>count</th><th>value</th><th>95 % interval</th></tr>{''.join(rows)}</table>
<h2>Confusion matrix</h2>
<img alt="confusion matrix" src="data:image/png;base64,{_png_base64(fig)}">
<h2>Twins</h2>
<table><tr><th>twin</th><th>truth</th><th>magnitude</th><th>answer</th><th>fitted</th>
<th>interval</th><th>shrink</th></tr>{twin_rows}</table>
<h2>Settings</h2><pre>{settings}</pre></body></html>
"""


def validation_report(result):
    """A report of a :class:`ValidationResult` (goals, confusion matrix, magnitude recovery)."""
    from ...report._model import Report, Table, run_section
    from .. import figures as pdg

    rep = Report(f"Diagnosis validation on synthetic twins ({result.preset})",
                 inputs={"simulator": result.simulator, "preset": result.preset},
                 settings=result.settings, version=__version__)

    def goals(s):
        s.text = ("Twins generated and diagnosed with the analytic SURROGATE simulator, not the DEM "
                  "engine." if result.simulator == "surrogate" else "")
        for k, g in result.goals.items():
            over = (f"; over the {g['n_twins']} effect twin(s) with a held-out gap beyond noise "
                    f"({g['n_no_heldout_gap']} without one)" if "n_no_heldout_gap" in g else "")
            s.add_number(k, g["value"], "1",
                         f"goal {g['goal']}: {'met' if g['met'] else 'NOT met'}{over}")
        s.add_number("null_gap_flagged", result.null_gap_flagged, "1",
                     "fraction of null twins where 'where' flagged a significant gap")
        s.add_number("median_gap_shrink_rms", result.median_gap_shrink_rms, "1",
                     "median shrink of the RMS held-out gap (noise floor included)")
        s.add_number("magnitude_coverage", result.magnitude_coverage, "1",
                     "fraction of correct attributions whose 95 % CI holds the true magnitude")
        s.add_number("magnitude_median_relative_error", result.magnitude_median_relative_error, "1",
                     "median |fitted - true| / true")
        ident = result.identifiable
        if ident.get("not_identifiable"):
            why = (f"over the twins of identifiable effects only (not identifiable with these "
                   f"observables: {', '.join(ident['not_identifiable'])})")
            s.add_number("top1_accuracy_identifiable", ident["top1_accuracy"], "1",
                         f"{why}; {ident['n_effect_twins']} twin(s)")
            s.add_number("out_of_catalogue_unexplained_identifiable",
                         ident["out_of_catalogue_unexplained"], "1",
                         f"{why}; {ident['n_out_of_catalogue_twins']} twin(s)")
        det = result.detected
        if det.get("n_effect_twins_undetected"):
            why = (f"over the twins whose gap 'where' found significant ("
                   f"{det['n_effect_twins_undetected']} effect twin(s) carry none: no method can "
                   "attribute them)")
            s.add_number("top1_accuracy_detected", det["top1_accuracy"], "1",
                         f"{why}; {det['n_effect_twins']} twin(s)")
            s.add_number("out_of_catalogue_unexplained_detected",
                         det["out_of_catalogue_unexplained"], "1",
                         f"{why}; {det['n_out_of_catalogue_twins']} twin(s)")
        capped = capped_summary(result.twins)
        if capped:
            s.text += (f" Effect twins held at the top of the prior below the drawn gap: {capped}; "
                       "the prior range caps how strong a twin of that effect can be.")
        missing = result.settings.get("missing_runs") or {}
        dropped = result.settings.get("unobservable") or {}
        failed = result.settings.get("failed") or []
        if missing or dropped or failed:
            s.text += (" Missing data: " + "; ".join(
                [f"{n} not observed in {k} fingerprint run(s)" for n, k in missing.items()]
                + [f"{n} dropped ({why})" for n, why in dropped.items()]
                + [f"twin {f['twin']} ({f['type']}) failed: {f['error'][:120]}" for f in failed]) + ".")
        uneven = result.settings.get("uneven_scatter") or {}
        if uneven:
            s.text += " Scatter: " + "; ".join(uneven_scatter_note(n, u) for n, u in uneven.items()) + "."

    def confusion(s):
        c = result.confusion
        s.tables.append(Table(["truth \\ diagnosis", *c["columns"]],
                              [[r, *row] for r, row in zip(c["rows"], c["matrix"])]))
        fig, _ = pdg.plot_confusion(result)
        s.add_figure(fig, "confusion matrix")

    def magnitudes(s):
        s.tables.append(Table(["effect", "true", "fitted", "95 % CI", "covered"],
                              [[m["effect"], _fmt(m["true"]), _fmt(m["fitted"]),
                                f"[{m['interval'][0]:.3g}, {m['interval'][1]:.3g}]", m["covered"]]
                               for m in result.magnitudes]))

    def twins(s):
        drawn = next((tuple(t["snr_range"]) for t in result.twins if t.get("snr_range")), None)
        s.text = ("One row per diagnosis. Twin gap: the effect's gap on the calibration "
                  "observables after recalibration, in the twin's own noise (drawn "
                  + (f"from U{drawn}σ, " if drawn else "") + "capped at the prior top), on the "
                  "response simulated at the magnitude first solved on the fingerprint (each "
                  "record states that node and its gap: twin_node_magnitude, twin_node_gap_sigma).")
        s.tables.append(Table(
            ["twin", "type", "true effect", "true magnitude", "twin gap (σ)", "verdict",
             "diagnosis", "fitted", "held-out gap shrink", "not told apart from"],
            [[t["twin"], t["type"], t.get("true_effect") or "", _fmt(t.get("true_magnitude")),
              _fmt(t.get("twin_gap_sigma"), 2), t["verdict"], t["predicted"],
              _fmt(t.get("fitted_magnitude")), _fmt(t.get("shrink"), 2),
              ", ".join(t.get("not_told_apart") or [])] for t in result.twins]))

    for key, t, fn in (("goals", "Goals", goals), ("confusion", "Confusion matrix", confusion),
                       ("magnitudes", "Magnitude recovery", magnitudes), ("twins", "Twins", twins)):
        rep.sections.append(run_section(key, t, fn, ok_badge=False))
    return rep
