"""The diagnosis in plain words and natural units, for a process engineer.

:func:`answer` turns a :class:`~bedstruct.diagnose.diagnosis_result.Diagnosis` into the
sentences and rows the CLI prints and the report's first screen shows: where the
simulation misses the measurements (measured against simulated, in µm, deg or %), which
effect explains it with its physical magnitude and interval, how far the gap shrinks on
the held-out observables, the recalibrated parameters, and what to measure next and why.
:func:`compact_answer` is the one-line JSON of ``bedstruct diagnose --json``. The
statistics behind them (z, chi-square, model weights) are in the report's appendix.

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

__all__ = ["Answer", "answer", "answer_lines", "compact_answer", "conditions_text", "difference_text",
           "gap_rows",
           "magnitude_text", "quantity_text"]

#: |z| below which a deviation is within noise (said so instead of a number of sigmas).
_WITHIN_NOISE = 2.0

#: How each effect magnitude is said: words, factor to the shown unit, shown unit, signed.
_MAGNITUDE_WORDS = {
    "relative_humidity": ("relative humidity", 100.0, "% RH", False),
    "fines_mass_fraction": ("mass fraction of fines missing", 100.0, "%", False),
    "wall_friction_excess": ("wall friction above particle friction, Δµ", 1.0, "", True),
    "extra_rolling_friction": ("extra rolling friction, µr", 1.0, "", True),
    "bond_strength_ratio": ("bond strength after rest, relative to cohesion", 1.0, "×", False),
    "ramp_time": ("blade start-up ramp time", 1e3, "ms", False),
}
#: How each recalibrated parameter is said: words, factor, unit.
_PARAMETER_WORDS = {
    "cohesion_energy_density": ("cohesion energy density", 1e-6, "MJ/m³"),
    "friction": ("sliding friction µ", 1.0, ""),
    "rolling_friction": ("rolling friction µr", 1.0, ""),
    "restitution": ("coefficient of restitution", 1.0, ""),
}


def _num(v: float, digits: int = 3, *, signed: bool = False) -> str:
    """``v`` to ``digits`` significant digits, without float noise or an exponent when avoidable.

    Examples
    --------
    >>> _num(29.84), _num(0.08534837), _num(35621.7), _num(-0.5, signed=True)
    ('29.8', '0.0853', '35600', '-0.5')
    """
    if v is None or not math.isfinite(v):
        return "n/a"
    if v == 0:
        return "0"
    mag = math.floor(math.log10(abs(v)))
    if -4 <= mag < 6:
        decimals = max(digits - 1 - mag, 0)
        text = f"{round(v, digits - 1 - mag):.{decimals}f}"
        if "." in text:
            text = text.rstrip("0").rstrip(".")
    else:
        text = f"{v:.{digits - 1}e}"
    if signed and v > 0:
        text = "+" + text
    return text


def _unit_of(value: float, unit: str, kind: str) -> tuple[float, str]:
    """The factor and natural unit to show a value of an observable in."""
    if unit == "m":
        return (1e6, "µm") if abs(value) < 1e-3 else (1e3, "mm")
    if unit == "1" and kind == "packing_fraction":
        return 100.0, "%"
    if unit == "1":
        return 1.0, ""
    return 1.0, unit


def quantity_text(value: float, unit: str, kind: str = "", *, sigma: float | None = None,
                  like: float | None = None, resolution: float | None = None) -> str:
    """A measured or simulated value in natural units (µm, mm, deg, %).

    The value has three significant digits, more where ``resolution`` needs them: it is
    then shown at least to the first significant digit of ``resolution``.

    Parameters
    ----------
    value : float
        In the canonical unit ``unit`` (``"m"``, ``"deg"``, ``"1"``).
    unit : str
    kind : str
        Observable kind (a packing fraction is shown in %).
    sigma : float, optional
        Its uncertainty, shown as ``± sigma``.
    like : float, optional
        The value whose natural unit ``value`` is shown in (default: ``value`` itself), so
        that a simulated value beside its measurement is in the measurement's unit.
    resolution : float, optional
        An uncertainty, in ``unit``, that the digits shown must resolve (a measurement's,
        for its value and the simulated one beside it).

    Examples
    --------
    >>> quantity_text(2.984e-05, "m", "psd")
    '29.8 µm'
    >>> quantity_text(33.0, "deg", sigma=4.0)
    '33 ± 4 deg'
    >>> quantity_text(0.5123, "1", "packing_fraction")
    '51.2 %'
    >>> quantity_text(1.004e-3, "m", "bed_height", sigma=2e-6, resolution=2e-6)
    '1.004 ± 0.002 mm'
    >>> quantity_text(9.95e-4, "m", "bed_height", like=1.004e-3, resolution=2e-6)
    '0.995 mm'
    """
    f, u = _unit_of(value if like is None else like, unit, kind)
    digits = 3
    if (resolution is not None and math.isfinite(resolution) and resolution > 0
            and math.isfinite(value) and value != 0):
        digits = max(digits, math.floor(math.log10(abs(value * f)))
                     - math.floor(math.log10(resolution * f)) + 1)
    text = _num(value * f, digits)
    if sigma is not None and math.isfinite(sigma):
        text += f" ± {_num(sigma * f, 2)}"
    return f"{text} {u}".strip()


def difference_text(diff: float, value: float, unit: str, kind: str = "") -> str:
    """A signed difference of two values of an observable, in the unit ``value`` is shown in.

    A difference of values shown in % is said in percentage points.

    Examples
    --------
    >>> difference_text(-2.6e-6, 1.01e-3, "m", "bed_height")
    '-0.0026 mm'
    >>> difference_text(0.46, 30.0, "deg")
    '+0.46 deg'
    >>> difference_text(-0.004, 0.55, "1", "packing_fraction")
    '-0.4 percentage points'
    """
    if not math.isfinite(diff):
        return "n/a"
    f, u = _unit_of(value, unit, kind)
    return f"{_num(diff * f, 2, signed=True)} {_difference_unit(u)}".strip()


def magnitude_text(effect, value: float, interval=None) -> str:
    """An effect's magnitude (and interval) in its physical words and unit.

    Examples
    --------
    >>> from bedstruct.diagnose import effect
    >>> magnitude_text(effect("missing_fines"), 0.0853, (0.0678, 0.0971))
    'mass fraction of fines missing 8.53 % (95 % interval 6.78 to 9.71 %)'
    """
    words, f, u, signed = _MAGNITUDE_WORDS.get(effect.magnitude,
                                               (effect.magnitude.replace("_", " "), 1.0,
                                                "" if effect.unit == "1" else effect.unit, False))
    text = f"{words} {_num(value * f, signed=signed)}{(' ' + u) if u else ''}"
    if interval is not None and all(math.isfinite(v) for v in interval):
        lo, hi = (_num(v * f, signed=signed) for v in interval)
        text += f" (95 % interval {lo} to {hi}{(' ' + u) if u else ''})"
    return text


#: Words for the conditions a label states as ``key=value`` (SI value -> text).
_CONDITION_WORDS = {
    "rest_time": lambda v: f"after {_num(v)} s at rest",
    "box_width": lambda v: f"box {_num(v * 1e3)} mm wide",
    "relative_humidity": lambda v: f"RH {_num(v * 100)} %",
    "stage": lambda v: f"{v} spreading",
    "walled": lambda v: "with side walls" if v in ("True", "true") else "without side walls",
}


def conditions_text(label: str) -> str:
    """A conditions label (:meth:`Conditions.label`) with its ``key=value`` parts in words.

    Examples
    --------
    >>> conditions_text("rest_time=600.0, box_width=0.03")
    'after 600 s at rest, box 30 mm wide'
    >>> conditions_text("v=2.54 cm/s, layer 3")
    'v=2.54 cm/s, layer 3'
    """
    if label in ("", "-"):
        return ""
    out = []
    for part in label.split(", "):
        key, eq, value = part.partition("=")
        fn = _CONDITION_WORDS.get(key) if eq else None
        if fn is None:
            out.append(part)
            continue
        try:
            out.append(fn(float(value)) if key != "stage" and key != "walled" else fn(value))
        except ValueError:
            out.append(part)
    return ", ".join(out)


_WINDOW = re.compile(r"^t=([-+0-9.eE]+)-([-+0-9.eE]+)$")


def _component_words(label: str) -> str:
    """A component label in words.

    A time window ``t=t0-t1`` holds fractions of the stroke (0: the blade starts, 1: it
    ends), as :meth:`~bedstruct.diagnose.measurements.Conditions.label` states them; it is
    said as a percentage of the stroke. Other labels are returned unchanged.

    Examples
    --------
    >>> _component_words("t=0-0.1"), _component_words("t=0.1-1"), _component_words("d10")
    ('0-10 % of the stroke', '10-100 % of the stroke', 'd10')
    """
    m = _WINDOW.match(label)
    if m is None:
        return label
    try:
        lo, hi = float(m.group(1)), float(m.group(2))
    except ValueError:
        return label
    return f"{_num(lo * 100)}-{_num(hi * 100)} % of the stroke"


def _observable_words(row: dict) -> str:
    name = row["observable"].replace("_", " ")
    comp = row["component"]
    return name if comp in ("value", "") else f"{name}, {_component_words(comp)}"


def _difference_unit(unit: str) -> str:
    """The unit a difference of two values shown in ``unit`` is said in.

    A difference of two percentages is in percentage points: "1.8 %" would read as a
    relative change.
    """
    return "percentage points" if unit == "%" else unit


def _gap_words(row: dict) -> str:
    """Where the measurement lies against the simulation, in its natural unit and in words.

    Examples
    --------
    >>> _gap_words(dict(z=3.0, real=0.55, simulated=0.5324, unit="1", kind="packing_fraction"))
    '1.8 percentage points above the simulation, 3.0× the uncertainty'
    """
    z = row["z"]
    if not math.isfinite(z):
        return "not observed in the simulation"
    if abs(z) < _WITHIN_NOISE:
        return "within noise"
    f, u = _unit_of(row["real"], row["unit"], row["kind"])
    u = _difference_unit(u)
    diff = abs(row["real"] - row["simulated"]) * f
    return (f"{_num(diff, 2)}{(' ' + u) if u else ''} {'above' if z > 0 else 'below'} the "
            f"simulation, {abs(z):.1f}× the uncertainty")


def gap_rows(diag) -> list[dict]:
    """Measured against simulated per measured component, before and after, in natural units.

    ``before`` is the recalibrated base model's rerun, ``after`` the rerun with the chosen
    effect(s) added (:attr:`~bedstruct.diagnose.confirm.Shrink.components`); rows follow
    the ranking of the gaps (largest first, as :attr:`Answer.where`).

    Returns
    -------
    list of dict
        ``what`` (words), ``role``, ``unit`` (the natural unit shown: µm, mm, deg, %),
        ``measured``, ``sigma`` (measurement uncertainty), ``base`` (the base model before
        recalibration), ``before``, ``before_sd``, ``after``, ``after_sd`` (simulated mean
        and its standard deviation from run scatter; NaN without a rerun with an effect),
        all in that unit, and ``gap_before``, ``gap_after``: simulated minus measured in
        units of the measurement's uncertainty.
    """
    comps = {(c["observable"], c["component"]): c for c in diag.shrink.components}
    out = []
    for r in diag.where.ranked():
        c = comps.get((r["observable"], r["component"]))
        if c is None:
            continue
        f, u = _unit_of(c["measured"], c["unit"], c["kind"])
        row = {"what": _observable_words(r),
               "role": "calibration" if c["role"] == "calibrate" else "held out", "unit": u}
        for k in ("measured", "sigma", "base", "before", "before_sd", "after", "after_sd"):
            row[k] = c[k] * f
        for k in ("before", "after"):
            row[f"gap_{k}"] = (row[k] - row["measured"]) / row["sigma"]
        out.append(row)
    return out


@dataclass(frozen=True)
class Answer:
    """The diagnosis in plain words.

    Attributes
    ----------
    headline : str
        One sentence: the verdict.
    where : list of dict
        Measured against simulated per observable component, largest gap first: ``what``,
        ``measured``, ``simulated`` (text, natural units), ``gap`` (words), ``z``,
        ``role`` (``"calibration"`` or ``"held out"``).
    which : str
        The effect, its physical magnitude and interval (or why none is named).
    how_far : str
        How far the gap on the held-out observables shrinks with the effect added.
    recalibration : str
        The recalibrated parameters (and any that ended on a physical bound).
    next : str
        What to measure next and why.
    gaps : list of dict
        Measured against simulated, before and after adding the effect, per component in
        natural units (:func:`gap_rows`): the numbers of the first figure.
    """

    headline: str
    where: list
    which: str
    how_far: str
    recalibration: str
    next: str
    gaps: list = ()


#: How an engine of a bridge is named in the answer.
_ENGINE_WORDS = {"liggghts": "LIGGGHTS", "lammps": "LAMMPS", "embedded": "the embedded engine"}


def _lower_first(title: str) -> str:
    return title[:1].lower() + title[1:] if title[1:2].islower() else title


def _headline(diag) -> str:
    att = diag.attribution
    sim = ("the analytic surrogate (a stand-in for tests and examples, not the DEM engine)"
           if diag.simulator == "surrogate" else f"the {diag.simulator} simulation")
    if att.verdict == "attributed":
        names = " together with ".join(_lower_first(diag.fingerprints[e.effect].effect.title)
                                       for e in att.selected)
        if att.partial:
            return (f"The gap between the measurements and {sim} is explained in large part by "
                    f"{names}; something else remains.")
        return f"The gap between the measurements and {sim} is explained by {names}."
    if att.verdict == "none":
        return (f"The measurements and {sim} agree within noise once the simulation is "
                "recalibrated: there is no gap to explain.")
    return (f"Unexplained: no effect of the catalogue explains the gap between the measurements "
            f"and {sim} within noise.")


def _which(diag) -> str:
    att = diag.attribution
    if att.verdict == "attributed":
        parts = []
        for e in att.selected:
            eff = diag.fingerprints[e.effect].effect
            parts.append(f"{eff.title}: {magnitude_text(eff, e.magnitude, e.interval)}")
        bridge = diag.settings.get("bridge") or {}
        unchecked = [e.effect for e in att.selected if e.effect in bridge.get("unprobed", ())]
        if unchecked:
            engine = _ENGINE_WORDS.get(bridge["engine"], bridge["engine"])
            for e in unchecked:
                parts.append(f"{_effect_words(diag, e)}: {engine} does not realise it, so its "
                             "response is the diagnosing simulator's alone, not checked against "
                             f"your {engine} model")
        if att.partial:
            worst = next((w for w in diag.shrink.rerun_worst if w.get("role") == "validate"),
                         None)
            where_ = f", furthest on {_observable_words(worst)}" if worst is not None else ""
            parts.append("a partial explanation: with it the simulation still misses the "
                         f"held-out measurements{where_}: either the powder or the machine "
                         "differs in a further way the catalogue does not hold, or your engine "
                         "responds to this effect differently from the diagnosing simulator")
        return "; ".join(parts) + "."
    if att.verdict == "none":
        return "No effect is needed: recalibration alone fits the calibration observables."
    return "No effect is named: " + _unexplained_words(diag) + "."


def _effect_words(diag, name: str, magnitude: float | None = None) -> str:
    eff = diag.fingerprints[name].effect
    text = _lower_first(eff.title)
    return text if magnitude is None else f"{text} ({magnitude_text(eff, magnitude)})"


def _unexplained_words(diag) -> str:
    """Why nothing is named, in words (the statistics are in the report's appendix)."""
    att, sh = diag.attribution, diag.shrink
    if sh.magnitudes:
        names = " together with ".join(_effect_words(diag, e, a) for e, a in sh.magnitudes.items())
        gof = float(diag.settings.get("gof_alpha", 0.01))
        held = float(diag.settings.get("heldout_alpha", 0.1))
        readings_ok = not (sh.p_rerun_calibration < gof or sh.p_rerun_heldout < held)
        if readings_ok and sh.p_rerun_trials < gof and sh.trial_rows:
            row = sh.trial_rows[0]
            pools = [(int(k), int(n)) for k, n in row["pools"]]
            runs = (f"none of the simulation's {max(n for _, n in pools)} runs"
                    if all(k == 0 for k, _ in pools) else
                    " or ".join(f"{k} of {n}" for k, n in pools) + " of the simulation's runs")
            return (f"the best candidate, {names}, fits the calibration observables and its "
                    f"rerun reproduces the readings, but not the trials that gave none: "
                    f"{row['observable'].replace('_', ' ')} gave no reading in {row['unread']} of "
                    f"your {row['trials']} trials and in {runs}")
        worst = sh.rerun_worst[0] if sh.rerun_worst else None
        where_ = (f", furthest on {_observable_words(worst)}" if worst is not None else "")
        return (f"the best candidate, {names}, fits the calibration observables, but the "
                f"simulation rerun with it does not reproduce the measurements{where_}")
    best = att.ranking[0] if att.ranking else None
    closest = (f"; the closest candidate was {_effect_words(diag, best.effect, best.magnitude)}"
               if best is not None else "")
    if "not identifiable" in att.reason:
        return ("the best candidate would fit, but these measurements cannot tell its effect "
                "from noise (see what to measure next and the report's appendix)" + closest)
    if getattr(att.best, "effects", ()):
        return ("even the best candidate leaves a gap beyond noise: the simulation misses "
                "something the catalogue of effects does not hold" + closest)
    return ("after recalibration a gap beyond noise remains that no effect of the catalogue "
            "narrows: the simulation misses something the catalogue does not hold" + closest)


def _heldout_gap(diag) -> bool:
    """Whether the held-out observables showed a gap beyond noise before, to shrink.

    A shrink is measured where the excess gap before is positive and its chi-square test
    against noise (:attr:`~bedstruct.diagnose.confirm.Shrink.p_before`) is below the
    diagnosis' ``alpha``; a partial explanation, named for the part of the held-out gap it
    closes, always has one. Elsewhere the ratio of two excesses within noise measures noise
    (a shrink of -1400 % from a held-out gap of 0.16 sigma beyond noise).
    """
    sh = diag.shrink
    if not math.isfinite(sh.fraction):
        return False
    if diag.attribution.partial:
        return True
    return not sh.p_before >= diag.settings.get("alpha", 0.05)


def _how_far(diag) -> str:
    sh, att = diag.shrink, diag.attribution
    if sh.n_heldout == 0:
        return ("Not checked: the measurement file has no held-out observables (role = "
                "\"validate\"), so how far the gap shrinks cannot be tested.")
    n = f"{sh.n_heldout} held-out observable component{'s' if sh.n_heldout != 1 else ''}"
    added = (" once " + " and ".join(e.effect.replace("_", " ") for e in att.selected)
             + " is added" if att.verdict == "attributed" else " after recalibration alone")
    if _heldout_gap(diag):
        lo, hi = sh.fraction_interval
        text = f"On the {n}, the gap beyond noise shrinks by {100 * sh.fraction:.0f} %{added}"
        if math.isfinite(lo) and math.isfinite(hi):
            text += f" (90 % interval {100 * lo:.0f} to {100 * hi:.0f} %)"
        return text + "."
    state = ("stay within noise" if sh.after_excess == 0 else
             f"depart by {sh.after:.1f}× the noise")
    if sh.n_heldout == 1:
        state = state.replace("stay", "stays").replace("depart", "departs")
    return (f"The {n} showed no gap beyond noise before, so there is no gap to shrink; "
            f"{'it' if sh.n_heldout == 1 else 'they'} {state}{added}.")


def _recalibration(diag) -> str:
    rec = diag.recalibration()
    if not rec:
        return "No parameter was recalibrated."
    parts, pinned = [], []
    for name, r in rec.items():
        words, f, u = _PARAMETER_WORDS.get(name, (name.replace("_", " "), 1.0, r["unit"]))
        unit = f" {u}" if u else ""
        parts.append(f"{words} {_num(r['value'] * f)}{unit} (was {_num(r['base'] * f)}{unit})")
        if r["at_bound"]:
            lo, hi = r["bounds"]
            at = lo if lo is not None and abs(r["value"] - lo) <= abs(r["value"] - (hi or math.inf)) \
                else hi
            pinned.append(f"{words} stopped at its physical bound {_num(at * f)}{unit}: the "
                          "data would take it further, so the model misses something "
                          "recalibration cannot absorb")
    return "Recalibrated: " + "; ".join(parts) + "." + "".join(f" {p}." for p in pinned)


def _next(diag) -> str:
    if not diag.next:
        return "No further measurement is needed to tell the candidates apart."
    n = diag.next[0]
    a, b = (x.replace("_", " ") for x in n.separates)
    status = "Measure again" if n.measured else "Measure"
    cond = conditions_text(n.conditions)
    cond = f" ({cond})" if cond else ""
    if not n.separation >= _WITHIN_NOISE and diag.attribution.verdict == "none":
        return ("Nothing further is needed: recalibration alone closes the gap, and no "
                "measurement of the design would tell an effect apart from it.")
    if not n.separation >= _WITHIN_NOISE:
        return (f"No measurement of the design tells the two leading explanations, {a} and "
                f"{b}, apart: the best, {n.observable.replace('_', ' ')}{cond}, puts them only "
                f"{n.separation:.1f}× the noise apart; a measurement of another kind is needed.")
    return (f"{status} {n.observable.replace('_', ' ')}{cond}: the two leading "
            f"explanations, {a} and {b}, predict it {n.separation:.1f}× the noise apart, so it "
            "tells them apart.")


def _where_rows(ranked, sigma: dict) -> list[dict]:
    """The rows of :attr:`Answer.where` from the where-table's ranked rows; ``sigma`` maps
    (observable, component) to the measurement's own uncertainty. Lengths of one kind are
    shown in one unit, the one of its largest value (bed heights of 20 layers all in mm).

    Examples
    --------
    >>> row = dict(observable="h", component="value", unit="m", kind="bed_height", z=0.5,
    ...            sigma=1e-5, role="calibrate")
    >>> rows = _where_rows([dict(row, real=5.08e-4, simulated=5.1e-4),
    ...                     dict(row, observable="h2", real=1.245e-3, simulated=1.25e-3)], {})
    >>> [r["measured"] for r in rows]
    ['0.508 ± 0.01 mm', '1.25 ± 0.01 mm']
    """
    scale: dict[str, float] = {}
    for r in ranked:
        if r["unit"] == "m" and math.isfinite(r["real"]):
            scale[r["kind"]] = max(scale.get(r["kind"], 0.0), abs(r["real"]))
    rows = []
    for r in ranked:
        s = sigma.get((r["observable"], r["component"]), r["sigma"])
        like = scale.get(r["kind"], r["real"])
        rows.append({"what": _observable_words(r),
                     "measured": quantity_text(r["real"], r["unit"], r["kind"], sigma=s,
                                               like=like, resolution=s),
                     "simulated": quantity_text(r["simulated"], r["unit"], r["kind"],
                                                like=like, resolution=s),
                     "gap": _gap_words(r), "z": r["z"],
                     "role": "calibration" if r["role"] == "calibrate" else "held out"})
    return rows


def answer(diag) -> Answer:
    """The diagnosis in plain words and natural units (see :class:`Answer`)."""
    # the measurement's own uncertainty (the where rows' sigma adds the simulation's)
    sigma = {(c["observable"], c["component"]): c["sigma"] for c in diag.shrink.components}
    rows = _where_rows(diag.where.ranked(), sigma)
    return Answer(_headline(diag), rows, _which(diag), _how_far(diag), _recalibration(diag),
                  _next(diag), gap_rows(diag))


def answer_lines(diag, *, n_where: int = 5, caveat: str | None = None) -> list[str]:
    """The CLI's default output: the answer, one statement per line (``caveat``: why the
    answer is not to be trusted, said first)."""
    a = answer(diag)
    head = a.headline if caveat is None else f"NOT TO BE TRUSTED: {caveat}. {a.headline}"
    out = [head, "", "Where the simulation misses the measurements (largest first):"]
    width = max((len(r["what"]) for r in a.where[:n_where]), default=0)
    for r in a.where[:n_where]:
        out.append(f"  {r['what']:<{width}}  measured {r['measured']}, simulated "
                   f"{r['simulated']}: {r['gap']}")
    if len(a.where) > n_where:
        out.append(f"  ... and {len(a.where) - n_where} more in the report")
    out += ["", "Which effect: " + a.which, "How far: " + a.how_far, a.recalibration,
            "What next: " + a.next[:1].lower() + a.next[1:]]
    return out


def compact_answer(diag, caveat: str | None = None) -> dict:
    """The one-line JSON answer of ``bedstruct diagnose --json``.

    Keys: ``verdict``; ``partial`` (an attribution that leaves part of the held-out gap,
    :attr:`~bedstruct.diagnose.attribution.Attribution.partial`); ``effect`` (name, ``None``
    unless attributed; a pair joined by ``+``); ``magnitude`` of the (first) effect
    (``value``, ``interval``, ``unit``, ``name``, or ``None``); ``magnitudes``, one per
    attributed effect (each also with its ``effect``; empty unless attributed); ``shrink`` (``value`` and its
    90 % ``interval`` as fractions, ``None`` where the held-out observables showed no gap
    beyond noise before (their chi-square test at the diagnosis' ``alpha``), with
    ``n_heldout`` and the p-value of that gap, ``p_heldout_gap_before``); ``where``
    (the three largest gaps: ``observable``, ``component``, ``measured``, ``simulated``,
    ``unit``, ``z``); ``at_bound`` (recalibrated parameters that ended on a bound); with
    ``caveat`` (why the answer is not to be trusted) also ``trusted`` (false) and ``caveat``.
    """
    att, sh = diag.attribution, diag.shrink

    def fin(v):
        """A finite value to six significant digits (no float noise), else ``None``."""
        return float(f"{v:.6g}") if v is not None and np.isfinite(v) else None

    chosen = tuple(att.selected) if att.verdict == "attributed" else ()

    def magnitude(sel):
        eff = diag.fingerprints[sel.effect].effect
        return {"effect": sel.effect, "name": eff.magnitude, "value": fin(sel.magnitude),
                "interval": [fin(v) for v in sel.interval], "unit": eff.unit}
    mags = [magnitude(sel) for sel in chosen]
    top = chosen[0] if chosen else None
    mag = {k: v for k, v in mags[0].items() if k != "effect"} if mags else None
    gap = _heldout_gap(diag)
    shrink = {"value": fin(sh.fraction) if gap else None,
              "interval": [fin(v) if gap else None for v in sh.fraction_interval],
              "n_heldout": sh.n_heldout, "p_heldout_gap_before": fin(sh.p_before)}
    where = [{"observable": r["observable"], "component": r["component"],
              "measured": fin(r["real"]), "simulated": fin(r["simulated"]), "unit": r["unit"],
              "z": fin(round(r["z"], 2))} for r in diag.where.ranked(3)]
    if mag is not None:
        mag["value"] = fin(mag["value"])
    out = {"verdict": att.verdict, "partial": bool(att.partial),
           "effect": "+".join(e.effect for e in att.selected) if top is not None else None,
           "magnitude": mag, "magnitudes": mags, "shrink": shrink, "where": where,
           "at_bound": [k for k, r in diag.recalibration().items() if r["at_bound"]]}
    if caveat is not None:
        out.update(trusted=False, caveat=caveat)
    return out
