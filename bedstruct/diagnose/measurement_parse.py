"""Parsers of the pieces of one ``[[observable]]`` table of a measurement file.

The building blocks of :func:`~bedstruct.diagnose.measurement_io.measurement_from_dict`:
typed keys (numbers, flat lists, tables of rows, strings), unit conversion to the
kind's canonical unit and the check against its plausible range (naming the unit
the values would fit), the ``conditions`` table, and the external sources of
values: a CSV file, a time series reduced to window means (with their
batch-means standard errors) and the angle read from an image by the image
operator (:mod:`bedstruct.diagnose.observables_image`). Each raises a
:class:`~bedstruct.errors.ConfigError` that names where in the file it is
(``where``), the key and what was expected.

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import ConfigError
from .measurements import (_DIM, _KNOWN_CONDITIONS, _UNIT, KINDS, NOT_PERCENT, PLAUSIBLE,
                           PLAUSIBLE_CONDITIONS, PLAUSIBLE_SETUP, Conditions, normalise_region)


def _err(where: str, msg: str) -> ConfigError:
    return ConfigError(f"{where}: {msg}")


def _is_number(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def _number(v, where: str, key: str, *, positive: bool = False, unit: str = "") -> float:
    """A plain number from the file (not a string, not a boolean)."""
    u = f" {unit}" if unit else ""
    if not _is_number(v):
        hint = ((f" (write the number alone, in {unit.strip('()')})" if unit else
                 " (write the number alone)") if isinstance(v, str) else "")
        raise _err(where, f"key {key!r}: expected a number{u}; got {v!r}{hint}")
    x = float(v)
    if not math.isfinite(x) or (positive and not x > 0):
        raise _err(where, f"key {key!r}: expected a {'positive' if positive else 'finite'} "
                          f"number{u}; got {v!r}")
    return x


def _float_array(value, where: str, key: str) -> np.ndarray:
    """A number or a flat list of numbers."""
    if _is_number(value):
        return np.array([float(value)])
    if not isinstance(value, (list, tuple, np.ndarray)):
        raise _err(where, f"key {key!r}: expected a number or a list of numbers; got {value!r}")
    if len(value) == 0:
        raise _err(where, f"key {key!r}: expected a number or a list of numbers; got an empty "
                          f"list")
    for i, x in enumerate(value):
        if isinstance(x, (list, tuple)):
            raise _err(where, f"key {key!r}: expected a flat list of numbers; element {i + 1} is "
                              f"a list {x!r}")
        if not _is_number(x):
            raise _err(where, f"key {key!r}: expected a number or a list of numbers; element "
                              f"{i + 1} is {x!r}")
    return np.asarray(value, dtype=float).reshape(-1)


def _table(value, where: str, key: str, *, row_name: str, width: int | None = None) -> np.ndarray:
    """A rectangular list of lists of numbers (rows of equal length)."""
    if not isinstance(value, (list, tuple)) or not value:
        raise _err(where, f"key {key!r}: expected a list of {row_name}s (lists of numbers); got {value!r}")
    rows = []
    for i, row in enumerate(value):
        if not isinstance(row, (list, tuple)):
            raise _err(where, f"key {key!r}: {row_name} {i + 1} is {row!r}, not a list of numbers")
        for x in row:
            if not _is_number(x):
                raise _err(where, f"key {key!r}: {row_name} {i + 1} holds {x!r}, not a number")
        if width is not None and len(row) != width:
            raise _err(where, f"key {key!r}: {row_name} {i + 1} is {list(row)!r}; expected "
                              f"{width} numbers")
        if rows and len(row) != len(rows[0]):
            raise _err(where, f"key {key!r}: {row_name} {i + 1} has {len(row)} values but "
                              f"{row_name} 1 has {len(rows[0])}: every {row_name} needs the same "
                              f"number of values")
        rows.append([float(x) for x in row])
    return np.asarray(rows, dtype=float)


def _string(v, where: str, key: str) -> str:
    if not isinstance(v, str):
        raise _err(where, f"key {key!r}: expected a string; got {v!r}")
    return v


def _convert(values, unit: str, kind: str, where: str) -> tuple[np.ndarray, str | None]:
    canonical = KINDS[kind]
    if unit not in _UNIT:
        raise _err(where, f"key 'unit': unknown unit {unit!r}; expected one of {sorted(_UNIT)}")
    dim, factor = _UNIT[unit]
    if dim != _DIM[canonical]:
        raise _err(where, f"key 'unit': {unit!r} is a {dim} unit but kind {kind!r} needs "
                          f"a {_DIM[canonical]} unit (canonical {canonical!r})")
    if unit == "%" and kind in NOT_PERCENT:
        raise _err(where, f"key 'unit': a {kind} is a count per particle, not a fraction: '%' "
                          f"does not apply; give unit = '1' (or none)")
    arr = np.asarray(values, dtype=float) * factor
    note = None if factor == 1.0 else f"{unit} -> {canonical} (x{factor:g})"
    return arr, note


_UNIT_CHOICES = {"angle": ("deg", "rad"), "length": ("m", "mm", "um", "nm"), "fraction": ("1", "%")}


def _units_that_fit(raw, lo: float, hi: float, units, *, closed: bool = False) -> list[str]:
    """The units of ``units`` (pairs: name, factor to the canonical unit) in which every number
    of ``raw`` would lie in the plausible range (``lo < x < hi``, or ``lo <= x <= hi`` when
    ``closed``): the unit an implausible number was most likely meant in."""
    raw = np.asarray(raw, dtype=float)
    fits = []
    for u, factor in units:
        x = raw * factor
        if np.all((x >= lo) & (x <= hi) if closed else (x > lo) & (x < hi)):
            fits.append(u)
    return fits


def _check_plausible(values, kind: str, unit: str, stated_unit: bool, where: str, key: str,
                     file_values=None) -> None:
    """Values (canonical unit) inside the kind's plausible range, else an error with the likely unit."""
    if kind not in PLAUSIBLE:
        return
    lo, hi = PLAUSIBLE[kind]
    v = np.asarray(values, dtype=float)
    bad = ~((v > lo) & (v < hi))
    if not np.any(bad):
        return
    canonical = KINDS[kind]
    fits = _units_that_fit(file_values if file_values is not None else values, lo, hi,
                           [(u, _UNIT[u][1]) for u in _UNIT_CHOICES[_DIM[canonical]]
                            if u != unit and not (u == "%" and kind in NOT_PERCENT)])
    shown = ", ".join(f"{x:g}" for x in v[bad][:3])
    u = "" if canonical == "1" else f" {canonical}"
    how = f"unit {unit!r}" if stated_unit else f"no 'unit' given, read in {unit!r}"
    low = "0 <= value" if -1e-9 < lo <= 0 else f"{lo:g} < value"
    msg = f"key {key!r}: implausible {kind} {shown}{u} ({how}); expected {low} < {hi:g}{u}"
    if fits:
        msg += f"; the values fit unit = {fits[0]!r}: is that their unit?"
    elif np.any(v <= 0) and lo >= 0:
        msg += "; it must be positive"
    raise _err(where, msg)


