"""LAMMPS/LIGGGHTS data files (``read_data``/``write_data``) for spheres.

Supported ``Atoms`` layouts:

* ``sphere`` and LIGGGHTS ``granular``: ``id type diameter density x y z [ix iy iz]``;
* ``hybrid`` with the sub-styles named: ``id type x y z`` then each
  sub-style's own columns in the order of the sub-styles, as LAMMPS writes
  them (``sphere``/``granular``: ``diameter density``; ``bond``, ``angle``,
  ``molecular``, LIGGGHTS ``bond/gran``: ``molecule``; ``charge``: ``q``;
  ``full``: ``molecule q``; ``dipole``: ``q mux muy muz``), then
  ``[ix iy iz]``. LIGGGHTS ``write_data`` leaves out the ``bond/gran``
  molecule id, so it may be missing;
* ``atomic``: ``id type x y z [ix iy iz]`` (radii from ``radius=``).

The style comes from the ``Atoms # style`` comment, the ``atom_style=``
argument, or, when neither is there, ``sphere`` (``hybrid granular bond/gran``
when the header declares bonds); the choice is noted in the provenance.
"""

from __future__ import annotations

import math
import os
import re
import warnings

import numpy as np

from ..core import Box, Frame, Provenance, Units
from ..core.box import _normalise_boundary
from ..errors import BedstructWarning, DumpFormatError
from ._text import check_unit_style

__all__ = ["read_data", "write_data"]

#: Begins the note of a frame read from a data file about its boundary flags, which data
#: files do not record (assumed, or given by the caller).
BOUNDARY_NOT_RECORDED = "data files do not record"

_HEADER_KEYS = ("atoms", "atom types", "bonds", "bond types", "angles", "angle types",
                "dihedrals", "dihedral types", "impropers", "improper types", "extra bond per atom",
                "extra angle per atom", "extra dihedral per atom", "extra improper per atom",
                "extra special per atom", "ellipsoids", "lines", "triangles", "bodies")
_SECTIONS = ("Atoms", "Velocities", "Masses", "Bonds", "Angles", "Dihedrals", "Impropers",
             "Pair Coeffs", "PairIJ Coeffs", "Bond Coeffs", "Angle Coeffs", "Dihedral Coeffs",
             "Improper Coeffs", "BondBond Coeffs", "BondAngle Coeffs", "MiddleBondTorsion Coeffs",
             "EndBondTorsion Coeffs", "AngleTorsion Coeffs", "AngleAngleTorsion Coeffs",
             "BondBond13 Coeffs", "AngleAngle Coeffs", "Ellipsoids", "Lines", "Triangles",
             "Bodies")


def _strip(line: str) -> str:
    k = line.find("#")
    return (line if k < 0 else line[:k]).strip()


# Columns each atom_style hybrid sub-style adds after 'id type x y z', with the per-atom
# field each fills (LAMMPS data_atom_hybrid / fields_data_atom). A field two sub-styles share is
# written once by LAMMPS since 2020 and twice before (and by LIGGGHTS), so such a combination
# is refused rather than guessed.
_HYBRID_COLUMNS = {
    "sphere": (("diameter", "radius"), ("density", "rmass")),
    "granular": (("diameter", "radius"), ("density", "rmass")),  # LIGGGHTS' name for sphere
    "bond": (("molecule", "molecule"),),
    "angle": (("molecule", "molecule"),),
    "molecular": (("molecule", "molecule"),),
    "bond/gran": (("molecule", "molecule"),),                    # LIGGGHTS
    "charge": (("q", "q"),),
    "full": (("molecule", "molecule"), ("q", "q")),
    "dipole": (("q", "q"), ("mux", "mu"), ("muy", "mu"), ("muz", "mu")),
    "atomic": (),
}


