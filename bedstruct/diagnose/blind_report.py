"""Figure and HTML page of a blind benchmark (:mod:`bedstruct.diagnose.blind`).

.. versionadded:: 0.1
"""

from __future__ import annotations

import base64
import html
import io
import json

import numpy as np

__all__ = ["confusion_figure", "benchmark_html"]


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