def _read_csv(path: Path, where: str, key: str = "csv") -> tuple[list[str], np.ndarray]:
    if not path.is_file():
        raise _err(where, f"key {key!r}: file not found: {path}")
    try:
        with open(path, encoding="utf-8") as fh:
            header = fh.readline().strip()
        names = [h.strip() for h in header.split(",")]
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2, encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise _err(where, f"key {key!r}: {path} is not UTF-8 text (byte {exc.object[exc.start]:#x} "
                          f"at position {exc.start}); save it as UTF-8") from None
    except ValueError as exc:
        raise _err(where, f"key {key!r}: {path} is not a numeric CSV with a header row ({exc})") from None
    if data.size == 0:
        raise _err(where, f"key {key!r}: {path} holds no data rows under its header")
    if data.shape[1] != len(names):
        raise _err(where, f"key {key!r}: {path} has {data.shape[1]} columns but header names {names}")
    if len(names) < 2:
        raise _err(where, f"key {key!r}: {path} has {len(names)} column ({names}); expected at least "
                          f"two (x and y, picked by 'columns')")
    return names, data


def _conditions(d: Mapping[str, Any] | None, where: str, conversions: list | None = None
                ) -> Conditions:
    """An observable's ``conditions`` table (speeds and the box width may carry a unit,
    e.g. ``"2.54 cm/s"``; a plain number is m/s or m); unit conversions are appended to
    ``conversions``."""
    if d is None:
        return Conditions()
    if not isinstance(d, Mapping):
        raise _err(where, f"key 'conditions': expected a table; got {d!r}")
    unknown = set(d) - _KNOWN_CONDITIONS
    if unknown:
        raise _err(where, f"key 'conditions.{sorted(unknown)[0]}': unknown condition; known: "
                          f"{sorted(_KNOWN_CONDITIONS)}")
    speed = d.get("speed")
    conv: list[str] = conversions if conversions is not None else []
    if speed is not None:
        plain = _is_number(speed)
        speed = _number(speed, where, "conditions.speed", positive=True, unit="(m/s)") \
            if plain else \
            _scalar_quantity(speed, where, "conditions.speed", _SPEED_UNITS, what="speed",
                             conversions=conv)
        _check_condition(speed, "speed", where, "conditions.speed", plain)
    layer = d.get("layer")
    if layer is not None and (isinstance(layer, bool) or not isinstance(layer, int) or layer < 1):
        raise _err(where, f"key 'conditions.layer': expected a positive integer (1-based); got {layer!r}")
    region = d.get("region")
    if region is not None:
        try:
            region = normalise_region(region)
        except ConfigError as exc:
            raise _err(where, f"key 'conditions.region': {exc}") from None
    tw = d.get("time_window")
    if tw is not None:
        if not isinstance(tw, (list, tuple)) or len(tw) != 2 or not all(_is_number(x) for x in tw) \
                or not (0.0 <= float(tw[0]) < float(tw[1]) <= 1.0):
            raise _err(where, f"key 'conditions.time_window': expected [t0, t1] with "
                              f"0 <= t0 < t1 <= 1 (stroke fractions); got {tw!r}")
        tw = (float(tw[0]), float(tw[1]))
    extra = []
    for k in ("stage", "relative_humidity", "rest_time", "box_width"):
        if k in d:
            v = d[k]
            if k == "stage":
                if v not in ("before", "after"):
                    raise _err(where, f"key 'conditions.stage': expected 'before' or 'after'; got {v!r}")
            else:
                plain = _is_number(v)
                units, what, si = {"box_width": (_LENGTH_UNITS, "length", "(m)"),
                                   "rest_time": (_TIME_UNITS, "time", "(s)"),
                                   "relative_humidity": (_FRACTION_UNITS, "fraction",
                                                         "(a fraction 0-1)")}[k]
                v = _number(v, where, f"conditions.{k}", unit=si) if plain else \
                    _scalar_quantity(v, where, f"conditions.{k}", units, what=what,
                                     conversions=conv)
                if k == "relative_humidity" and not 0 <= v <= 1:
                    raise _err(where, f"key 'conditions.relative_humidity': expected 0..1 (a "
                                      f"fraction, or a string such as \"45 %\"); got {v:g}")
                if k == "rest_time" and v < 0:
                    raise _err(where, f"key 'conditions.{k}': must be >= 0; got {v}")
                if k == "box_width" and not v > 0:
                    raise _err(where, f"key 'conditions.{k}': must be > 0 (the width of the "
                                      f"box, m); got {v}")
                if k in PLAUSIBLE_CONDITIONS:
                    _check_condition(v, k, where, f"conditions.{k}", plain)
            extra.append((k, v))
    return Conditions(speed, layer, region, tw, tuple(extra))