def _hybrid_layout(style: str) -> tuple[list, str | None]:
    """Column names of an ``atom_style hybrid`` Atoms row (without image flags), and the
    one column that may be missing (LIGGGHTS write_data leaves out bond/gran's molecule).

    Raises
    ------
    ValueError
        If the sub-styles are not named, unknown, or share a column.
    """
    subs = style.split()[1:]
    if not subs:
        raise ValueError("'atom_style hybrid' without its sub-styles: pass them in the order "
                         "of the atom_style command, e.g. atom_style='hybrid sphere bond'")
    cols = ["id", "type", "x", "y", "z"]
    owner: dict = {}
    for sub in subs:
        if sub not in _HYBRID_COLUMNS:
            raise ValueError(f"atom_style hybrid sub-style {sub!r} is not supported; known: "
                             f"{', '.join(_HYBRID_COLUMNS)}")
        for col, fld in _HYBRID_COLUMNS[sub]:
            if owner.setdefault(fld, sub) != sub:
                raise ValueError(f"atom_style {style!r}: sub-styles {owner[fld]!r} and {sub!r} "
                                 f"both have '{col}', which LAMMPS versions write once or "
                                 f"twice; this combination is not supported")
            cols.append(col)
    return cols, ("molecule" if "bond/gran" in subs else None)


_PLAIN_COLUMNS = {
    "sphere": ["id", "type", "diameter", "density", "x", "y", "z"],
    "granular": ["id", "type", "diameter", "density", "x", "y", "z"],
    "atomic": ["id", "type", "x", "y", "z"],
    "bond/gran": ["id", "molecule", "type", "x", "y", "z"],
}


def _row_layouts(style: str) -> dict:
    """Atoms row layouts of ``style``: values per row -> (column names, image flags last?).

    Raises
    ------
    ValueError
        For an unsupported style or hybrid combination.
    """
    words = style.split()
    head = words[0] if words else "sphere"
    if head == "hybrid":
        cols, optional = _hybrid_layout(style)
        variants = [cols] + ([[c for c in cols if c != optional]] if optional else [])
    elif head in _PLAIN_COLUMNS:
        variants = [_PLAIN_COLUMNS[head]]
    else:
        raise ValueError(f"atom_style {style!r} is not supported; expected sphere, granular, "
                         f"atomic, bond/gran or hybrid with the sub-styles "
                         f"{', '.join(_HYBRID_COLUMNS)}")
    layouts = {}
    for cols in variants:
        layouts[len(cols)] = (cols, False)
        layouts[len(cols) + 3] = (cols, True)
    return layouts


def _map_atoms(table, names, has_images, rows, path):
    """ids, types, positions, the other named columns and image flags of an Atoms table."""
    col = {name: table[:, k] for k, name in enumerate(names)}
    ids = _ints(col.pop("id"), rows, path, "id")
    types = _ints(col.pop("type"), rows, path, "type")
    pos = np.stack([col.pop(a) for a in "xyz"], axis=1)
    columns = {name: values.copy() for name, values in col.items()}
    if "molecule" in columns:
        columns["molecule"] = _ints(columns["molecule"], rows, path, "molecule")
    images = None
    if has_images:
        images = np.stack([_ints(table[:, c], rows, path, "image flag")
                           for c in range(len(names), len(names) + 3)], 1)
    return ids, types, pos, columns, images


