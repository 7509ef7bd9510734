"""Render a :class:`Report` as one self-contained HTML file."""

from __future__ import annotations

import html
import json
import math
from pathlib import Path

import numpy as np

from .._atomic import atomic_path
from ._model import Report, Section

__all__ = ["render_html", "write_report"]

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;max-width:1100px;margin:2em auto;
padding:0 1em;color:#1d2330;line-height:1.45}
h1{font-size:1.6em;margin-bottom:.2em}h2{border-bottom:2px solid #dde3ec;padding-bottom:.2em;margin-top:1.8em}
table{border-collapse:collapse;margin:.6em 0;font-size:.92em}
td,th{border:1px solid #dde3ec;padding:.25em .6em;text-align:left;vertical-align:top}
th{background:#f3f6fa}td.num{text-align:right;font-variant-numeric:tabular-nums}
.status{display:inline-block;padding:.05em .5em;border-radius:.6em;font-size:.8em;margin-left:.5em}
.ok{background:#dff3e4;color:#185c2b}.failed{background:#fde2e1;color:#8a1c17}
.skipped{background:#eceff3;color:#4a5568}.not-meaningful{background:#fff4d6;color:#7a5200}
.state{border-left:4px solid #3867d6;background:#f3f6fd;padding:.6em 1em;margin:1em 0}
.state.warn{border-left-color:#d69e2e;background:#fffaf0}.state b{font-size:1.1em}figure{display:inline-block;margin:.6em .6em .6em 0}
figure img{max-width:100%;border:1px solid #e5e9f0}figcaption{font-size:.85em;color:#4a5568}
.def{color:#4a5568;font-size:.88em}.ref{color:#718096;font-style:italic}.error{background:#fff5f5;border-left:4px solid #e53e3e;padding:.5em .8em}
nav a{margin-right:.8em}
"""


_LENGTH_SI = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "nm": 1e-9, "Å": 1e-10,
              "Bohr": 5.29177210903e-11}
#: Natural display units of lengths, largest first, with the smallest size (m) each shows.
_LENGTH_DISPLAY = (("m", 1.0), ("mm", 1e-3), ("µm", 1e-6), ("nm", 1e-9))
_PERCENT_KEYS = ("rattler_fraction", "uncovered_fraction", "network_fraction", "moving_fraction",
                 "wall_cell_fraction")


#: A number below this fraction of its scale is rounding noise, shown as 0.
_NOISE = 1e-12


def _is_probability(name: str) -> bool:
    """Whether a quantity or column named ``name`` is a probability or a model weight.

    A tiny probability is a result, not rounding noise, so it is never shown as 0:
    ``p``, ``p_...``, ``p (...)`` and names ending in ``weight``.
    """
    n = name.strip().lower()
    return n == "p" or n.startswith(("p_", "p (")) or n.endswith("weight")


def _number(v: float, digits: int = 4, scale: float | None = None) -> str:
    """A float with ``digits`` significant digits.

    Parameters
    ----------
    v : float
        The value, in the unit it is shown in.
    digits : int
        Significant digits.
    scale : float, optional
        The size of the values shown with it (its column, its list): ``v`` below
        ``1e-12 * scale`` is rounding noise and shown as ``0`` (``0.0``: nothing is).

    Returns
    -------
    str
        Positional notation from 1e-4 to 1e15 (thousands separated from 10 ** digits on,
        rounded to ``digits`` significant digits), scientific notation (``1.58e-16``)
        outside that range.

    Examples
    --------
    >>> _number(0.0853412), _number(1.58e-16), _number(-2.84e-14, scale=72.6)
    ('0.08534', '1.58e-16', '0')
    >>> _number(123456.7), _number(1.3912e12), _number(3.2e16), _number(0.00012345)
    ('123,500', '1,391,000,000,000', '3.2e+16', '0.0001234')
    """
    if not math.isfinite(v):
        return "n/a"
    if v == 0 or (scale is not None and abs(v) < _NOISE * abs(scale)):
        return "0"
    if abs(v) < 1e-4 or abs(v) >= 1e15:
        mantissa, exponent = f"{v:.{digits - 1}e}".split("e")
        if "." in mantissa:
            mantissa = mantissa.rstrip("0").rstrip(".")
        return f"{mantissa}e{exponent[0]}{exponent[1:].lstrip('0') or '0'}"
    if abs(v) >= 10 ** digits:
        return f"{float(f'{v:.{digits}g}'):,.0f}"
    return np.format_float_positional(v, precision=digits, unique=False, fractional=False, trim="-")


def _scale(values, factor: float = 1.0) -> float | None:
    """The largest finite magnitude among ``values`` (nested lists too), times ``factor``."""
    vals = [abs(v) for v in _finite_values(_flatten(values))]
    return max(vals) * abs(factor) if vals else None


def _flatten(values) -> list:
    out = []
    for v in values:
        if isinstance(v, np.ndarray):
            v = v.tolist()
        if isinstance(v, (list, tuple)):
            out.extend(_flatten(v))
        else:
            out.append(v)
    return out


def _finite_values(value):
    flat = np.ravel(np.asarray(value, dtype=object)) if isinstance(value, (list, tuple, np.ndarray)) else [value]
    return [float(v) for v in flat if isinstance(v, (int, float, np.number)) and not isinstance(v, bool)
            and math.isfinite(float(v))]


def _display_unit(value, unit: str, key: str = "") -> tuple[float, str]:
    """(factor, unit) that shows ``value`` in natural units: um or mm, %, ms, mm/s, 1/mm^3."""
    if unit in _LENGTH_SI:
        vals = _finite_values(value)
        big = max((abs(v) for v in vals), default=0.0) * _LENGTH_SI[unit]
        # mm and um cover powder beds; metres from 1 m, nm below 1 um
        if big >= 1.0:
            target, size = _LENGTH_DISPLAY[0]
        elif big >= 1e-3 or big == 0.0:
            target, size = _LENGTH_DISPLAY[1]
        elif big >= 1e-6:
            target, size = _LENGTH_DISPLAY[2]
        else:
            target, size = _LENGTH_DISPLAY[3]
        return _LENGTH_SI[unit] / size, target
    if unit.endswith("/s") and unit[:-2] in _LENGTH_SI:
        return _LENGTH_SI[unit[:-2]] / 1e-3, "mm/s"
    if unit.startswith("1/") and unit.endswith("^3") and unit[2:-2] in _LENGTH_SI:
        # a number density: per mm^3 (per m^3 for sparse ones), whatever the dump's unit
        per_mm3 = (1e-3 / _LENGTH_SI[unit[2:-2]]) ** 3
        vals = _finite_values(value)
        if max((abs(v) for v in vals), default=1.0) * per_mm3 >= 1e-2:
            return per_mm3, "1/mm³"
        return (1.0 / _LENGTH_SI[unit[2:-2]]) ** 3, "1/m³"
    if unit == "s":
        vals = _finite_values(value)
        if vals and max(abs(v) for v in vals) < 1:
            return 1e3, "ms"
    if unit == "1" and key.endswith(_PERCENT_KEYS):
        return 100.0, "%"
    if unit == "degC":
        return 1.0, "°C"
    if unit == "1":
        return 1.0, ""
    return 1.0, unit


#: Row names of the page's input table (the JSON keeps the keys).
_INPUT_LABELS = {"paths": "files", "frames_in_input": "frames in the input",
                 "frames_selected": "frames selected (index in the input)",
                 "frame_described": "frame the sections describe",
                 "units_given": "units given (--units)", "radius_given": "radius given (--radius)",
                 "boundary": "boundary (data file)", "contact_gaps": "gaps of the given contacts"}


def _input_html(value) -> str:
    """A value of the input table: strings one per line, a table of values as 'key: value'
    lines, numbers as :func:`_fmt`, nothing as 'not given'."""
    if value is None:
        return "not given"
    if isinstance(value, (list, tuple)) and value and all(isinstance(v, str) for v in value):
        return "<br>".join(html.escape(v) for v in value)
    if isinstance(value, dict):
        return "<br>".join(f"{html.escape(str(k).replace('_', ' '))}: {_fmt(v)}"
                           for k, v in value.items())
    if isinstance(value, (list, tuple)) and value and all(
            isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in value):
        return ", ".join(str(int(v)) for v in value[:12]) + (", ..." if len(value) > 12 else "")
    return _fmt(value)


def _fmt(value, factor: float = 1.0, scale: float | None = None) -> str:
    """A value for the page: numbers by :func:`_number`, lists as lists, None as n/a.

    ``scale`` (in the shown unit) is the size of the values shown together with
    ``value`` (see :func:`_number`); a list's own largest value is its scale when none
    is given.
    """
    if value is None:
        return "n/a"
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, int):
        return _number(value * factor, scale=scale) if factor != 1.0 else str(value)
    if isinstance(value, float):
        return _number(value * factor, scale=scale)
    if isinstance(value, (list, tuple)):
        if scale is None:
            scale = _scale(value, factor)
        inner = ", ".join(_fmt(v, factor, scale) for v in value[:12])
        return f"[{inner}{', ...' if len(value) > 12 else ''}]"
    return html.escape(str(value))


def _quantity_scale(key: str, value, unit: str, factor: float) -> float | None:
    """The scale of a reported number: a dimensionless one is of order 1, a list its largest
    value; a probability is never rounding noise (0.0), a lone number with a unit has none."""
    if _is_probability(key.rsplit(".", 1)[-1]):
        return 0.0
    if isinstance(value, (list, tuple, np.ndarray)):
        return _scale(value, factor)
    return abs(factor) if unit == "1" else None


def _section_html(s: Section) -> str:
    css = s.status.replace(" ", "-")
    badge = ("" if s.status == "ok" and not s.ok_badge
             else f'<span class="status {css}">{html.escape(s.status)}</span>')
    parts = [f'<section id="{html.escape(s.key)}"><h2>{html.escape(s.title)}{badge}</h2>']
    if s.error:
        parts.append(f'<p class="error">This section failed: {html.escape(s.error)}. '
                     f'The rest of the report is unaffected.</p>')
    if s.text:
        parts.append(f"<p>{html.escape(s.text)}</p>")
    if s.numbers:
        parts.append("<table><tr><th>quantity</th><th>value</th><th>unit</th><th>definition</th></tr>")
        for key, q in s.numbers.items():
            link = (f' <span class="ref">(see {html.escape(q.doc)})</span>' if q.doc else "")
            factor, unit = _display_unit(q.value, q.unit, key)
            scale = _quantity_scale(key, q.value, q.unit, factor)
            parts.append(f'<tr><td>{html.escape(key)}</td><td class="num">{_fmt(q.value, factor, scale)}</td>'
                         f'<td>{html.escape(unit)}</td><td class="def">{html.escape(q.definition)}{link}</td></tr>')
        parts.append("</table>")
    for t in s.tables:
        parts.append("<table>")
        if t.caption:
            parts.append(f"<caption>{html.escape(t.caption)}</caption>")
        units = list(t.units) if t.units else [""] * len(t.columns)
        shown = [_display_unit([row[c] for row in t.rows], u or "1", t.columns[c]) if u else (1.0, "")
                 for c, u in enumerate(units)]
        parts.append("<tr>" + "".join(
            f"<th>{html.escape(c)}{f' ({html.escape(u)})' if u else ''}</th>"
            for c, (_, u) in zip(t.columns, shown)) + "</tr>")
        scales = [0.0 if _is_probability(name) else
                  _scale([row[c] for row in t.rows if c < len(row)], f)
                  for c, (name, (f, _)) in enumerate(zip(t.columns, shown))]
        for row in t.rows:
            parts.append("<tr>" + "".join(f'<td class="num">{_fmt(v, f, sc)}</td>'
                                          for v, (f, _), sc in zip(row, shown, scales)) + "</tr>")
        parts.append("</table>")
    for caption, uri in s.figures:
        parts.append(f'<figure><img src="{uri}" alt="{html.escape(caption)}">'
                     f"<figcaption>{html.escape(caption)}</figcaption></figure>")
    parts.append("</section>")
    return "\n".join(parts)


def _state_html(report: Report) -> str:
    """The box at the top: what the input is, the evidence, and what is not reported."""
    st = report.state
    if not st:
        return ""
    bed = st["kind"] in ("settled bed", "pile")
    parts = [f'<div class="state{"" if bed else " warn"}" id="input-state"><b>Input: {html.escape(st["kind"])}</b>'
             f' &mdash; {html.escape(st["reason"])}.']
    if st.get("not_meaningful"):
        parts.append(" Not reported for this input: " + ", ".join(html.escape(k) for k in st["not_meaningful"])
                     + " (each section says why).")
    parts.append("</div>")
    return "".join(parts)


def _skipped_html(report: Report) -> str:
    """The frames of damaged dumps left out of the report (read with ``on_error="skip"``)."""
    skipped = report.inputs.get("skipped_frames") or []
    if not skipped:
        return ""
    rows = "".join(
        f"<tr><td>{html.escape(str(k.get('path')))}</td>"
        f"<td class=\"num\">{_fmt(k.get('timestep'))}</td><td class=\"num\">{_fmt(k.get('line'))}</td>"
        f"<td>{html.escape(str(k.get('reason')))}</td></tr>" for k in skipped)
    return (f'<div class="state warn" id="skipped-frames"><b>{len(skipped)} malformed frame(s) left out</b>'
            f" &mdash; the input was read leniently; these frames are not in the report."
            f"<table><tr><th>file</th><th>timestep</th><th>line</th><th>what is wrong</th></tr>"
            f"{rows}</table></div>")


def _pictures_html(report: Report) -> str:
    """The pictures of the bed at the top of the page, with how they were drawn."""
    if not report.pictures and not report.picture_note:
        return ""
    figs = "".join(f'<figure><img src="{uri}" alt="{html.escape(caption)}">'
                   f"<figcaption>{html.escape(caption)}</figcaption></figure>"
                   for caption, uri in report.pictures)
    note = f'<p class="def">{html.escape(report.picture_note)}</p>' if report.picture_note else ""
    return f'<div id="bed-pictures">{figs}{note}</div>'


def render_html(report: Report) -> str:
    """The report as a self-contained HTML document (figures embedded as data URIs)."""
    nav = " ".join(f'<a href="#{html.escape(s.key)}">{html.escape(s.title)}</a>' for s in report.sections)
    inputs = "".join(f"<tr><th>{html.escape(_INPUT_LABELS.get(k, str(k).replace('_', ' ')))}"
                     f"</th><td>{_input_html(v)}</td></tr>"
                     for k, v in report.inputs.items() if k != "skipped_frames")
    if "skipped_frames" in report.inputs:
        n = len(report.inputs["skipped_frames"] or [])
        inputs += (f"<tr><th>skipped_frames</th><td>{n} (malformed frames left out"
                   f"{', listed above' if n else ''})</td></tr>")
    body = "\n".join(_section_html(s) for s in report.sections)
    return (f"<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
            f"<title>{html.escape(report.title)}</title><style>{_CSS}</style></head><body>"
            f"<h1>{html.escape(report.title)}</h1>"
            f"<p class=\"def\">bedstruct {html.escape(report.version)}</p>"
            f"{_state_html(report)}{_skipped_html(report)}{_pictures_html(report)}<table>{inputs}</table><nav>{nav}</nav>{body}</body></html>")


def _atomic_write(path: Path, text: str) -> None:
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)


def write_report(report: Report, out_dir) -> tuple[Path, Path]:
    """Write ``report.html`` and ``report.json`` into ``out_dir`` atomically.

    Returns the two paths.
    """
    out = Path(out_dir)
    html_path, json_path = out / "report.html", out / "report.json"
    _atomic_write(json_path, json.dumps(report.to_json(), indent=1, allow_nan=False))
    _atomic_write(html_path, render_html(report))
    return html_path, json_path
