"""Reading and writing measurement files (TOML plus optional CSV/images).

The file format is documented in ``docs/diagnose.md``; the containers are in
:mod:`bedstruct.diagnose.measurements`, which re-exports the public names of this
module (``load_measurements``, ``write_measurements``, ``measurement_from_dict``).

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import ConfigError
from .measurements import (_DIM, _KNOWN_CONDITIONS, _UNIT, KINDS, ROLES, Conditions, Measurement,
                           MeasurementSet)
from .replicates import variance_upper_bound

__all__ = ["load_measurements", "write_measurements", "measurement_from_dict"]


# --------------------------------------------------------------------------- loading

def _err(where: str, msg: str) -> ConfigError:
    return ConfigError(f"{where}: {msg}")


def _convert(values, unit: str, kind: str, where: str) -> tuple[np.ndarray, str | None]:
    canonical = KINDS[kind]
    if unit not in _UNIT:
        raise _err(where, f"key 'unit': unknown unit {unit!r}; expected one of {sorted(_UNIT)}")
    dim, factor = _UNIT[unit]
    if dim != _DIM[canonical]:
        raise _err(where, f"key 'unit': {unit!r} is a {dim} unit but kind {kind!r} needs "
                          f"a {_DIM[canonical]} unit (canonical {canonical!r})")
    arr = np.asarray(values, dtype=float) * factor
    note = None if factor == 1.0 else f"{unit} -> {canonical} (x{factor:g})"
    return arr, note


def _float_array(value, where: str, key: str) -> np.ndarray:
    try:
        arr = np.atleast_1d(np.asarray(value, dtype=float))
    except (TypeError, ValueError):
        raise _err(where, f"key {key!r}: expected a number or a list of numbers; got {value!r}") from None
    if arr.ndim != 1:
        raise _err(where, f"key {key!r}: expected a flat list; got shape {arr.shape}")
    return arr


def _read_csv(path: Path, where: str) -> tuple[list[str], np.ndarray]:
    if not path.is_file():
        raise _err(where, f"key 'csv': file not found: {path}")
    with open(path, encoding="utf-8") as fh:
        header = fh.readline().strip()
    names = [h.strip() for h in header.split(",")]
    try:
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except ValueError as exc:
        raise _err(where, f"key 'csv': {path} is not a numeric CSV with a header row ({exc})") from None
    if data.shape[1] != len(names):
        raise _err(where, f"key 'csv': {path} has {data.shape[1]} columns but header names {names}")
    return names, data


def _conditions(d: Mapping[str, Any] | None, where: str) -> Conditions:
    if d is None:
        return Conditions()
    if not isinstance(d, Mapping):
        raise _err(where, f"key 'conditions': expected a table; got {d!r}")
    unknown = set(d) - _KNOWN_CONDITIONS
    if unknown:
        raise _err(where, f"key 'conditions.{sorted(unknown)[0]}': unknown condition; known: "
                          f"{sorted(_KNOWN_CONDITIONS)}")
    speed = d.get("speed")
    if speed is not None:
        speed = float(speed)
        if not speed > 0:
            raise _err(where, f"key 'conditions.speed': must be > 0 m/s; got {speed}")
    layer = d.get("layer")
    if layer is not None and (not isinstance(layer, int) or layer < 1):
        raise _err(where, f"key 'conditions.layer': expected a positive integer; got {layer!r}")
    region = d.get("region")
    if region is not None and not isinstance(region, str):
        raise _err(where, f"key 'conditions.region': expected a string; got {region!r}")
    tw = d.get("time_window")
    if tw is not None:
        tw = tuple(float(x) for x in tw)
        if len(tw) != 2 or not (0.0 <= tw[0] < tw[1] <= 1.0):
            raise _err(where, f"key 'conditions.time_window': expected [t0, t1] with "
                              f"0 <= t0 < t1 <= 1 (stroke fractions); got {d.get('time_window')!r}")
    extra = []
    for k in ("stage", "relative_humidity", "rest_time", "box_width"):
        if k in d:
            v = d[k]
            if k == "stage":
                if v not in ("before", "after"):
                    raise _err(where, f"key 'conditions.stage': expected 'before' or 'after'; got {v!r}")
            else:
                v = float(v)
                if k == "relative_humidity" and not 0 <= v <= 1:
                    raise _err(where, f"key 'conditions.relative_humidity': expected 0..1; got {v}")
                if k in ("rest_time", "box_width") and v < 0:
                    raise _err(where, f"key 'conditions.{k}': must be >= 0; got {v}")
            extra.append((k, v))
    return Conditions(speed, layer, region, tw, tuple(extra))


def _windowed(times, series, windows, where):
    """Mean and standard error of ``series`` in each window (the series operator)."""
    from .observables import windowed_mean
    try:
        return windowed_mean(times, series, windows)
    except ValueError as exc:
        raise _err(where, f"key 'windows': {exc}") from None


def measurement_from_dict(d: Mapping[str, Any], *, base_dir: Path | str | None = None,
                          where: str | None = None) -> Measurement:
    """Build one :class:`Measurement` from a parsed ``[[observable]]`` table.

    Parameters
    ----------
    d : mapping
        The table (see ``docs/diagnose.md`` for keys).
    base_dir : path, optional
        Folder that relative ``csv``/``image`` paths are resolved against.
    where : str, optional
        Location used in error messages.

    Raises
    ------
    ConfigError
        Naming the offending key when the table is invalid.
    """
    base_dir = Path(base_dir) if base_dir is not None else Path(".")
    name = d.get("name")
    where = where or f"observable {name!r}"
    if not isinstance(name, str) or not name:
        raise _err(where, "key 'name': expected a non-empty string")
    where = f"observable {name!r}"
    allowed = {"name", "kind", "unit", "value", "uncertainty", "replicates", "conditions", "role",
               "windows", "percentiles", "labels", "csv", "columns", "stroke_duration", "image",
               "images", "pixel_size", "note", "provenance"}
    unknown = set(d) - allowed
    if unknown:
        raise _err(where, f"key {sorted(unknown)[0]!r}: unknown key; allowed: {sorted(allowed)}")
    kind = d.get("kind")
    if kind not in KINDS:
        raise _err(where, f"key 'kind': expected one of {sorted(KINDS)}; got {kind!r}")
    role = d.get("role", "calibrate")
    if role not in ROLES:
        raise _err(where, f"key 'role': expected one of {ROLES}; got {role!r}")
    unit = str(d.get("unit", KINDS[kind]))
    file_unit = unit
    cond = _conditions(d.get("conditions"), where)
    conversions: list[str] = []
    windows = percentiles = replicates = None
    sem = None

    if kind == "dynamic_angle_series":
        if "windows" in d:
            windows = np.asarray(d["windows"], dtype=float)
            if windows.ndim != 2 or windows.shape[1] != 2 or np.any(windows[:, 0] >= windows[:, 1]) \
                    or np.any(windows < 0) or np.any(windows > 1):
                raise _err(where, "key 'windows': expected [[t0, t1], ...] with 0 <= t0 < t1 <= 1 "
                                  "(stroke fractions)")
        elif cond.time_window is not None:
            windows = np.asarray([cond.time_window])
        else:
            raise _err(where, "key 'windows': a dynamic_angle_series needs 'windows' "
                              "(or conditions.time_window)")
    if kind == "psd":
        if "percentiles" not in d:
            raise _err(where, "key 'percentiles': a psd needs the volume percentiles of its values, "
                              "e.g. [10, 50, 90]")
        percentiles = _float_array(d["percentiles"], where, "percentiles")
        if np.any(percentiles <= 0) or np.any(percentiles >= 100):
            raise _err(where, "key 'percentiles': expected values in (0, 100)")

    # ---- values: inline value, replicates, csv, or image(s)
    sources = [k for k in ("value", "replicates", "csv", "image", "images") if k in d]
    if role == "candidate":
        if sources:
            raise _err(where, f"key {sources[0]!r}: a candidate (not yet measured) observable has no values")
    elif len(sources) != 1:
        raise _err(where, "key 'value': give exactly one of 'value', 'replicates', 'csv', 'image', "
                          f"'images'; got {sources or 'none'}")
    src = sources[0] if sources else None
    if src == "value":
        values = _float_array(d["value"], where, "value")
    elif src == "replicates":
        rep = np.asarray(d["replicates"], dtype=float)
        if rep.ndim == 1:
            rep = rep[:, None]
        if rep.ndim != 2 or rep.shape[0] < 2:
            raise _err(where, "key 'replicates': expected at least 2 replicate readings")
        replicates = rep
        values = rep.mean(axis=0)
        # a standard error from a few readings is itself uncertain: taken at the same upper
        # confidence bound as the simulation's run scatter (an understated one makes a gap)
        bound = float(np.sqrt(variance_upper_bound(rep.shape[0] - 1)))
        sem = rep.std(axis=0, ddof=1) / math.sqrt(rep.shape[0]) * bound
        conversions.append(f"uncertainty: the standard error of {rep.shape[0]} replicates at its "
                           f"one-sided 84 % upper confidence bound (x{bound:.2f})")
    elif src == "csv":
        path = base_dir / str(d["csv"])
        names, data = _read_csv(path, where)
        cols = d.get("columns", ["force_x", "force_z"] if kind == "tool_force_ratio"
                      else names[:2])
        for c in cols:
            if c not in names:
                raise _err(where, f"key 'columns': column {c!r} not in {path.name} header {names}")
        x, y = data[:, names.index(cols[0])], data[:, names.index(cols[1])]
        if kind == "dynamic_angle_series":
            dur = d.get("stroke_duration")
            t = x / float(dur) if dur is not None else x
            if np.nanmax(t) > 1.0 + 1e-9:
                raise _err(where, "key 'stroke_duration': times exceed one stroke; give "
                                  "stroke_duration (s) or times as stroke fractions")
            values, sem = _windowed(t, y, windows, where)
        elif kind == "psd":
            from .observables import psd_percentiles_from_cumulative
            x_conv, note = _convert(x, unit, kind, where)
            if note:
                conversions.append(note)
            values = psd_percentiles_from_cumulative(x_conv, y, percentiles)
        elif kind == "tool_force_ratio":   # columns: horizontal, vertical load over the stroke
            from .observables import tool_force_ratio
            try:
                ratio, se = tool_force_ratio(x, y)
            except ValueError as exc:
                raise _err(where, f"key 'csv': {path.name}: {exc}") from None
            values = np.array([ratio])
            sem = np.array([se]) if math.isfinite(se) else None
        else:
            values = y
    elif src in ("image", "images"):
        if kind not in ("static_angle", "dynamic_angle_series"):
            raise _err(where, f"key {src!r}: images are supported for angle kinds only")
        if "pixel_size" not in d:
            raise _err(where, "key 'pixel_size': image observables need the pixel size (m)")
        from .observables import angle_from_image, read_image
        if src == "image":
            values = np.asarray([angle_from_image(read_image(base_dir / str(d["image"])),
                                                  pixel_size=float(d["pixel_size"]))])
        else:
            imgs = d["images"]
            if not isinstance(imgs, Mapping) or "files" not in imgs or "times" not in imgs:
                raise _err(where, "key 'images': expected {files = [...], times = [...]} "
                                  "(times as stroke fractions)")
            angles = [angle_from_image(read_image(base_dir / str(f)), pixel_size=float(d["pixel_size"]))
                      for f in imgs["files"]]
            values, sem = _windowed(np.asarray(imgs["times"], float), np.asarray(angles), windows, where)
    else:  # candidate
        n = (len(windows) if windows is not None else len(percentiles) if percentiles is not None
             else 1)
        values = np.full(n, np.nan)

    if src not in ("csv",) or kind != "psd":
        values, note = _convert(values, unit, kind, where) if src is not None else (values, None)
        if note:
            conversions.append(note)
        if replicates is not None:
            replicates = _convert(replicates, unit, kind, where)[0]
        if sem is not None:
            sem = _convert(sem, unit, kind, where)[0]

    n = len(values)
    if windows is not None and len(windows) != n:
        raise _err(where, f"key 'windows': {len(windows)} windows but {n} values")
    if percentiles is not None and len(percentiles) != n:
        raise _err(where, f"key 'percentiles': {len(percentiles)} percentiles but {n} values")
    if src is not None and not np.all(np.isfinite(values)):
        raise _err(where, "key 'value': values must be finite numbers")

    # ---- uncertainty: stated (systematic) and/or from replicates/series, in quadrature
    if "uncertainty" in d:
        unc = _float_array(d["uncertainty"], where, "uncertainty")
        if len(unc) == 1:
            unc = np.full(n, unc[0])
        if len(unc) != n:
            raise _err(where, f"key 'uncertainty': expected 1 or {n} values; got {len(unc)}")
        unc, _ = _convert(unc, file_unit, kind, where)
        if np.any(~np.isfinite(unc)) or np.any(unc <= 0):
            raise _err(where, "key 'uncertainty': must be positive and finite")
        if sem is not None:
            unc = np.sqrt(unc ** 2 + sem ** 2)
    elif sem is not None:
        unc = np.where(sem > 0, sem, np.nan)
        if np.any(~np.isfinite(unc)):
            raise _err(where, "key 'uncertainty': replicates show no scatter; state an uncertainty")
    else:
        raise _err(where, "key 'uncertainty': needed (one standard deviation), unless replicates "
                          "or a time series give it")

    labels = d.get("labels")
    if labels is None:
        if windows is not None:
            labels = [f"t={w[0]:.3g}-{w[1]:.3g}" for w in windows]
        elif percentiles is not None:
            labels = [f"d{p:g}" for p in percentiles]
        elif n == 1:
            labels = ["value"]
        else:
            labels = [f"c{i}" for i in range(n)]
    labels = tuple(str(x) for x in labels)
    if len(labels) != n:
        raise _err(where, f"key 'labels': {len(labels)} labels but {n} values")
    return Measurement(name=name, kind=kind, values=values, uncertainty=unc, labels=labels,
                       conditions=cond, role=role, windows=windows, percentiles=percentiles,
                       replicates=replicates, note=str(d.get("note", "")),
                       provenance=str(d.get("provenance", "measured" if src else "design")),
                       conversions=tuple(conversions))


def load_measurements(path) -> MeasurementSet:
    """Read and validate a measurement file (TOML, with optional CSV/image files beside it).

    Parameters
    ----------
    path : str or Path
        The TOML file. Relative ``csv``/``image`` paths are resolved against its folder.

    Returns
    -------
    MeasurementSet

    Raises
    ------
    FileNotFoundError
        If the file does not exist.
    ConfigError
        If the file is not valid TOML or a table is invalid (the message names the key).

    Examples
    --------
    >>> import bedstruct.diagnose as dg, pathlib
    >>> ms = dg.load_measurements(pathlib.Path(dg.__file__).parents[2] / "data/measurements/seed.toml")
    >>> ms["static_angle"].values
    array([33.])
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"measurement file not found: {path}")
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML ({exc})") from None
    meta = doc.get("meta", {})
    if not isinstance(meta, Mapping):
        raise ConfigError(f"{path}: key 'meta': expected a table")
    obs = doc.get("observable")
    if not isinstance(obs, list) or not obs:
        raise ConfigError(f"{path}: key 'observable': expected one or more [[observable]] tables")
    unknown = set(doc) - {"meta", "observable"}
    if unknown:
        raise ConfigError(f"{path}: key {sorted(unknown)[0]!r}: unknown top-level key; "
                          f"expected 'meta' and [[observable]]")
    ms = tuple(measurement_from_dict(o, base_dir=path.parent, where=f"{path}: observable #{i + 1}")
               for i, o in enumerate(obs))
    try:
        return MeasurementSet(ms, title=str(meta.get("title", path.stem)),
                              source=str(meta.get("source", "")), path=str(path),
                              notes=str(meta.get("notes", "")))
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None


