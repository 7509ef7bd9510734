"""Storing frames, contacts and results in one HDF5 file (h5py).

Layout (``format = "bedstruct-hdf5"``, ``format_version = 1``)::

    /                      attrs: format, format_version, bedstruct_version, n_frames
    /frames/000000         attrs: timestep, time, box_lo, box_hi, box_tilt, box_boundary,
                                  units_style, units_conversions, source, frame_index, notes
        positions radii ids types [velocities omegas forces images]
        columns/<k>        attrs: name   (any dump column, k = 0, 1, ...)
    /contacts/000000       (optional, one per frame) i j branch radii_i radii_j ...
    /results/<name>        arrays as datasets, scalars and strings as attributes

Arrays are chunked and gzip-compressed; the file is written to a temporary
file in the same folder and moved into place with :func:`os.replace`, so a
crash never leaves a half-written file under the final name.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass

import numpy as np

from .._atomic import atomic_path
from .._version import __version__
from ..core import Box, Contacts, Frame, FrameList, Provenance, Units

#: The first bytes of every HDF5 file.
HDF5_MAGIC = b"\x89HDF\r\n\x1a\n"

__all__ = ["save_hdf5", "load_hdf5", "HDF5Contents"]

_FORMAT = "bedstruct-hdf5"
_VERSION = 1
_FRAME_ARRAYS = ("positions", "radii", "ids", "types", "velocities", "omegas", "forces", "images")
_CONTACT_ARRAYS = ("i", "j", "branch", "radii_i", "radii_j", "ids_i", "ids_j", "periodic",
                   "force_normal", "force_tangential", "area")


@dataclass(frozen=True)
class HDF5Contents:
    """What :func:`load_hdf5` returns.

    Attributes
    ----------
    frames : FrameList
        The stored frames, in order.
    contacts : list of (Contacts or None), or None
        Contacts stored for each frame (None where absent), or None when the
        file holds no contacts.
    results : dict
        Stored results by name (arrays, numbers, strings, nested dicts).
    bedstruct_version : str
        The bedstruct version that wrote the file.
    """

    frames: FrameList
    contacts: list | None
    results: dict
    bedstruct_version: str


def _dataset(group, name, arr, what=None):
    """Store ``arr`` as dataset ``name``; booleans and strings are marked so that
    :func:`_value` gives them back with their dtype."""
    arr = np.asarray(arr)
    kind = None
    if arr.dtype == bool:
        arr, kind = arr.astype(np.uint8), "bool"
    elif arr.dtype.kind in "US":
        import h5py
        kind = "str" if arr.dtype.kind == "U" else "bytes"
        arr = np.char.encode(arr, "utf-8") if kind == "str" else arr
        arr = arr.astype(h5py.string_dtype("utf-8" if kind == "str" else "ascii"))
    elif arr.dtype.kind not in "iuf":
        raise ValueError(f"{what or repr(name)} holds {arr.dtype} values, which bedstruct's "
                         f"HDF5 files do not store (numbers, booleans or strings)")
    if arr.size >= 64:
        ds = group.create_dataset(name, data=arr, chunks=True, compression="gzip",
                                  compression_opts=4, shuffle=True)
    else:
        ds = group.create_dataset(name, data=arr)
    if kind is not None:
        ds.attrs["bedstruct_dtype"] = kind
    return ds


def _value(ds):
    """The array of a dataset written by :func:`_dataset`, with its original dtype."""
    kind = ds.attrs.get("bedstruct_dtype")
    if kind == "bool":
        return ds[()].astype(bool)
    if kind == "str":
        return np.asarray(ds.asstr()[()], dtype=str)
    if kind == "bytes":
        return np.asarray(ds[()], dtype=bytes)
    return ds[()]


def _write_arrays(g, obj, names):
    """The arrays ``names`` of a Frame or Contacts (those not None) and its extra
    ``columns`` (as ``columns/<k>`` with a ``name`` attribute, in order)."""
    for name in names:
        arr = getattr(obj, name)
        if arr is not None:
            _dataset(g, name, arr)
    cols = g.create_group("columns")
    for k, (name, arr) in enumerate(obj.columns.items()):
        ds = _dataset(cols, str(k), arr, what=f"column {name!r}")
        ds.attrs["name"] = name


def _read_arrays(g, names):
    """(arrays by name, columns by name) as written by :func:`_write_arrays`."""
    kw = {name: _value(g[name]) for name in names if name in g}
    cols = {}
    for key in sorted(g["columns"], key=int):
        ds = g["columns"][key]
        cols[str(ds.attrs["name"])] = _value(ds)
    return kw, cols


def _write_frame(g, frame: Frame):
    g.attrs["timestep"] = frame.timestep
    g.attrs["time"] = np.nan if frame.time is None else frame.time
    g.attrs["has_time"] = frame.time is not None
    g.attrs["box_lo"] = frame.box.lo
    g.attrs["box_hi"] = frame.box.hi
    g.attrs["box_tilt"] = frame.box.tilt
    g.attrs["box_boundary"] = " ".join(frame.box.boundary)
    g.attrs["units_style"] = "" if frame.units.style is None else frame.units.style
    g.attrs["units_known"] = frame.units.style is not None
    g.attrs["units_conversions"] = json.dumps(list(frame.units.conversions))
    prov = frame.provenance
    g.attrs["source"] = "" if prov.source is None else prov.source
    g.attrs["frame_index"] = -1 if prov.frame_index is None else prov.frame_index
    g.attrs["notes"] = json.dumps(list(prov.notes))
    _write_arrays(g, frame, _FRAME_ARRAYS)


def _read_frame(g) -> Frame:
    a = g.attrs
    box = Box(a["box_lo"], a["box_hi"], a["box_tilt"], str(a["box_boundary"]))
    kw, cols = _read_arrays(g, _FRAME_ARRAYS)
    positions = kw.pop("positions").reshape(-1, 3)
    radii = kw.pop("radii")
    units = Units(str(a["units_style"]) if a["units_known"] else None,
                  tuple(json.loads(a["units_conversions"])))
    fi = int(a["frame_index"])
    prov = Provenance(source=str(a["source"]) or None, frame_index=None if fi < 0 else fi,
                      notes=tuple(json.loads(a["notes"])))
    return Frame(positions, radii, box=box, timestep=int(a["timestep"]),
                 time=float(a["time"]) if a["has_time"] else None, columns=cols, units=units,
                 provenance=prov, **kw)


def _write_contacts(g, c: Contacts):
    g.attrs["n_particles"] = c.n_particles
    g.attrs["source"] = c.source
    _write_arrays(g, c, _CONTACT_ARRAYS)


def _read_contacts(g) -> Contacts:
    kw, cols = _read_arrays(g, _CONTACT_ARRAYS)
    if "periodic" in kw:
        kw["periodic"] = kw["periodic"].astype(bool)
    m = kw["i"].shape[0]
    for name in ("branch", "force_normal", "force_tangential"):
        if name in kw:
            kw[name] = kw[name].reshape(m, 3)
    return Contacts(n_particles=int(g.attrs["n_particles"]), source=str(g.attrs["source"]),
                    columns=cols, **kw)


def _write_results(g, results: dict, where=""):
    for name, value in results.items():
        name = str(name)
        if "/" in name:
            raise ValueError(f"result names cannot contain '/': {name!r}")
        what = f"result {where + name!r}"
        if isinstance(value, dict):
            _write_results(g.create_group(name), value, where + name + "/")
        elif value is None:
            g.attrs[name] = "__none__"
        elif isinstance(value, str) and value != "__none__":
            g.attrs[name] = value
        elif isinstance(value, (bool, np.bool_)):
            g.attrs[name] = np.bool_(value)
        elif isinstance(value, (int, np.integer)) and not -2 ** 63 <= int(value) < 2 ** 63:
            _json_attr(g, name, int(value), what)
        elif isinstance(value, (int, float, complex, bytes, np.number)):
            g.attrs[name] = value
        else:
            try:
                arr = np.asarray(value)
            except ValueError:  # ragged nesting
                arr = np.asarray(None, dtype=object)
            if isinstance(value, (list, tuple, str)) and arr.dtype.kind in "OUS":
                _json_attr(g, name, value, what)
            elif arr.dtype.kind == "U" and arr.ndim:
                _json_attr(g, name, arr.tolist(), what)
            else:
                _dataset(g, name, arr, what=what)


def _json_attr(g, name, value, what):
    try:
        text = json.dumps(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what} cannot be stored in HDF5: {exc}") from None
    g.attrs[name] = text
    g.attrs[name + "__json__"] = True


def _read_results(g) -> dict:
    out = {}
    for name, value in g.attrs.items():
        if name.endswith("__json__"):
            continue
        if g.attrs.get(name + "__json__", False):
            out[name] = json.loads(value)
        elif isinstance(value, str) and value == "__none__":
            out[name] = None
        elif isinstance(value, bytes):
            out[name] = value.decode()
        elif isinstance(value, np.generic):
            out[name] = value.item()
        else:
            out[name] = value
    for name, item in g.items():
        out[name] = _read_results(item) if hasattr(item, "keys") else _value(item)
    return out


def save_hdf5(path, frames, contacts=None, results=None) -> None:
    """Save frames (and optionally contacts and results) to an HDF5 file.

    Parameters
    ----------
    path : path-like
        Output file; replaced atomically.
    frames : Frame or iterable of Frame
        Frames to store (a lazy trajectory is read one frame at a time).
    contacts : Contacts or sequence of (Contacts or None), optional
        Contacts of each frame, aligned with ``frames``.
    results : dict, optional
        Named results: arrays, numbers, strings, or nested dicts of those.

    Examples
    --------
    >>> import os, tempfile
    >>> from bedstruct import Frame, load_hdf5, save_hdf5
    >>> path = os.path.join(tempfile.mkdtemp(), "bed.h5")
    >>> save_hdf5(path, Frame([[0.5, 0.5, 0.5]], [0.5], box=[1, 1, 1]), results={"phi": 0.52})
    >>> stored = load_hdf5(path)
    >>> len(stored.frames), stored.results["phi"]
    (1, 0.52)

    .. versionadded:: 0.1
    """
    import h5py

    if isinstance(frames, Frame):
        frames = [frames]
    if isinstance(contacts, Contacts):
        contacts = [contacts]
    with atomic_path(os.fspath(path), suffix=".h5.tmp") as tmp:
        with h5py.File(tmp, "w") as h:
            h.attrs["format"] = _FORMAT
            h.attrs["format_version"] = _VERSION
            h.attrs["bedstruct_version"] = __version__
            fg = h.create_group("frames")
            count = 0
            for k, frame in enumerate(frames):
                if not isinstance(frame, Frame):
                    raise TypeError(f"frames must be Frame objects; item {k} is "
                                    f"{type(frame).__name__}")
                _write_frame(fg.create_group(f"{k:06d}"), frame)
                count += 1
            h.attrs["n_frames"] = count
            if contacts is not None:
                contacts = list(contacts)
                if len(contacts) != count:
                    raise ValueError(f"`contacts` must align with `frames` ({count}); got "
                                     f"{len(contacts)}")
                cg = h.create_group("contacts")
                for k, c in enumerate(contacts):
                    if c is not None:
                        _write_contacts(cg.create_group(f"{k:06d}"), c)
            if results is not None:
                _write_results(h.create_group("results"), dict(results))


def load_hdf5(path) -> HDF5Contents:
    """Load a file written by :func:`save_hdf5`.

    Returns
    -------
    HDF5Contents
        ``frames``, ``contacts``, ``results`` and ``bedstruct_version``.

    Raises
    ------
    FileNotFoundError
        If the file does not exist.
    ValueError
        If the file is not a bedstruct HDF5 file (not HDF5 at all, or HDF5
        written by something else).

    Examples
    --------
    >>> import os, tempfile
    >>> from bedstruct import Frame, load_hdf5, save_hdf5
    >>> path = os.path.join(tempfile.mkdtemp(), "bed.h5")
    >>> save_hdf5(path, [Frame([[0.5, 0.5, 0.5]], [0.5], box=[1, 1, 1], timestep=t)
    ...                  for t in (0, 10)])
    >>> load_hdf5(path).frames.timesteps.tolist()
    [0, 10]

    .. versionadded:: 0.1
    """
    import h5py

    path = os.fspath(path)
    if not os.path.exists(path):
        raise FileNotFoundError(f"{path}: no such file")
    if os.path.isfile(path) and os.access(path, os.R_OK) and not h5py.is_hdf5(path):
        raise ValueError(f"{path}: not an HDF5 file (bedstruct.io.read reads dump and data "
                         f"files)")
    with h5py.File(path, "r") as h:
        if h.attrs.get("format") != _FORMAT:
            raise ValueError(f"{path}: not a bedstruct HDF5 file (format attribute "
                             f"{h.attrs.get('format')!r})")
        n = int(h.attrs["n_frames"])
        frames = FrameList([_read_frame(h["frames"][f"{k:06d}"]) for k in range(n)])
        contacts = None
        if "contacts" in h:
            cg = h["contacts"]
            contacts = [_read_contacts(cg[f"{k:06d}"]) if f"{k:06d}" in cg else None
                        for k in range(n)]
        results = _read_results(h["results"]) if "results" in h else {}
        version = str(h.attrs["bedstruct_version"])
    return HDF5Contents(frames=frames, contacts=contacts, results=results,
                        bedstruct_version=version)