#: Canonical unit of a condition in :data:`PLAUSIBLE_CONDITIONS` and the units a plain number
#: is most often meant in when it is implausible in the canonical one.
_CONDITION_UNITS = {"speed": ("m/s", (("cm/s", 1e-2), ("mm/s", 1e-3))),
                    "box_width": ("m", (("mm", 1e-3),)), "rest_time": ("s", ()),
                    **{k: ("m", (("mm", 1e-3), ("um", 1e-6))) for k in PLAUSIBLE_SETUP}}


def _natural(v: float, unit: str) -> str:
    """An SI length or speed in the unit a person reads it in (um, mm, m; mm/s, m/s)."""
    if unit == "m" and 0 < abs(v) < 1e-3:
        return f"{v * 1e6:.4g} um"
    if unit == "m" and 0 < abs(v) < 1.0:
        return f"{v * 1e3:.4g} mm"
    if unit == "m/s" and 0 < abs(v) < 0.1:
        return f"{v * 1e3:.4g} mm/s"
    return f"{v:.4g} {unit}"


def _check_condition(v: float, name: str, where: str, key: str, plain: bool) -> None:
    """A condition (SI) inside its plausible range, else an error; a plain number (no unit
    written) that would fit in another unit gets that unit as a hint."""
    lo, hi = PLAUSIBLE_CONDITIONS.get(name) or PLAUSIBLE_SETUP[name]
    if lo <= v <= hi:
        return
    unit, alternatives = _CONDITION_UNITS[name]
    shown = f"{v:g} {unit}" if plain else _natural(v, unit)
    msg = (f"key {key!r}: implausible {name.replace('_', ' ')} {shown}; expected "
           f"{_natural(lo, unit)} to {_natural(hi, unit)}")
    fits = _units_that_fit(v, lo, hi, alternatives, closed=True) if plain else []
    if fits:
        msg += f"; is it in {' or '.join(fits)}? write \"{v:g} {fits[0]}\""
    raise _err(where, msg)


