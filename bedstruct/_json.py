"""JSON-ready data: the one converter every result, record and report uses.

:func:`to_jsonable` turns dataclasses, mappings, sequences, numpy arrays and
scalars and paths into plain JSON data; :func:`json_default` is the same rule as
a ``json.dump`` hook for writers that keep NaN and infinities; :func:`plain` is
the JSON round trip a checkpoint gives back; :func:`write_json_atomic` writes a
file that is either complete or absent.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, is_dataclass
from pathlib import Path

import numpy as np

from ._atomic import atomic_path

__all__ = ["to_jsonable", "json_default", "plain", "write_json_atomic"]


def to_jsonable(obj, *, keep_nonfinite: bool = False):
    """Convert ``obj`` to data that :func:`json.dumps` accepts.

    Parameters
    ----------
    obj : object
        Dataclass instances (converted field by field), mappings (keys become
        strings), lists and tuples, numpy arrays and scalars, :class:`~pathlib.Path`,
        and plain JSON values.
    keep_nonfinite : bool, optional
        Keep NaN and infinities as floats (JSON's ``NaN``/``Infinity``, which
        Python reads back). By default they become ``None`` (``null``), which every
        JSON reader accepts.

    Returns
    -------
    object
        Nested dicts, lists, strings, numbers, booleans and ``None``.

    Raises
    ------
    TypeError
        For an object with no JSON form, named by its type.

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import to_jsonable
    >>> to_jsonable({"phi": np.float64(0.58), "n": np.arange(3), "bad": float("nan")})
    {'phi': 0.58, 'n': [0, 1, 2], 'bad': None}
    """
    if is_dataclass(obj) and not isinstance(obj, type):
        return {k: to_jsonable(v, keep_nonfinite=keep_nonfinite) for k, v in asdict(obj).items()}
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v, keep_nonfinite=keep_nonfinite) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v, keep_nonfinite=keep_nonfinite) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist(), keep_nonfinite=keep_nonfinite)
    if isinstance(obj, np.generic):
        return to_jsonable(obj.item(), keep_nonfinite=keep_nonfinite)
    if isinstance(obj, float):
        return obj if keep_nonfinite or math.isfinite(obj) else None
    if isinstance(obj, Path):
        return str(obj)
    if obj is None or isinstance(obj, (str, int, bool)):
        return obj
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def json_default(o):
    """``default=`` hook of :func:`json.dump` with the rules of :func:`to_jsonable`.

    Non-finite floats stay as they are (``json.dump`` writes ``NaN``).

    Examples
    --------
    >>> import json
    >>> import numpy as np
    >>> from bedstruct._json import json_default
    >>> json.dumps({"x": np.float32(0.5), "v": np.zeros(2)}, default=json_default)
    '{"x": 0.5, "v": [0.0, 0.0]}'
    """
    if is_dataclass(o) and not isinstance(o, type):
        return asdict(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def plain(value):
    """``value`` as a checkpoint gives it back: a JSON round trip that keeps NaN and inf.

    Tuples become lists, numpy scalars Python numbers, dataclasses dicts.

    Examples
    --------
    >>> from bedstruct._json import plain
    >>> plain({"a": (1, 2), "b": float("inf")})
    {'a': [1, 2], 'b': inf}
    """
    return json.loads(json.dumps(value, default=json_default))


def write_json_atomic(path, data, *, keep_nan: bool = False) -> Path:
    """Write JSON to ``path`` atomically (temporary file in the same folder, then rename).

    NaN becomes ``null`` unless ``keep_nan`` (then JSON's ``NaN``, which Python reads back).

    Examples
    --------
    >>> import json, tempfile, pathlib
    >>> from bedstruct._json import write_json_atomic
    >>> p = write_json_atomic(pathlib.Path(tempfile.mkdtemp()) / "r.json", {"x": float("nan")})
    >>> json.loads(p.read_text())
    {'x': None}
    """
    path = Path(path)
    with atomic_path(path) as tmp:
        with open(tmp, "w") as fh:
            if keep_nan:
                json.dump(data, fh, indent=2, default=json_default)
            else:
                json.dump(to_jsonable(data), fh, indent=2)
            fh.write("\n")
    return path