def read_data(path, *, atom_style=None, boundary=None, radius=None, units=None) -> Frame:
    """Read a LAMMPS/LIGGGHTS data file of spheres into a :class:`Frame`.

    Parameters
    ----------
    path : str or path-like
        The data file.
    atom_style : str, optional
        ``"sphere"``, ``"granular"``, ``"hybrid granular bond/gran"``,
        ``"bond/gran"`` or ``"atomic"``; default from the ``Atoms # style``
        comment, else ``sphere`` (or the LIGGGHTS hybrid layout when bonds are
        declared).
    boundary : str or sequence of 3 str, optional
        Boundary flags (``"pp pp ff"``, ``("p", "p", "f")``); data files do
        not record them. Default ``"pp pp pp"`` (the LAMMPS default). For a
        bed with open space above it, give the bounded axis as ``f``:
        measured as periodic, the empty space counts in packing fractions.
        The provenance notes whether the boundary was given or assumed.
    radius : float, optional
        Radius for styles without a diameter column (``atomic``, ``bond/gran``).
    units : str, optional
        Unit style of the numbers (data files do not say); default unknown.

    Returns
    -------
    Frame
        Rows sorted by id; the timestep is the one ``write_data`` states in
        the title line (``timestep = N``, or bedstruct's ``(timestep N)``),
        else 0. ``columns`` holds ``density`` and ``mass``
        (density times sphere volume) for sphere styles, ``molecule`` when
        present; ``velocities`` and ``omegas`` come from a ``Velocities``
        section; per-type ``Masses`` are kept as ``type_mass``.

    Raises
    ------
    DumpFormatError
        For malformed files (file, line and what was expected).

    Examples
    --------
    >>> import os, tempfile
    >>> from bedstruct import Frame, read_data, write_data
    >>> path = os.path.join(tempfile.mkdtemp(), "data.spheres")
    >>> write_data(path, Frame([[1.0, 1.0, 1.0]], [0.5], box=[2, 2, 2]), density=2500.0)
    >>> f = read_data(path)
    >>> f.radii.tolist(), round(float(f.columns["mass"][0]), 3)
    ([0.5], 1308.997)
    """
    from .lammps_dump import _check_radius
    _check_radius(radius)
    units = check_unit_style(units)
    path = os.fspath(path)
    with open(path, "r", encoding="latin-1") as fh:
        lines = fh.read().splitlines()
    if not any(line.strip() for line in lines):
        raise DumpFormatError("empty data file (nothing but blank lines); expected a title "
                              "line, then a header with 'N atoms'", path=path, line=1)
    box_flags = _normalise_boundary(_DEFAULT_BOUNDARY if boundary is None else boundary)
    timestep = _title_timestep(lines[0])
    counts = {}
    bounds = {}
    tilt = None
    k = 1
    # ---- header (the first line is a title)
    while k < len(lines):
        text = _strip(lines[k])
        if not text:
            k += 1
            continue
        head = text.split()[0]
        if any(text.startswith(s) and (text == s or text[len(s)].isspace()) for s in _SECTIONS):
            break
        words = text.split()
        done = False
        for axis in ("x", "y", "z"):
            if text.endswith(f"{axis}lo {axis}hi"):
                bounds[axis] = _bounds_line(words, axis, path, k + 1, lines[k])
                done = True
        if text.endswith("xy xz yz"):
            try:
                tilt = [float(w) for w in words[:3]]
            except ValueError:
                raise DumpFormatError("expected 'xy xz yz' tilt factors", path=path, line=k + 1,
                                      text=lines[k]) from None
            if not all(math.isfinite(t) for t in tilt):
                raise DumpFormatError("tilt factors must be finite", path=path, line=k + 1,
                                      text=lines[k])
            done = True
        if not done:
            rest = " ".join(words[1:])
            if rest in _HEADER_KEYS:
                try:
                    counts[rest] = int(head)
                except ValueError:
                    raise DumpFormatError(f"expected an integer count of {rest}", path=path,
                                          line=k + 1, text=lines[k]) from None
            else:
                raise DumpFormatError("unknown data file header line", path=path, line=k + 1,
                                      text=lines[k])
        k += 1
    if "atoms" not in counts:
        raise DumpFormatError("header lacks the 'N atoms' line", path=path)
    missing = [a for a in "xyz" if a not in bounds]
    if missing:
        raise DumpFormatError(f"header lacks the box bounds for {missing}", path=path)
    n = counts["atoms"]
    # ---- sections
    sections = {}
    while k < len(lines):
        raw_line = lines[k]
        text = _strip(raw_line)
        if not text:
            k += 1
            continue
        name = next((s for s in _SECTIONS if text == s), None)
        if name is None:
            raise DumpFormatError("expected a section name such as 'Atoms' or 'Velocities'",
                                  path=path, line=k + 1, text=raw_line)
        comment = raw_line.split("#", 1)[1].strip() if "#" in raw_line else ""
        k += 1
        rows = []
        # section body: skip blank lines after the title, then rows until the next title
        while k < len(lines):
            t = _strip(lines[k])
            if not t:
                k += 1
                if rows:
                    # a blank line ends the section unless more rows follow directly
                    nxt = k
                    while nxt < len(lines) and not _strip(lines[nxt]):
                        nxt += 1
                    if nxt >= len(lines) or _strip(lines[nxt]) in _SECTIONS:
                        break
                continue
            if t in _SECTIONS:
                break
            if t[0].isalpha():
                raise DumpFormatError("unknown section name; expected one of "
                                      + ", ".join(_SECTIONS[:5]) + ", ...", path=path,
                                      line=k + 1, text=lines[k])
            rows.append((k + 1, t))
            k += 1
        sections[name] = (comment, rows)
    if "Atoms" not in sections:
        raise DumpFormatError("no 'Atoms' section", path=path)
    comment, rows = sections["Atoms"]
    notes = []
    if atom_style is None:
        if comment:
            atom_style = comment
        elif counts.get("bonds", 0) > 0 or counts.get("bond types", 0) > 0:
            atom_style = "hybrid granular bond/gran"
            notes.append("atom_style not stated; assumed LIGGGHTS 'hybrid granular bond/gran' "
                         "layout (id type x y z diameter density) because bonds are declared")
        else:
            atom_style = "sphere"
            notes.append("atom_style not stated; assumed 'sphere' (id type diameter density x y z)")
    try:
        layouts = _row_layouts(atom_style)
    except ValueError as exc:
        raise DumpFormatError(str(exc), path=path) from None
    if len(rows) != n:
        raise DumpFormatError(f"atom count mismatch: the header says {n} atoms but the Atoms "
                              f"section has {len(rows)} rows", path=path,
                              line=rows[-1][0] if rows else None)
    table = _numeric_rows(rows, path, "Atoms", allowed=tuple(sorted(layouts)))
    names, has_images = layouts[table.shape[1] if n else min(layouts)]
    ids, types, pos, columns, images = _map_atoms(table, names, has_images, rows, path)
    _warn_repeated_ids(ids, rows, path)
    diam = columns.pop("diameter", None)
    dens = columns.pop("density", None)
    if diam is not None:
        bad = ~(np.isfinite(diam) & (diam > 0))
        if bad.any():
            r = int(np.flatnonzero(bad)[0])
            raise DumpFormatError(f"diameter must be positive and finite (atom_style "
                                  f"{atom_style!r}: diameter is column "
                                  f"{names.index('diameter') + 1})", path=path,
                                  line=rows[r][0], text=rows[r][1])
        radii = diam / 2.0
        columns["density"] = dens.copy()
        columns["mass"] = dens * (4.0 / 3.0) * math.pi * radii ** 3
    elif radius is not None:
        radii = np.full(n, float(radius))
        notes.append(f"radius {float(radius)!r} given by the caller (atom_style {atom_style!r})")
    else:
        raise DumpFormatError(f"atom_style {atom_style!r} has no diameter; pass radius= "
                              f"(--radius on the command line)", path=path)
    bad = ~np.isfinite(pos).all(axis=1)
    if bad.any():
        r = int(np.flatnonzero(bad)[0])
        raise DumpFormatError("position must be finite", path=path, line=rows[r][0],
                              text=rows[r][1])
    kw = {}
    if images is not None:
        kw["images"] = images
    if "Velocities" in sections:
        vrows = sections["Velocities"][1]
        if len(vrows) != n:
            raise DumpFormatError(f"the Velocities section has {len(vrows)} rows; expected {n}",
                                  path=path, line=vrows[-1][0] if vrows else None)
        vt = _numeric_rows(vrows, path, "Velocities", allowed=(4, 7))
        vids = _ints(vt[:, 0], vrows, path, "id")
        order = np.argsort(vids)
        where = np.searchsorted(vids[order], ids)
        where = np.minimum(where, n - 1)
        if not np.array_equal(vids[order][where], ids):
            raise DumpFormatError("Velocities ids do not match the Atoms ids", path=path,
                                  line=vrows[0][0])
        vt = vt[order][where]
        kw["velocities"] = vt[:, 1:4]
        if vt.shape[1] == 7:
            kw["omegas"] = vt[:, 4:7]
    if "Masses" in sections:
        mrows = sections["Masses"][1]
        mt = _numeric_rows(mrows, path, "Masses", allowed=(2,))
        mass_of = dict(zip(_ints(mt[:, 0], mrows, path, "type").tolist(), mt[:, 1].tolist()))
        columns["type_mass"] = np.array([mass_of.get(int(t), np.nan) for t in types])
    skipped = [s for s in sections if s not in ("Atoms", "Velocities", "Masses")]
    if skipped:
        notes.append("sections not read: " + ", ".join(skipped))
    bstr = " ".join(box_flags)
    if boundary is None:
        notes.append(f"{BOUNDARY_NOT_RECORDED} boundary flags: boundary {bstr!r} assumed "
                     f"(the LAMMPS default; give boundary=, --boundary on the command line)")
    else:
        notes.append(f"boundary {bstr!r} given by the caller ({BOUNDARY_NOT_RECORDED} it)")
    if timestep is not None:
        notes.append(f"timestep {timestep} from the title line")
    lo = [bounds[a][0] for a in "xyz"]
    hi = [bounds[a][1] for a in "xyz"]
    box = Box(lo, hi, tilt if tilt is not None else np.zeros(3), box_flags)
    frame = Frame(pos, radii, box=box, ids=ids, types=types, columns=columns,
                  timestep=0 if timestep is None else timestep,
                  units=Units(None if units is None else units),
                  provenance=Provenance(source=path, frame_index=0, notes=tuple(notes)), **kw)
    return frame.sorted_by_id()