def _windowed(times, series, windows, where, key):
    """Mean and standard error of ``series`` in each window (the series operator)."""
    from .observables import windowed_mean
    try:
        mean, sem = windowed_mean(times, series, windows)
    except ValueError as exc:
        raise _err(where, f"key {key!r}: {exc}") from None
    empty = [w for w, m in zip(np.atleast_2d(np.asarray(windows, float)), mean) if not np.isfinite(m)]
    if empty:   # a measured series: a window without a value is a gap in the file
        raise _err(where, f"key {key!r}: window [{empty[0][0]:g}, {empty[0][1]:g}] holds no "
                          f"finite value")
    return mean, sem


_SERIES_NOTE = ("uncertainty: the window means' standard errors by batch means (10 blocks, "
                "corrected for correlated blocks; fewer than 20 samples: their standard deviation)")


def _image_angle(path: Path, d, where: str, key: str, powder: str, flanks: str):
    from .observables_image import fit_image_angle, read_image
    if not path.is_file():
        raise _err(where, f"key {key!r}: image file not found: {path}")
    try:
        img = read_image(path)
    except Exception as exc:  # noqa: BLE001  (any reader failure: not an image)
        raise _err(where, f"key {key!r}: cannot read {path} as an image ({type(exc).__name__}: "
                          f"{exc})") from None
    try:
        return fit_image_angle(img, pixel_size=d["pixel_size"], powder=powder, flanks=flanks)
    except ValueError as exc:
        raise _err(where, f"key {key!r}: {path}: no angle read from this image: {exc}") from None


