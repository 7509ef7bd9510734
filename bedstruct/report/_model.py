"""The report's content model: sections of numbers, tables and figures."""

from __future__ import annotations

import io
import base64
import logging
import math
import time
import traceback
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from .._json import to_jsonable

__all__ = ["Quantity", "Table", "Section", "Report", "run_section", "not_meaningful_section"]

log = logging.getLogger(__name__)

SCHEMA = "bedstruct.report/1"


@dataclass(frozen=True)
class Quantity:
    """One reported number with its unit and definition.

    Parameters
    ----------
    value : float, int, str, list or None
        The number (None when it cannot be computed for this input).
    unit : str
        Unit, ``"1"`` for dimensionless quantities.
    definition : str
        One sentence saying what the number is.
    doc : str, optional
        Link (relative to the docs) to the full definition.
    """

    value: Any
    unit: str
    definition: str
    doc: str | None = None

    def to_json(self) -> dict:
        out = {"value": to_jsonable(self.value), "unit": self.unit, "definition": self.definition}
        if self.doc:
            out["doc"] = self.doc
        return out


@dataclass
class Table:
    """A small table: column names, rows of values and, optionally, each column's unit.

    ``units`` holds one unit per column (``"1"`` dimensionless, ``""`` for
    labels); the JSON keeps the values in these units and the HTML shows
    them in natural ones (um or mm, %, ms).
    """

    columns: list[str]
    rows: list[list[Any]]
    caption: str = ""
    units: list[str] | None = None

    def __post_init__(self):
        if self.units is not None and len(self.units) != len(self.columns):
            raise ValueError(f"`units` must have one entry per column ({len(self.columns)}); got {len(self.units)}")

    def to_json(self) -> dict:
        out = {"caption": self.caption, "columns": list(self.columns), "rows": to_jsonable(self.rows)}
        if self.units is not None:
            out["units"] = list(self.units)
        return out


@dataclass
class Section:
    """A report section.

    ``status`` is ``"ok"``, ``"failed"``, ``"skipped"`` (the analysis found
    nothing to measure, e.g. no pile) or ``"not meaningful"`` (the analysis
    does not apply to this kind of input, e.g. German's law on a dilute flow;
    ``text`` gives the reason and no numbers are reported).

    ``ok_badge`` says whether the HTML heading of an ``"ok"`` section shows the
    ``ok`` badge. A section whose content is a judgement (a diagnosis's verdict)
    leaves it out: ``ok`` beside "unexplained" would contradict it. The other
    statuses are always shown.
    """

    key: str
    title: str
    status: str = "ok"
    numbers: dict[str, Quantity] = field(default_factory=dict)
    tables: list[Table] = field(default_factory=list)
    figures: list[tuple[str, str]] = field(default_factory=list)  # (caption, data URI)
    text: str = ""
    error: str | None = None
    seconds: float = 0.0
    ok_badge: bool = True

    def add_number(self, key: str, value, unit: str, definition: str, doc: str | None = None):
        self.numbers[key] = Quantity(value, unit, definition, doc)

    def add_figure(self, fig, caption: str) -> None:
        """Embed a matplotlib Figure as a PNG data URI (the figure is then closed)."""
        self.figures.append((caption, figure_uri(fig)))

    def to_json(self) -> dict:
        out = {"title": self.title, "status": self.status,
               "numbers": {k: q.to_json() for k, q in self.numbers.items()},
               "tables": [t.to_json() for t in self.tables],
               "n_figures": len(self.figures), "seconds": round(self.seconds, 3)}
        if self.text:
            out["text"] = self.text
        if self.error:
            out["error"] = self.error
        return out