_DEFAULT_BOUNDARY = "pp pp pp"
# the title line of LAMMPS/LIGGGHTS write_data ("..., timestep = 101, units = si") and of
# bedstruct's write_data ("... (timestep 101)")
_TITLE_TIMESTEP = (re.compile(r"\btimestep\s*=\s*(\d+)\b"), re.compile(r"\(timestep (\d+)\)"))


def _title_timestep(title: str) -> int | None:
    """The timestep a ``write_data`` title line states, else None."""
    for pattern in _TITLE_TIMESTEP:
        found = pattern.search(title)
        if found:
            return int(found.group(1))
    return None


def _warn_repeated_ids(ids, rows, path) -> None:
    """Warn when an atom id appears twice (LAMMPS read_data refuses that; the Velocities
    join would pick one of them)."""
    order = np.argsort(ids, kind="stable")
    same = np.flatnonzero(ids[order][1:] == ids[order][:-1])
    if same.size:
        a, b = int(order[same[0]]), int(order[same[0] + 1])
        warnings.warn(f"{path}, line {rows[b][0]}: atom id {int(ids[a])} appears more than once "
                      f"in the Atoms section (also on line {rows[a][0]})", BedstructWarning,
                      stacklevel=3)


def _bounds_line(words, axis, path, line, text):
    """``lo hi`` of one ``xlo xhi`` header line: finite, ``hi`` not below ``lo``."""
    try:
        lo, hi = float(words[0]), float(words[1])
    except (ValueError, IndexError):
        raise DumpFormatError(f"expected '{axis}lo {axis}hi' bounds", path=path, line=line,
                              text=text) from None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise DumpFormatError(f"box bounds must be finite ('{axis}lo {axis}hi')", path=path,
                              line=line, text=text)
    if hi < lo:
        raise DumpFormatError(f"box '{axis}hi' {hi!r} is below '{axis}lo' {lo!r}", path=path,
                              line=line, text=text)
    return lo, hi