def _trials(d: Mapping[str, Any], where: str, role: str):
    """The ``trials`` and ``not_measured`` keys: how many repeated trials the values summarise
    and, per component, how many of them gave no reading (``(None, None)`` when not stated).

    ``not_measured`` is a whole number (every component) or a list of them (one per
    component), each in ``0 .. trials``; it needs ``trials``.
    """
    if "trials" not in d:
        if "not_measured" in d:
            raise _err(where, "key 'not_measured': needs 'trials' (how many trials were made)")
        return None, None
    if role == "candidate":
        raise _err(where, "key 'trials': a candidate (not yet measured) observable has no trials")
    t = d["trials"]
    if not _is_number(t) or not math.isfinite(float(t)) or float(t) != int(t) or int(t) < 1:
        raise _err(where, f"key 'trials': expected a whole number >= 1; got {t!r}")
    trials = int(t)
    raw = d.get("not_measured", 0)
    items = raw if isinstance(raw, (list, tuple)) else [raw]
    if not items or not all(_is_number(k) and math.isfinite(float(k)) and float(k) == int(k)
                            for k in items):
        raise _err(where, f"key 'not_measured': expected a whole number or a list of them (one "
                          f"per component); got {raw!r}")
    counts = np.asarray([int(k) for k in items], dtype=int)
    if np.any(counts < 0) or np.any(counts > trials):
        raise _err(where, f"key 'not_measured': expected counts between 0 and trials = {trials} "
                          f"(trials that gave no reading); got {raw!r}")
    return trials, (counts if isinstance(raw, (list, tuple)) else int(counts[0]))


# --------------------------------------------------------------------------- set-up

_SPEED_UNITS = {"m/s": 1.0, "cm/s": 1e-2, "mm/s": 1e-3, "um/s": 1e-6, "µm/s": 1e-6,
                "μm/s": 1e-6}
_LENGTH_UNITS = {u: f for u, (dim, f) in _UNIT.items() if dim == "length"}
_TIME_UNITS = {"s": 1.0, "min": 60.0, "h": 3600.0, "d": 86400.0}
_FRACTION_UNITS = {"%": 1e-2, "1": 1.0}
#: Per kind of quantity: its SI unit, an example, and whether it must be above zero.
_QUANTITY = {"length": ("m", "18.9 mm", True), "speed": ("m/s", "2.54 cm/s", True),
             "time": ("s", "10 min", False), "fraction": ("1", "45 %", False)}
_SETUP_KEYS = ("psd", "layers", "layer_thickness", "blade_speed", "platform_length",
               "platform_width", "side_walls", "wall_distance")
#: The most layers a file's set-up may ask for.
MAX_LAYERS = 50


def _quantity(v, where: str, key: str, units: Mapping[str, float], *, what: str,
              conversions: list) -> np.ndarray:
    """Numbers with their unit, in SI: ``"18.9 mm"``, a list of such strings, or
    ``{value = 18.9, unit = "mm"}`` (``value`` a number or a list of numbers)."""
    si, example, positive = _QUANTITY[what]
    example = f'"{example}"'
    expected = (f"a {what} with its unit, e.g. {example} or {{value = ..., unit = ...}} "
                f"(units: {', '.join(units)})")
    if isinstance(v, Mapping):
        extra = set(v) - {"value", "unit"}
        if extra or "value" not in v or "unit" not in v:
            raise _err(where, f"key {key!r}: expected {{value = ..., unit = ...}}; got {dict(v)!r}")
        unit = v["unit"]
        nums = _float_array(v["value"], where, f"{key}.value")
        items = [(x, unit) for x in nums]
    else:
        raw = v if isinstance(v, (list, tuple)) else [v]
        if not raw:
            raise _err(where, f"key {key!r}: expected {expected}; got an empty list")
        items = []
        for x in raw:
            if _is_number(x):
                raise _err(where, f"key {key!r}: {x!r} has no unit; expected {expected}")
            if not isinstance(x, str) or len(x.split()) != 2:
                raise _err(where, f"key {key!r}: expected {expected}; got {x!r}")
            num, unit = x.split()
            try:
                items.append((float(num), unit))
            except ValueError:
                raise _err(where, f"key {key!r}: {num!r} in {x!r} is not a number; expected "
                                  f"{expected}") from None
    out = []
    for x, unit in items:
        if unit not in units:
            raise _err(where, f"key {key!r}: unknown {what} unit {unit!r}; expected one of "
                              f"{', '.join(units)}")
        if not (math.isfinite(x) and (x > 0 if positive else x >= 0)):
            raise _err(where, f"key {key!r}: expected a {'positive' if positive else 'non-negative'} "
                              f"{what}; got {x:g} {unit}")
        f = units[unit]
        # a decimal prefix divides by its (exact) reciprocal: "100 um" is 1e-4 m exactly
        out.append(x / round(1.0 / f) if f < 1.0 and float(round(1.0 / f)) * f == 1.0 else x * f)
        if f != 1.0:
            note = f"{key}: {unit} -> {si}"
            if note not in conversions:
                conversions.append(note)
    return np.asarray(out, dtype=float)