@dataclass
class Report:
    """A whole report: inputs, settings and sections in order."""

    title: str
    inputs: dict[str, Any]
    settings: dict[str, Any]
    sections: list[Section] = field(default_factory=list)
    version: str = ""
    state: dict | None = None
    #: Pictures of the bed for the top of the page: (caption, PNG data URI).
    pictures: list[tuple[str, str]] = field(default_factory=list)
    #: How the pictures were drawn, or why one is missing.
    picture_note: str = ""

    def section(self, key: str) -> Section:
        for s in self.sections:
            if s.key == key:
                return s
        raise KeyError(key)

    @property
    def failed(self) -> list[str]:
        """Keys of sections that failed."""
        return [s.key for s in self.sections if s.status == "failed"]

    def to_json(self) -> dict:
        """The full, documented JSON document (schema ``bedstruct.report/1``)."""
        out = {"schema": SCHEMA, "bedstruct_version": self.version, "title": self.title,
               "inputs": to_jsonable(self.inputs), "settings": to_jsonable(self.settings),
               "input_state": self._state_json()}
        if self.pictures or self.picture_note:
            out["pictures"] = {"captions": [c for c, _ in self.pictures], "note": self.picture_note}
        out.update(sections={s.key: s.to_json() for s in self.sections},
                   failed_sections=self.failed)
        return out

    def _state_json(self) -> dict | None:
        if self.state is None:
            return None
        out = {k: v for k, v in self.state.items() if k != "evidence"}
        out["evidence"] = {k: q.to_json() for k, q in self.state.get("evidence", {}).items()}
        return out

    def summary(self) -> dict:
        """A compact summary: every number's value by ``section.key``, plus status."""
        values = {}
        for s in self.sections:
            for k, q in s.numbers.items():
                values[f"{s.key}.{k}"] = to_jsonable(q.value)
        out = {"schema": SCHEMA, "title": self.title,
               "input_kind": self.state["kind"] if self.state else None,
               "sections": {s.key: s.status for s in self.sections},
               "failed_sections": self.failed, "values": values}
        if self.inputs.get("skipped_frames"):
            out["skipped_frames"] = to_jsonable(self.inputs["skipped_frames"])
        return out


def figure_uri(fig) -> str:
    """A matplotlib Figure as a PNG data URI."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    return png_uri(buf.getvalue())


def png_uri(png: bytes) -> str:
    """PNG bytes as a data URI."""
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def run_section(key: str, title: str, func: Callable[[Section], None], *,
                ok_badge: bool = True) -> Section:
    """Run ``func(section)``; an exception marks the section failed, never the report.

    ``ok_badge`` is the section's :attr:`Section.ok_badge`.
    """
    section = Section(key, title, ok_badge=ok_badge)
    t0 = time.perf_counter()
    try:
        func(section)
    except _Skip as skip:
        section.status = "skipped"
        section.text = str(skip)
    except Exception as exc:  # a failing section must not take the report down
        section.status = "failed"
        section.error = f"{type(exc).__name__}: {exc}"
        log.debug("section %s failed:\n%s", key, traceback.format_exc())
    else:
        numeric = [q.value for q in section.numbers.values() if not isinstance(q.value, str)]
        if numeric and not any(_has_finite(v) for v in numeric):
            # an "ok" beside numbers that are all n/a would say something was measured
            section.status = "skipped"
            section.text = " ".join(t for t in ("No number could be computed for this input.", section.text) if t)
            section.numbers.clear()
    section.seconds = time.perf_counter() - t0
    return section


def not_meaningful_section(key: str, title: str, reason: str) -> Section:
    """A section not run because its analysis does not apply to this input."""
    return Section(key, title, status="not meaningful", text=reason)


def _has_finite(value) -> bool:
    """True when ``value`` (a number, list or array, possibly nested) holds a finite number."""
    if isinstance(value, (list, tuple, np.ndarray)):
        return any(_has_finite(v) for v in (value.tolist() if isinstance(value, np.ndarray) else value))
    if isinstance(value, (bool, np.bool_)) or value is None:
        return False
    try:
        return math.isfinite(float(value))
    except (TypeError, ValueError):
        return False


class _Skip(Exception):
    """Raised inside a section to mark it skipped with a reason."""


def skip(reason: str):
    """Mark the running section as skipped (not applicable to this input)."""
    raise _Skip(reason)
