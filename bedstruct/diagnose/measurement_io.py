"""Reading and writing measurement files (TOML plus optional CSV/images).

The file format is documented in ``docs/diagnose.md``; the containers are in
:mod:`bedstruct.diagnose.measurements`.

Every error raised on a bad file is a :class:`~bedstruct.errors.ConfigError` that
names the file, the observable (its number in the file and its name) and the key,
and says what was expected.

The parsers of the table's pieces (typed keys, units and plausible ranges,
conditions, the CSV, time-series and image readers) are in
:mod:`bedstruct.diagnose.measurement_parse`; the values of an observable from its
source (inline, replicates, CSV, images) in :mod:`bedstruct.diagnose.measurement_values`.

.. versionadded:: 0.1
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import ConfigError
from .measurement_parse import (_check_plausible, _conditions, _convert, _err, _float_array,
                                _setup, _string, _table, _trials)
from .measurement_values import _source_values
from .measurements import (_UNIT, KIND_CONDITIONS, KINDS, PLAUSIBLE, ROLES, Measurement,
                           MeasurementSet)

#: Built-in kinds of one component: one number per observable (other layers, regions or
#: speeds are observables of their own; repeated readings go in ``replicates``).
ONE_COMPONENT = tuple(k for k in KIND_CONDITIONS if k not in ("dynamic_angle_series", "psd"))
#: Smallest relative uncertainty a powder measurement is taken to have: below it the
#: uncertainty was almost always written in another unit than the value (a fraction
#: beside a value in %).
MIN_RELATIVE_UNCERTAINTY = 5e-4

__all__ = ["load_measurements", "write_measurements", "measurement_from_dict"]


# --------------------------------------------------------------------------- loading

_ALLOWED = {"name", "kind", "unit", "value", "uncertainty", "replicates", "conditions", "role",
            "windows", "percentiles", "labels", "csv", "columns", "stroke_duration", "image",
            "images", "pixel_size", "powder", "flanks", "note", "provenance", "trials",
            "not_measured", "callable"}


def _register_user_kind(d: Mapping[str, Any], kind, where: str) -> None:
    """Register the ``callable`` of a user observable under its ``kind`` (unit: the
    canonical unit of the stated ``unit``'s dimension)."""
    from .observables_registry import (canonical_unit, load_callable, observable_kinds,
                                       register_observable)
    spec = _string(d["callable"], where, "callable")
    if not isinstance(kind, str) or not kind.isidentifier():
        raise _err(where, f"key 'kind': a user observable ('callable') needs a kind name of its own "
                          f"(letters, digits, _); got {kind!r}")
    builtin = {k.name: k for k in observable_kinds() if not k.user}
    if kind in builtin:
        raise _err(where, f"key 'callable': {kind!r} is a built-in kind, computed by "
                          f"{builtin[kind].analysis or 'bedstruct'}; give a user observable a "
                          f"kind name of its own")
    if "unit" not in d:
        raise _err(where, "key 'unit': a user observable needs the unit of its values "
                          f"(one of {sorted(_UNIT)}; its function returns the SI unit)")
    try:
        func = load_callable(spec)
        register_observable(kind, func, unit=canonical_unit(_string(d["unit"], where, "unit")))
    except (ConfigError, ValueError, TypeError) as exc:
        raise _err(where, f"key 'callable': {exc}") from None


def measurement_from_dict(d: Mapping[str, Any], *, base_dir: Path | str | None = None,
                          where: str | None = None, check_range: bool = False) -> Measurement:
    """Build one :class:`Measurement` from a parsed ``[[observable]]`` table.

    Parameters
    ----------
    d : mapping
        The table (see ``docs/diagnose.md`` for keys).
    base_dir : path, optional
        Folder that relative ``csv``/``image`` paths are resolved against.
    where : str, optional
        Location put before the observable's name in error messages (the file
        reader gives ``"<file>: observable #<i>"``).
    check_range : bool
        Check the values against the kind's plausible range
        (:data:`~bedstruct.diagnose.measurements.PLAUSIBLE`), the PSD's order, and
        the replicates' layout. :func:`load_measurements` always does; designs
        built in code (values 0 as placeholders) do not.

    Raises
    ------
    ConfigError
        Naming the file (when ``where`` says it), the observable and the offending key.
    """
    base_dir = Path(base_dir) if base_dir is not None else Path(".")
    if not isinstance(d, Mapping):
        raise ConfigError(f"{where or 'observable'}: expected a table; got {d!r}")
    name = d.get("name")
    if not isinstance(name, str) or not name.strip():
        raise _err(where or "observable", f"key 'name': expected a non-empty string; got {name!r}")
    if name != name.strip():
        raise _err(where or "observable", f"key 'name': {name!r} begins or ends with white "
                                          f"space; expected {name.strip()!r}")
    where = f"{where} {name!r}" if where else f"observable {name!r}"
    unknown = set(d) - _ALLOWED
    if unknown:
        raise _err(where, f"key {sorted(unknown)[0]!r}: unknown key; allowed: {sorted(_ALLOWED)}")
    kind = d.get("kind")
    if "callable" in d:
        _register_user_kind(d, kind, where)
    if kind not in KINDS:
        raise _err(where, f"key 'kind': expected one of {sorted(KINDS)}; got {kind!r}")
    role = d.get("role", "calibrate")
    if role not in ROLES:
        raise _err(where, f"key 'role': expected one of {ROLES}; got {role!r}")
    stated_unit = "unit" in d
    unit = _string(d["unit"], where, "unit") if stated_unit else KINDS[kind]
    if unit not in _UNIT:
        _convert([], unit, kind, where)   # the unknown-unit error
    file_unit = unit
    conversions: list[str] = []
    cond = _conditions(d.get("conditions"), where, conversions)
    allowed = KIND_CONDITIONS.get(kind)
    for key in cond.as_dict() if allowed is not None else ():
        if key not in allowed:   # a condition the kind does not depend on: never ignored
            kinds = [k for k, keys in KIND_CONDITIONS.items() if key in keys]
            raise _err(where, f"key 'conditions.{key}': only a {', '.join(kinds[:-1])}"
                              f"{' or ' if len(kinds) > 1 else ''}{kinds[-1]} has a "
                              f"{key.replace('_', ' ')}; this is a {kind} (its conditions: "
                              f"{', '.join(allowed)})")
    for key in ("note", "provenance"):
        if key in d and not isinstance(d[key], str):
            raise _err(where, f"key {key!r}: expected a string; got {d[key]!r}")
    windows = percentiles = replicates = None
    sem = None
    for key, kinds in (("windows", ("dynamic_angle_series",)), ("percentiles", ("psd",))):
        if key in d and kind not in kinds:
            raise _err(where, f"key {key!r}: only a {' or '.join(kinds)} has {key}; this is a {kind}")

    if kind == "dynamic_angle_series":
        if "windows" in d:
            windows = _table(d["windows"], where, "windows", row_name="window", width=2)
            if np.any(windows[:, 0] >= windows[:, 1]) or np.any(windows < 0) or np.any(windows > 1):
                raise _err(where, "key 'windows': expected [[t0, t1], ...] with 0 <= t0 < t1 <= 1 "
                                  f"(stroke fractions); got {d['windows']!r}")
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
            raise _err(where, f"key 'percentiles': expected values in (0, 100); got {d['percentiles']!r}")
        if len(percentiles) > 1 and np.all(percentiles <= 1):
            raise _err(where, f"key 'percentiles': {d['percentiles']!r} look like fractions; "
                              f"percentiles are in percent, e.g. "
                              f"{[float(f'{p * 100:.6g}') for p in percentiles]}")
        if np.any(np.diff(percentiles) <= 0):
            raise _err(where, f"key 'percentiles': expected increasing percentiles; got "
                              f"{d['percentiles']!r}")

    # ---- trials: a test that gave no reading in some (or all) of its trials
    trials, not_measured = _trials(d, where, role)
    in_no_trial = trials is not None and bool(np.all(np.asarray(not_measured) == trials))

    # ---- values: inline value, replicates, csv, or image(s)
    sources = [k for k in ("value", "replicates", "csv", "image", "images") if k in d]
    if role == "candidate":
        if sources:
            raise _err(where, f"key {sources[0]!r}: a candidate (not yet measured) observable has no values")
    elif in_no_trial:
        given = sources + ["uncertainty"] * ("uncertainty" in d)
        if given:
            raise _err(where, f"key {given[0]!r}: no reading in any of its {trials} trial(s) "
                              f"(not_measured = trials), so it has no value and no "
                              f"uncertainty; give neither")
    elif len(sources) != 1:
        raise _err(where, "key 'value': give exactly one of 'value', 'replicates', 'csv', 'image', "
                          f"'images'; got {sources or 'none'}")
    src = sources[0] if sources else None
    for key, needs in (("columns", ("csv",)), ("stroke_duration", ("csv",)),
                       ("pixel_size", ("image", "images")), ("powder", ("image", "images")),
                       ("flanks", ("image", "images"))):
        if key in d and src not in needs:
            raise _err(where, f"key {key!r}: only used with {' or '.join(repr(n) for n in needs)}")
    from_image = src in ("image", "images")
    if src is not None:
        values, sem, replicates = _source_values(d, src, kind, unit, windows, percentiles,
                                                 base_dir=base_dir, where=where,
                                                 conversions=conversions, check_range=check_range)
    else:  # candidate, or tried in vain
        n = (len(windows) if windows is not None else len(percentiles) if percentiles is not None
             else len(not_measured) if isinstance(not_measured, np.ndarray) else 1)
        values = np.full(n, np.nan)

    file_values = values
    # image angles are measured in deg by the operator: the file's unit is the unit of the
    # stated numbers (uncertainty), never applied to them; a psd CSV converted its sizes above
    if src is not None and not from_image and not (src == "csv" and kind == "psd"):
        values, note = _convert(values, unit, kind, where)
        if note:
            conversions.append(note)
        if replicates is not None:
            replicates = _convert(replicates, unit, kind, where)[0]
        if sem is not None:
            sem = _convert(sem, unit, kind, where)[0]

    n = len(values)
    if kind in ONE_COMPONENT and n != 1:
        raise _err(where, f"key {src!r}: a {kind} is one number, got {n}; repeated readings go "
                          f"in 'replicates = [...]', and another layer, region or speed is an "
                          f"observable of its own")
    if windows is not None and len(windows) != n:
        raise _err(where, f"key 'windows': {len(windows)} windows but {n} values")
    if percentiles is not None and len(percentiles) != n:
        raise _err(where, f"key 'percentiles': {len(percentiles)} percentiles but {n} values")
    if src is not None and not np.all(np.isfinite(values)):
        raise _err(where, f"key {src!r}: values must be finite numbers")
    # ---- uncertainty: stated (systematic) and/or from replicates/series, in quadrature
    if "uncertainty" in d:
        unc = _float_array(d["uncertainty"], where, "uncertainty")
        if len(unc) == 1:
            unc = np.full(n, unc[0])
        if len(unc) != n:
            raise _err(where, f"key 'uncertainty': expected 1 or {n} values; got {len(unc)}")
        unc, note = _convert(unc, file_unit, kind, where)
        stated_unc = unc
        if note and from_image:
            conversions.append(f"uncertainty: {note}")
        if np.any(~np.isfinite(unc)) or np.any(unc <= 0):
            raise _err(where, "key 'uncertainty': must be positive and finite")
        if sem is not None:
            unc = np.sqrt(unc ** 2 + sem ** 2)
    elif sem is not None:
        unc = np.where(sem > 0, sem, np.nan)
        if np.any(~np.isfinite(unc)):
            what = "replicates show" if src == "replicates" else f"the {src} gives"
            raise _err(where, f"key 'uncertainty': {what} no scatter; state an uncertainty")
    elif in_no_trial:
        unc = np.full(n, np.nan)
    else:
        raise _err(where, "key 'uncertainty': needed (one standard deviation), unless replicates "
                          "or a time series give it")
    if trials is not None:
        not_measured = np.broadcast_to(np.asarray(not_measured, dtype=int), (n,)).copy() \
            if np.ndim(not_measured) == 0 else not_measured
        if len(not_measured) != n:
            raise _err(where, f"key 'not_measured': {len(not_measured)} counts but {n} components")
        if not in_no_trial and np.any(not_measured == trials):
            raise _err(where, "key 'not_measured': some components had a reading in no trial and "
                              "others did; give those components as an observable of their own")
        if replicates is not None and np.any(trials - not_measured != replicates.shape[0]):
            raise _err(where, f"key 'trials': {replicates.shape[0]} replicate readings, but "
                              f"trials - not_measured = {(trials - not_measured).tolist()}")

    if check_range and src is not None:
        key = "value" if src in ("value",) else src
        if from_image:
            _check_plausible(values, kind, "deg", True, where, key)
        elif src == "csv" and kind == "psd":
            _check_plausible(values, kind, unit, stated_unit, where, key,
                             file_values=values / _UNIT[unit][1])
        else:
            _check_plausible(values, kind, unit, stated_unit, where, key, file_values=file_values)
        if kind == "psd" and n > 1:
            if np.any(np.diff(values) <= 0):
                raise _err(where, f"key {key!r}: the diameters must increase with the percentile "
                                  f"(d{percentiles[0]:g} < ... < d{percentiles[-1]:g}); got "
                                  f"{np.asarray(file_values).tolist()} {unit}")
            if replicates is not None:
                for i, row in enumerate(replicates):
                    if np.any(np.diff(row) <= 0):
                        raise _err(where, f"key 'replicates': replicate {i + 1} "
                                          f"{(row / _UNIT[unit][1]).tolist()} does not increase with "
                                          f"the percentile: each row must be one reading of all "
                                          f"percentiles, e.g. [d10, d50, d90]")
                spread = replicates.std(axis=0, ddof=1)
                if np.max(spread) > np.min(np.diff(values)):
                    raise _err(where, "key 'replicates': the replicates of one percentile scatter "
                                      "more than the percentiles differ; each row must be one "
                                      "reading of all percentiles (the layout looks transposed)")
        if "uncertainty" in d and PLAUSIBLE.get(kind, (0.0,))[0] > 0:
            _check_uncertainty(values, stated_unc, file_unit, where)

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
    elif not isinstance(labels, (list, tuple)) or not all(isinstance(x, str) for x in labels):
        raise _err(where, f"key 'labels': expected a list of strings; got {labels!r}")
    labels = tuple(str(x) for x in labels)
    if len(labels) != n:
        raise _err(where, f"key 'labels': {len(labels)} labels but {n} values")
    twice = sorted({x for x in labels if labels.count(x) > 1})
    if twice:
        raise _err(where, f"key 'labels': {twice[0]!r} labels more than one component; each "
                          f"component needs a label of its own")
    if percentiles is not None:
        for lab, pc in zip(labels, percentiles):
            named = re.fullmatch(r"[dD]_?(\d+(?:\.\d+)?)", lab.strip())
            if named and float(named.group(1)) != float(pc):
                raise _err(where, f"key 'labels': {lab!r} labels the {pc:g}th percentile; give "
                                  f"the labels in the order of 'percentiles' "
                                  f"({', '.join(f'{x:g}' for x in percentiles)})")
    return Measurement(name=name, kind=kind, values=values, uncertainty=unc, labels=labels,
                       conditions=cond, role=role, windows=windows, percentiles=percentiles,
                       replicates=replicates, note=str(d.get("note", "")),
                       provenance=str(d.get("provenance", "measured" if src else "design")),
                       conversions=tuple(conversions), trials=trials, not_measured=not_measured)


def _identity(m: Measurement):
    """What makes two measured observables the same measurement (None for one without values)."""
    if not np.all(np.isfinite(m.values)):
        return None
    extra = tuple(tuple(np.asarray(a, float).round(12).ravel().tolist())
                  for a in (m.windows, m.percentiles) if a is not None)
    return (m.kind, repr(sorted(m.conditions.as_dict().items())), tuple(m.values.tolist()),
            tuple(m.uncertainty.tolist()), extra)


def _check_uncertainty(values, unc, unit: str, where: str) -> None:
    """A stated uncertainty (canonical unit) of the order a measurement can have, else an
    error that names the likely unit slip."""
    v = np.abs(np.asarray(values, dtype=float))
    f = _UNIT[unit][1] if unit in _UNIT else 1.0
    u = "" if unit == "1" else f" {unit}"
    big = unc > v
    if np.any(big):
        i = int(np.flatnonzero(big)[0])
        raise _err(where, f"key 'uncertainty': {unc[i] / f:g}{u} is larger than the value "
                          f"{v[i] / f:g}{u}; the uncertainty is one standard deviation in "
                          f"the observable's unit ({unit!r}), as the value")
    small = unc < MIN_RELATIVE_UNCERTAINTY * v
    if np.any(small):
        i = int(np.flatnonzero(small)[0])
        raise _err(where, f"key 'uncertainty': {unc[i] / f:g}{u} is {unc[i] / v[i]:.2%} of "
                          f"the value {v[i] / f:g}{u}, finer than a powder measurement is; "
                          f"the uncertainty is one standard deviation in the observable's unit "
                          f"({unit!r}), as the value")


def load_measurements(path, *, check_range: bool = True) -> MeasurementSet:
    """Read and validate a measurement file (TOML, with optional CSV/image files beside it).

    Parameters
    ----------
    path : str or Path
        The TOML file. Relative ``csv``/``image`` paths are resolved against its folder.
    check_range : bool, optional
        Refuse values outside their kind's plausible range (default). The
        validation reads its synthetic twins without it: a toy simulator's
        numbers need not be physical.

    Returns
    -------
    MeasurementSet

    Raises
    ------
    FileNotFoundError
        If the file does not exist.
    ConfigError
        If the file is not valid TOML or a table is invalid: the message names the
        file, the observable (``#<i> '<name>'``) and the key. Values outside the
        kind's plausible range are errors (usually a unit mistake; the message
        says which unit would fit).

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
    for key, v in meta.items():
        if key not in ("title", "source", "notes"):
            raise ConfigError(f"{path}: key 'meta.{key}': unknown; expected title, source, notes")
        if not isinstance(v, str):
            raise ConfigError(f"{path}: key 'meta.{key}': expected a string; got {v!r}")
    obs = doc.get("observable")
    if not isinstance(obs, list) or not obs:
        raise ConfigError(f"{path}: key 'observable': expected one or more [[observable]] tables")
    unknown = set(doc) - {"meta", "observable", "conditions"}
    if unknown:
        raise ConfigError(f"{path}: key {sorted(unknown)[0]!r}: unknown top-level key; "
                          f"expected 'meta', 'conditions' and [[observable]]")
    setup = _setup(doc.get("conditions"), str(path), path.parent)
    ms = tuple(measurement_from_dict(o, base_dir=path.parent, where=f"{path}: observable #{i + 1}",
                                     check_range=check_range)
               for i, o in enumerate(obs))
    if setup.n_layers is not None:
        for i, m in enumerate(ms):
            if m.conditions.layer is not None and m.conditions.layer > setup.n_layers:
                raise ConfigError(f"{path}: observable #{i + 1} {m.name!r}: key "
                                  f"'conditions.layer': layer {m.conditions.layer}, but the "
                                  f"file's conditions give {setup.n_layers} layer(s); expected "
                                  f"1 to {setup.n_layers}")
    first: dict[str, int] = {}
    same: dict[tuple, int] = {}
    for i, m in enumerate(ms):
        if m.name in first:
            raise ConfigError(f"{path}: observable #{i + 1} {m.name!r}: key 'name': already the "
                              f"name of observable #{first[m.name] + 1}; expected a unique name")
        first[m.name] = i
        key = _identity(m)
        if key is not None and key in same:
            j = same[key]
            raise ConfigError(f"{path}: observable #{i + 1} {m.name!r}: repeats observable "
                              f"#{j + 1} {ms[j].name!r} (the same kind, conditions, values and "
                              f"uncertainty): one measurement would count twice; give it once "
                              f"(several readings go in 'replicates')")
        if key is not None:
            same[key] = i
    try:
        return MeasurementSet(tuple(m for m in ms if not m.measured_in_no_trial),
                              title=str(meta.get("title", path.stem)),
                              source=str(meta.get("source", "")), path=str(path),
                              notes=str(meta.get("notes", "")),
                              unmeasured=tuple(m for m in ms if m.measured_in_no_trial),
                              setup=setup)
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


def _user_callable(kind: str) -> str | None:
    """``"module:function"`` of a user kind whose function a file can name (importable by
    name: not defined in ``__main__`` or inside another function), else None."""
    from .observables_registry import observable_kinds
    k = {x.name: x for x in observable_kinds()}.get(kind)
    if k is None or not k.user:
        return None
    where = k.source.split("#")[0]
    return None if where.startswith("__main__:") or "<locals>" in where else where


def _setup_lines(setup) -> list[str]:
    """The ``[conditions]`` table of a set-up (SI values with their units)."""
    if setup.is_empty:
        return []
    lines = ["", "[conditions]"]
    if setup.psd is not None:
        d10, d50, d90, lo, hi = (f'"{x!r} m"' for x in setup.psd)
        table = ""
        if setup.psd_table is not None:
            dd, cum = setup.psd_table
            table = (", diameters = [" + ", ".join(f'"{x!r} m"' for x in dd) + "], cumulative = ["
                     + ", ".join(repr(float(x)) for x in cum) + "]")
        lines.append(f"psd = {{d10 = {d10}, d50 = {d50}, d90 = {d90}, d_min = {lo}, "
                     f"d_max = {hi}{table}}}")
    if setup.layer_thickness is not None:
        lines.append("layer_thickness = [" + ", ".join(f'"{x!r} m"' for x in setup.layer_thickness)
                     + "]")
    if setup.blade_speed is not None:
        lines.append(f'blade_speed = "{setup.blade_speed!r} m/s"')
    for key in ("platform_length", "platform_width", "wall_distance"):
        v = getattr(setup, key)
        if v is not None:
            lines.append(f'{key} = "{v!r} m"')
    if setup.side_walls is not None:
        lines.append(f"side_walls = {_toml_value(setup.side_walls)}")
    return lines


def write_measurements(mset: MeasurementSet, path) -> Path:
    """Write a :class:`MeasurementSet` as a measurement TOML file (canonical units).

    Values are written inline; replicates are not kept (their mean and standard
    error are), nor is an unmeasured observable's value (it has none), but the trials and
    the counts of those without a reading are. Reading the file back gives the same
    values, uncertainties and counts.
    """
    path = Path(path)
    lines = ["[meta]", f"title = {_toml_value(mset.title)}", f"source = {_toml_value(mset.source)}"]
    if mset.notes:
        lines.append(f"notes = {_toml_value(mset.notes)}")
    lines += _setup_lines(mset.setup)
    for m in mset.measurements + tuple(mset.unmeasured):
        lines += ["", "[[observable]]", f"name = {_toml_value(m.name)}", f"kind = {_toml_value(m.kind)}",
                  f"unit = {_toml_value(m.unit)}", f"role = {_toml_value(m.role)}"]
        func = _user_callable(m.kind)
        if func:
            lines.append(f"callable = {_toml_value(func)}")
        if m.role != "candidate" and not m.measured_in_no_trial:
            lines.append(f"value = {_toml_value(m.values)}")
        if np.all(np.isfinite(m.uncertainty)) and not m.measured_in_no_trial:
            lines.append(f"uncertainty = {_toml_value(m.uncertainty)}")
        if m.trials is not None:
            lines.append(f"trials = {_toml_value(int(m.trials))}")
            lines.append(f"not_measured = {_toml_value([int(k) for k in m.not_measured])}")
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