def _scalar_quantity(v, where, key, units, *, what, conversions) -> float:
    q = _quantity(v, where, key, units, what=what, conversions=conversions)
    if q.size != 1:
        raise _err(where, f"key {key!r}: expected one {what}; got {q.size}")
    return float(q[0])


def _setup_psd(v, where: str, base_dir: Path, conversions: list):
    """``(d10, d50, d90, d_min, d_max)`` (m), its source and, from a file, the table
    ``(diameters, cumulative volume fractions)`` at the size classes' edges (else None)."""
    key = "conditions.psd"
    if not isinstance(v, Mapping):
        raise _err(where, f"key {key!r}: expected a table: {{file = \"psd.csv\", unit = \"um\"}} "
                          f"(columns diameter, fraction) or {{d10 = \"30 um\", d50 = \"52 um\", "
                          f"d90 = \"86 um\"}}; got {v!r}")
    if "file" in v:
        extra = set(v) - {"file", "unit", "columns"}
        if extra:
            raise _err(where, f"key '{key}.{sorted(extra)[0]}': unknown; a size-distribution file "
                              f"takes file, unit, columns")
        if "unit" not in v:
            raise _err(where, f"key '{key}.unit': the unit of the file's diameters (one of "
                              f"{', '.join(_LENGTH_UNITS)})")
        unit = _string(v["unit"], where, f"{key}.unit")
        if unit not in _LENGTH_UNITS:
            raise _err(where, f"key '{key}.unit': unknown length unit {unit!r}; expected one of "
                              f"{', '.join(_LENGTH_UNITS)}")
        path = base_dir / _string(v["file"], where, f"{key}.file")
        names, data = _read_csv(path, where, f"{key}.file")
        cols = v.get("columns", ["diameter", "fraction"])
        if not isinstance(cols, (list, tuple)) or len(cols) != 2 or \
                not all(isinstance(c, str) and c in names for c in cols):
            raise _err(where, f"key '{key}.columns': expected two column names of {path.name}'s "
                              f"header {names} (diameter, volume fraction); got {cols!r}")
        d = data[:, names.index(cols[0])] * _LENGTH_UNITS[unit]
        f = data[:, names.index(cols[1])]
        if d.size < 3 or np.any(~np.isfinite(d)) or np.any(np.diff(d) <= 0) or d[0] <= 0:
            raise _err(where, f"key '{key}.file': {path.name}: column {cols[0]!r} must hold at "
                              f"least 3 increasing positive diameters")
        if np.any(~np.isfinite(f)) or np.any(f < 0) or not f.sum() > 0:
            raise _err(where, f"key '{key}.file': {path.name}: column {cols[1]!r} must hold "
                              f"volume fractions >= 0 (per size class), not all 0")
        from ..analysis import percentile_diameter
        d10, d50, d90 = (float(x) for x in percentile_diameter(d, [0.1, 0.5, 0.9], weights=f))
        # the size classes' outer edges: half a class beyond the smallest and largest diameter
        d_min = max(float(d[0] - 0.5 * (d[1] - d[0])), 0.5 * float(d[0]))
        d_max = float(d[-1] + 0.5 * (d[-1] - d[-2]))
        if unit != "m":
            conversions.append(f"conditions.psd: {path.name} diameters {unit} -> m")
        conversions.append(f"conditions.psd: {path.name}: volume-weighted d10/d50/d90 "
                           f"{d10 * 1e6:.4g}/{d50 * 1e6:.4g}/{d90 * 1e6:.4g} um, sizes "
                           f"{d_min * 1e6:.4g}-{d_max * 1e6:.4g} um")
        # the cumulative volume fraction undersize at the classes' edges (midway between
        # diameters; the outer edges d_min, d_max): the whole distribution, for the engine
        edges = np.concatenate([[d_min], 0.5 * (d[1:] + d[:-1]), [d_max]])
        cum = np.concatenate([[0.0], np.cumsum(f) / f.sum()])
        cum[-1] = 1.0
        table = (tuple(float(x) for x in edges), tuple(float(x) for x in cum))
        source = str(path)
    else:
        extra = set(v) - {"d10", "d50", "d90", "d_min", "d_max", "diameters", "cumulative"}
        if extra:
            raise _err(where, f"key '{key}.{sorted(extra)[0]}': unknown; expected file (a size "
                              f"distribution) or d10, d50, d90 (and optionally d_min, d_max, "
                              f"and the whole distribution as diameters and cumulative)")
        missing = [k for k in ("d10", "d50", "d90") if k not in v]
        if missing:
            raise _err(where, f"key '{key}.{missing[0]}': the percentile form needs d10, d50 "
                              f"and d90 (volume-weighted), e.g. d10 = \"30 um\"")
        q = {k: _scalar_quantity(v[k], where, f"{key}.{k}", _LENGTH_UNITS, what="length",
                                 conversions=conversions)
             for k in v if k not in ("diameters", "cumulative")}
        d10, d50, d90 = q["d10"], q["d50"], q["d90"]
        if not d10 < d50 < d90:
            raise _err(where, f"key {key!r}: expected d10 < d50 < d90; got "
                              f"{', '.join(str(v[k]) for k in ('d10', 'd50', 'd90'))}")
        # default truncation: as wide again as the D10-D90 span's outer parts
        d_min = q.get("d_min", max(d10 - (d50 - d10), 0.5 * d10))
        d_max = q.get("d_max", d90 + (d90 - d50))
        source = "percentiles"
        table = _psd_table(v, where, key, d_min, d_max, conversions)
    if not d_min < d10 < d50 < d90 < d_max:
        raise _err(where, f"key {key!r}: expected d_min < d10 < d50 < d90 < d_max; got "
                          f"{d_min * 1e6:.4g}, {d10 * 1e6:.4g}, {d50 * 1e6:.4g}, {d90 * 1e6:.4g}, "
                          f"{d_max * 1e6:.4g} um")
    return (d10, d50, d90, d_min, d_max), source, table