def _numeric_rows(rows, path, section, allowed):
    if not rows:
        return np.zeros((0, allowed[0]))
    width = len(rows[0][1].split())
    if width not in allowed:
        raise DumpFormatError(f"{section} rows need {' or '.join(map(str, allowed))} values; "
                              f"found {width}", path=path, line=rows[0][0], text=rows[0][1])
    out = np.empty((len(rows), width))
    for r, (ln, text) in enumerate(rows):
        parts = text.split()
        if len(parts) != width:
            raise DumpFormatError(f"wrong number of values in the {section} section: found "
                                  f"{len(parts)}, expected {width}", path=path, line=ln, text=text)
        try:
            out[r] = [float(p) for p in parts]
        except ValueError:
            raise DumpFormatError(f"non-numeric value in the {section} section", path=path,
                                  line=ln, text=text) from None
    return out


def _ints(col, rows, path, what):
    with np.errstate(invalid="ignore"):
        ints = col.astype(np.int64)
    bad = np.flatnonzero(ints != col)
    if bad.size:
        r = int(bad[0])
        raise DumpFormatError(f"{what} must be an integer", path=path, line=rows[r][0],
                              text=rows[r][1])
    return ints


def _r(x) -> str:
    return repr(float(x))


def write_data(path, frame: Frame, *, density=None, title=None) -> None:
    """Write a frame as a LAMMPS data file with ``atom_style sphere``.

    Rows are ``id type diameter density x y z [ix iy iz]`` under
    ``Atoms # sphere``; a ``Velocities`` section (``id vx vy vz wx wy wz``)
    follows when the frame has velocities. Floats are written round-trip exact.

    Parameters
    ----------
    path : path-like
        Output file.
    frame : Frame
        The spheres.
    density : float or (N,) array_like, optional
        Particle density (mass/length^3); default the frame's ``density``
        column. One of the two is required.
    title : str, optional
        The first (comment) line.

    Examples
    --------
    >>> import os, tempfile
    >>> from bedstruct import Frame, write_data
    >>> path = os.path.join(tempfile.mkdtemp(), "data.spheres")
    >>> write_data(path, Frame([[1.0, 1.0, 1.0]], [0.5], box=[2, 2, 2]), density=2500.0)
    >>> print(open(path).read().split("Atoms")[1].strip())
    # sphere
    <BLANKLINE>
    1 1 1.0 2500.0 1.0 1.0 1.0
    """
    if not isinstance(frame, Frame):
        raise TypeError(f"expected a Frame; got {type(frame).__name__}")
    n = frame.n_particles
    if density is None:
        if "density" not in frame.columns:
            raise ValueError("write_data needs a density: pass density= or give the frame a "
                             "'density' column")
        density = frame.columns["density"]
    dens = np.broadcast_to(np.asarray(density, dtype=np.float64), (n,))
    box = frame.box
    out = [title or f"LAMMPS data file written by bedstruct (timestep {frame.timestep})", "",
           f"{n} atoms", f"{int(frame.types.max(initial=1))} atom types", ""]
    for k, a in enumerate("xyz"):
        out.append(f"{_r(box.lo[k])} {_r(box.hi[k])} {a}lo {a}hi")
    if box.is_triclinic:
        out.append(f"{_r(box.tilt[0])} {_r(box.tilt[1])} {_r(box.tilt[2])} xy xz yz")
    out += ["", "Atoms # sphere", ""]
    img = frame.images
    for r in range(n):
        p = frame.positions[r]
        line = (f"{frame.ids[r]} {frame.types[r]} {_r(2.0 * frame.radii[r])} {_r(dens[r])} "
                f"{_r(p[0])} {_r(p[1])} {_r(p[2])}")
        if img is not None:
            line += f" {img[r, 0]} {img[r, 1]} {img[r, 2]}"
        out.append(line)
    if frame.velocities is not None:
        out += ["", "Velocities", ""]
        om = frame.omegas if frame.omegas is not None else np.zeros((n, 3))
        for r in range(n):
            v = frame.velocities[r]
            w = om[r]
            out.append(f"{frame.ids[r]} " + " ".join(_r(x) for x in (*v, *w)))
    with open(path, "w", encoding="ascii") as fh:
        fh.write("\n".join(out) + "\n")
