"""The values of one observable from its source: inline, replicate readings, a CSV, images.

:func:`measurement_from_dict <bedstruct.diagnose.measurement_io.measurement_from_dict>`
takes an observable's values from exactly one source key of its ``[[observable]]``
table. :func:`_source_values` reads that source and returns the values in the file's
unit, with the standard errors the source itself gives (replicates, time series,
tool-force series) and the replicate readings:

* ``value``: the numbers as written;
* ``replicates``: one row per replicate reading of all components; the mean, and its
  standard error at the one-sided 84 % upper confidence bound;
* ``csv``: a time series reduced to window means (``dynamic_angle_series``), a
  cumulative size distribution read at the percentiles (``psd``, converted to m here),
  or the horizontal and vertical tool forces over a stroke (``tool_force_ratio``);
* ``image`` / ``images``: the angle read by the image operator from one image, or the
  window means of a series of images over the stroke (deg).

Each raises a :class:`~bedstruct.errors.ConfigError` that names where in the file it is,
the key and what was expected; every step that changes the numbers is noted in
``conversions``.

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .measurement_parse import (_SERIES_NOTE, _convert, _err, _float_array, _image_angle, _number,
                                _read_csv, _string, _table, _windowed)
from .replicates import variance_upper_bound

__all__: list[str] = []


def _check_coverage(t, windows, dur, where: str, name: str) -> None:
    """Every window inside the series' times, within one sample spacing (a series in seconds
    read as stroke fractions ends early and would be averaged over part of a window)."""
    ts = np.unique(t)
    spacing = float(np.median(np.diff(ts))) if ts.size > 1 else 0.0
    tol = spacing + 1e-9
    for t0, t1 in np.atleast_2d(np.asarray(windows, float)):
        if ts[0] <= t0 + tol and ts[-1] >= t1 - tol:
            continue
        how = "times / stroke_duration" if dur is not None else "times"
        hint = ("" if dur is not None else
                "; are the times in seconds? give stroke_duration (s) to read them as "
                "fractions of the stroke")
        raise _err(where, f"key 'csv': {name}: its {how} run from {ts[0]:g} to {ts[-1]:g} "
                          f"(stroke fractions), so they do not cover window [{t0:g}, {t1:g}]"
                          f"{hint}")


def _check_samples(t, y, unit: str, where: str, name: str, column: str) -> None:
    """Every finite angle sample of a series between 0 and 90 deg (a sign or unit mistake
    otherwise; a window mean could hide it)."""
    from .measurements import _UNIT
    dim, factor = _UNIT.get(unit, ("", 1.0))
    if dim != "angle":
        return   # the unit's own error comes when the values are converted
    deg = np.asarray(y, float) * factor
    bad = np.flatnonzero(np.isfinite(deg) & ((deg < 0.0) | (deg > 90.0)))
    if bad.size:
        i = int(bad[0])
        raise _err(where, f"key 'csv': {name}: column {column!r} holds {y[i]:g} {unit} at time "
                          f"{t[i]:g} ({bad.size} sample(s) outside 0..90 deg); a heap's angle "
                          f"lies in 0..90 deg")


def _source_values(d: Mapping[str, Any], src: str, kind: str, unit: str, windows, percentiles,
                   *, base_dir: Path, where: str, conversions: list[str],
                   check_range: bool = True):
    """The values of an observable from its source key ``src`` of table ``d``.

    ``check_range`` also checks each sample of an angle series (0 to 90 deg).

    Returns
    -------
    values : (n,) ndarray
        In the file's unit; a ``psd`` CSV's sizes already in m, image angles in deg.
    sem : (n,) ndarray or None
        Standard errors the source gives (file's unit), or None.
    replicates : (R, n) ndarray or None
        The replicate readings (file's unit), or None.
    """
    sem = replicates = None
    # components expected from the other keys (to check replicates' layout against)
    n_expected = (len(windows) if windows is not None else len(percentiles) if percentiles is not None
                  else None)
    from_image = src in ("image", "images")
    if src == "value":
        values = _float_array(d["value"], where, "value")
    elif src == "replicates":
        raw = d["replicates"]
        if isinstance(raw, (list, tuple)) and raw and all(isinstance(r, (list, tuple)) for r in raw):
            rep = _table(raw, where, "replicates", row_name="replicate")
        elif isinstance(raw, (list, tuple)) and raw and any(isinstance(r, (list, tuple)) for r in raw):
            raise _err(where, "key 'replicates': mixes numbers and lists; give a flat list (readings "
                              "of one component) or a list of lists (one list per replicate)")
        else:
            rep = _float_array(raw, where, "replicates")[:, None]
        if rep.shape[0] < 2:
            raise _err(where, "key 'replicates': expected at least 2 replicate readings "
                              f"(one row per replicate); got {rep.shape[0]}")
        if n_expected is not None and rep.shape[1] != n_expected:
            what = "windows" if windows is not None else "percentiles"
            if rep.shape[1] == 1:
                raise _err(where, f"key 'replicates': a flat list holds the readings of one "
                                  f"component, but the {n_expected} {what} need one list per "
                                  f"replicate, each of {n_expected} values: [[...], [...], ...]")
            if rep.shape[0] == n_expected:
                raise _err(where, f"key 'replicates': {rep.shape[0]} rows of {rep.shape[1]} values, "
                                  f"but the {n_expected} {what} need rows of {n_expected}: the layout "
                                  f"looks transposed. Each row is one replicate reading of all "
                                  f"components, e.g. [[d10, d50, d90], [d10, d50, d90], ...]")
            raise _err(where, f"key 'replicates': rows of {rep.shape[1]} values, but the "
                              f"{n_expected} {what} need {n_expected} per row (one row per replicate)")
        replicates = rep
        values = rep.mean(axis=0)
        # a standard error from a few readings is itself uncertain: taken at the same upper
        # confidence bound as the simulation's run scatter (an understated one makes a gap)
        bound = float(np.sqrt(variance_upper_bound(rep.shape[0] - 1)))
        sem = rep.std(axis=0, ddof=1) / math.sqrt(rep.shape[0]) * bound
        conversions.append(f"uncertainty: the standard error of {rep.shape[0]} replicates at its "
                           f"one-sided 84 % upper confidence bound (x{bound:.2f})")
    elif src == "csv":
        if kind not in ("dynamic_angle_series", "psd", "tool_force_ratio"):
            raise _err(where, f"key 'csv': a CSV is read for dynamic_angle_series, psd and "
                              f"tool_force_ratio; a {kind} takes 'value' or 'replicates'")
        path = base_dir / _string(d["csv"], where, "csv")
        names, data = _read_csv(path, where)
        cols = d.get("columns", ["force_x", "force_z"] if kind == "tool_force_ratio" else names[:2])
        if not isinstance(cols, (list, tuple)) or len(cols) != 2 or not all(isinstance(c, str) for c in cols):
            raise _err(where, f"key 'columns': expected two column names [x, y]; got {cols!r}")
        for c in cols:
            if c not in names:
                raise _err(where, f"key 'columns': column {c!r} not in {path.name} header {names}")
        x, y = data[:, names.index(cols[0])], data[:, names.index(cols[1])]
        if kind == "dynamic_angle_series":
            dur = d.get("stroke_duration")
            if dur is not None:
                dur = _number(dur, where, "stroke_duration", positive=True, unit="(s)")
            if not np.all(np.isfinite(x)):
                row = int(np.flatnonzero(~np.isfinite(x))[0]) + 2
                raise _err(where, f"key 'csv': {path.name}: time column {cols[0]!r} holds "
                                  f"{x[row - 2]} on line {row}; every sample needs its time")
            t = x / dur if dur is not None else x
            if np.max(t) > 1.0 + 1e-9:
                raise _err(where, "key 'stroke_duration': times exceed one stroke; give "
                                  "stroke_duration (s) or times as stroke fractions")
            _check_coverage(t, windows, dur, where, path.name)
            if check_range:
                _check_samples(t, y, unit, where, path.name, cols[1])
            values, sem = _windowed(t, y, windows, where, "csv")
            conversions.append(_SERIES_NOTE)
            n_missing = int(np.sum(~np.isfinite(y)))
            if n_missing:
                conversions.append(f"csv {path.name}: {n_missing} sample(s) without an angle "
                                   f"(NaN: no heap to read) left out of the window means")
        elif kind == "psd":
            from .observables import psd_percentiles_from_cumulative
            x_conv, note = _convert(x, unit, kind, where)
            if note:
                conversions.append(note)
            yy = np.asarray(y, float)
            if not np.all(np.isfinite(yy)) or np.any(yy < 0):
                raise _err(where, f"key 'csv': {path.name}: cumulative column {cols[1]!r} must be "
                                  f"finite and >= 0 (% passing)")
            if np.max(yy) <= 1.0:
                yy = yy * 100.0
                conversions.append(f"csv {path.name}: cumulative column {cols[1]!r} given as "
                                   f"fractions (max <= 1) -> percent (x100)")
            if np.max(yy) > 100.0 + 1e-6:
                raise _err(where, f"key 'csv': {path.name}: cumulative column {cols[1]!r} exceeds "
                                  f"100 % (max {np.max(yy):g}); expected % passing (0..100)")
            if percentiles.min() < yy.min() or percentiles.max() > yy.max():
                raise _err(where, f"key 'csv': {path.name}: the cumulative curve covers "
                                  f"{yy.min():g}..{yy.max():g} %, not the percentiles "
                                  f"{percentiles.tolist()} (no extrapolation)")
            try:
                values = psd_percentiles_from_cumulative(x_conv, yy, percentiles)
            except ValueError as exc:
                raise _err(where, f"key 'csv': {path.name}: {exc}") from None
        else:  # tool_force_ratio: columns horizontal, vertical load over the stroke
            from .observables import tool_force_ratio
            if unit not in ("1", ""):
                raise _err(where, f"key 'unit': a tool_force_ratio read from a CSV is the ratio "
                                  f"of its two force columns, dimensionless: unit {unit!r} does "
                                  f"not apply; leave 'unit' out (or give '1')")
            try:
                ratio, se = tool_force_ratio(x, y)
            except ValueError as exc:
                raise _err(where, f"key 'csv': {path.name}: {exc}") from None
            values = np.array([ratio])
            sem = np.array([se]) if math.isfinite(se) else None
    elif from_image:
        if kind not in ("static_angle", "dynamic_angle_series"):
            raise _err(where, f"key {src!r}: images are supported for angle kinds only")
        if "pixel_size" not in d:
            raise _err(where, "key 'pixel_size': image observables need the pixel size (m)")
        _number(d["pixel_size"], where, "pixel_size", positive=True, unit="(m)")
        powder = d.get("powder", "auto")
        if powder not in ("bright", "dark", "auto"):
            raise _err(where, f"key 'powder': expected 'bright' (powder brighter than the "
                              f"background), 'dark' or 'auto'; got {powder!r}")
        flanks = d.get("flanks", "both")
        if flanks not in ("both", "left", "right"):
            raise _err(where, f"key 'flanks': expected 'both', 'left' or 'right'; got {flanks!r}")
        if src == "image":
            fname = _string(d["image"], where, "image")
            fit = _image_angle(base_dir / fname, d, where, "image", powder, flanks)
            values = np.asarray([fit.angle])
            fits = [fit]
        else:
            imgs = d["images"]
            if not isinstance(imgs, Mapping) or "files" not in imgs or "times" not in imgs:
                raise _err(where, "key 'images': expected {files = [...], times = [...]} "
                                  "(times as stroke fractions)")
            extra = set(imgs) - {"files", "times"}
            if extra:
                raise _err(where, f"key 'images.{sorted(extra)[0]}': unknown; expected files, times")
            files = imgs["files"]
            if not isinstance(files, list) or not files or not all(isinstance(f, str) for f in files):
                raise _err(where, f"key 'images.files': expected a list of file names; got {files!r}")
            times = _float_array(imgs["times"], where, "images.times")
            if len(times) != len(files):
                raise _err(where, f"key 'images.times': {len(times)} times for {len(files)} files "
                                  f"(one stroke fraction per image)")
            if np.any(times < 0) or np.any(times > 1):
                raise _err(where, "key 'images.times': expected stroke fractions in [0, 1]")
            fits = [_image_angle(base_dir / f, d, where, f"images.files[{i}]", powder, flanks)
                    for i, f in enumerate(files)]
            values, sem = _windowed(times, np.asarray([f.angle for f in fits]), windows, where,
                                    "images")
            conversions.append(_SERIES_NOTE)
        pols = sorted({f.powder for f in fits})
        sides = sorted({"+".join(f.flanks) for f in fits})
        conversions.append(f"{src}: angle read in deg from {len(fits)} image(s) (powder "
                           f"{'/'.join(pols)}{', auto-detected' if powder == 'auto' else ''}; "
                           f"flank(s) {'/'.join(sides)}); the unit applies to the stated "
                           f"uncertainty only")
    return values, sem, replicates