def _psd_table(v, where: str, key: str, d_min: float, d_max: float, conversions: list):
    """The whole distribution given beside the percentiles (``diameters``: lengths at the
    size classes' edges, ``cumulative``: volume fraction undersize at each), or None."""
    if ("diameters" in v) != ("cumulative" in v):
        raise _err(where, f"key '{key}': the whole distribution needs both diameters and "
                          f"cumulative (volume fraction undersize at each diameter)")
    if "diameters" not in v:
        return None
    d = _quantity(v["diameters"], where, f"{key}.diameters", _LENGTH_UNITS, what="length",
                  conversions=conversions)
    c = np.asarray(v["cumulative"], dtype=float) if isinstance(v["cumulative"], list) else None
    if d.size < 3 or np.any(np.diff(d) <= 0) or d[0] <= 0:
        raise _err(where, f"key '{key}.diameters': expected at least 3 increasing positive "
                          f"diameters")
    if c is None or c.shape != d.shape or np.any(~np.isfinite(c)) or np.any(c < 0) \
            or np.any(c > 1) or np.any(np.diff(c) < 0) or not c[-1] > c[0]:
        raise _err(where, f"key '{key}.cumulative': expected {d.size} non-decreasing volume "
                          f"fractions in [0, 1], one per diameter; got {v['cumulative']!r}")
    if not (math.isclose(d[0], d_min, rel_tol=1e-9) and math.isclose(d[-1], d_max, rel_tol=1e-9)):
        raise _err(where, f"key '{key}': the diameters must span d_min to d_max "
                          f"({d_min * 1e6:.6g}-{d_max * 1e6:.6g} um); got "
                          f"{d[0] * 1e6:.6g}-{d[-1] * 1e6:.6g} um")
    return tuple(float(x) for x in d), tuple(float(x) for x in c)