# --------------------------------------------------------------------------- writing

def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"').replace("\n", " ") + '"'
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def write_measurements(mset: MeasurementSet, path) -> Path:
    """Write a :class:`MeasurementSet` as a measurement TOML file (canonical units).

    Values are written inline; replicates are not kept (their mean and standard
    error are). Reading the file back gives the same values and uncertainties.
    """
    path = Path(path)
    lines = ["[meta]", f"title = {_toml_value(mset.title)}", f"source = {_toml_value(mset.source)}"]
    if mset.notes:
        lines.append(f"notes = {_toml_value(mset.notes)}")
    for m in mset.measurements:
        lines += ["", "[[observable]]", f"name = {_toml_value(m.name)}", f"kind = {_toml_value(m.kind)}",
                  f"unit = {_toml_value(m.unit)}", f"role = {_toml_value(m.role)}"]
        if m.role != "candidate":
            lines.append(f"value = {_toml_value(m.values)}")
        lines.append(f"uncertainty = {_toml_value(m.uncertainty)}")
        lines.append(f"labels = {_toml_value(list(m.labels))}")
        if m.windows is not None:
            lines.append(f"windows = {_toml_value(m.windows)}")
        if m.percentiles is not None:
            lines.append(f"percentiles = {_toml_value(m.percentiles)}")
        if m.note:
            lines.append(f"note = {_toml_value(m.note)}")
        lines.append(f"provenance = {_toml_value(m.provenance)}")
        cd = m.conditions.as_dict()
        if cd:
            lines.append("[observable.conditions]")
            lines += [f"{k} = {_toml_value(v)}" for k, v in cd.items()]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path