def _setup(d, where: str, base_dir: Path):
    """The file's set-up (its top-level ``[conditions]`` table), in SI."""
    from .measurements import Setup
    if d is None:
        return Setup(path=where)
    if not isinstance(d, Mapping):
        raise _err(where, f"key 'conditions': expected a table; got {d!r}")
    unknown = set(d) - set(_SETUP_KEYS)
    if unknown:
        raise _err(where, f"key 'conditions.{sorted(unknown)[0]}': unknown condition of the "
                          f"set-up; known: {list(_SETUP_KEYS)} (an observable's own conditions "
                          f"go in its [observable.conditions])")
    conv: list[str] = []
    kw: dict[str, Any] = {}
    if "psd" in d:
        kw["psd"], kw["psd_source"], kw["psd_table"] = _setup_psd(d["psd"], where, base_dir,
                                                                   conv)
    layers = d.get("layers")
    if layers is not None and (isinstance(layers, bool) or not isinstance(layers, int)
                               or not 1 <= layers <= MAX_LAYERS):
        raise _err(where, f"key 'conditions.layers': expected a whole number of layers, 1 to "
                          f"{MAX_LAYERS}; got {layers!r}")
    if "layer_thickness" in d:
        t = _quantity(d["layer_thickness"], where, "conditions.layer_thickness", _LENGTH_UNITS, what="length",
                      conversions=conv)
        if t.size == 1 and layers is not None:
            t = np.full(layers, t[0])
        elif layers is not None and t.size != layers:
            raise _err(where, f"key 'conditions.layer_thickness': {t.size} thicknesses but "
                              f"layers = {layers}; give one thickness (every layer) or one per layer")
        if t.size > MAX_LAYERS:
            raise _err(where, f"key 'conditions.layer_thickness': {t.size} layers; at most "
                              f"{MAX_LAYERS}")
        for x in t:
            _check_condition(float(x), "layer_thickness", where, "conditions.layer_thickness",
                             False)
        kw["layer_thickness"] = tuple(float(x) for x in t)
    elif layers is not None:
        raise _err(where, "key 'conditions.layer_thickness': 'layers' needs the layer thickness "
                          "(one for every layer, e.g. \"100 um\", or a list, one per layer)")
    if "blade_speed" in d:
        kw["blade_speed"] = _scalar_quantity(d["blade_speed"], where, "conditions.blade_speed", _SPEED_UNITS,
                                             what="speed", conversions=conv)
        _check_condition(kw["blade_speed"], "speed", where, "conditions.blade_speed", False)
    for key in ("platform_length", "platform_width", "wall_distance"):
        if key in d:
            kw[key] = _scalar_quantity(d[key], where, f"conditions.{key}", _LENGTH_UNITS, what="length",
                                       conversions=conv)
            _check_condition(kw[key], key, where, f"conditions.{key}", False)
    if "side_walls" in d:
        if not isinstance(d["side_walls"], bool):
            raise _err(where, f"key 'conditions.side_walls': expected true or false; got "
                              f"{d['side_walls']!r}")
        kw["side_walls"] = d["side_walls"]
    if "wall_distance" in kw and kw.get("side_walls") is not True:
        raise _err(where, "key 'conditions.wall_distance': the distance between side walls needs "
                          "side_walls = true")
    return Setup(path=where, conversions=tuple(conv), **kw)
