"""Contact files: LIGGGHTS ``compute pair/gran/local`` and LAMMPS ``property/local`` dumps.

A ``dump local`` file has one row per contact and no self-describing column
names (``c_ID[1] c_ID[2] ...``), so the caller says what was dumped: the
LIGGGHTS keywords (``keywords=``) or a map from column to meaning
(``columns=``). Contacts are joined by particle id to the atom frame of the
same timestep, or by the dumped positions where the ids cannot be used; branch
vectors come from that frame's positions by the minimum image, so contacts
across periodic boundaries are kept and flagged.
"""

from __future__ import annotations

import os
import warnings

import numpy as np

from ..core import Contacts, Frame, Trajectory
from ..errors import BedstructWarning, DumpFormatError
from ._columns import SYNTHESISED_IDS_NOTE
from ._source import Source, scan_text, stream_cut
from ._text import (TruncatedFrame, parse_text_frame, skip_or_raise, tail_truncation,
                    truncated)
from ._writer import _box_header, _format_rows, _open_write
from .lammps_dump import expand_paths, read_dump

__all__ = ["read_dump_local", "write_dump_local", "liggghts_local_columns",
           "PAIR_GRAN_LOCAL_ORDER", "PAIR_GRAN_LOCAL_DEFAULT"]

#: LIGGGHTS ``compute pair/gran/local`` keywords in the fixed order their values
#: are written, with the number of values each gives (None: pair-style dependent).
PAIR_GRAN_LOCAL_ORDER = (("pos", 6), ("vel", 6), ("id", 3), ("force", 3), ("force_normal", 3),
                         ("force_tangential", 3), ("torque", 3), ("history", None),
                         ("contactArea", 1), ("delta", 1), ("heatFlux", 1))

#: What ``compute pair/gran/local`` stores when no keyword is given.
PAIR_GRAN_LOCAL_DEFAULT = ("pos", "vel", "id", "force", "torque", "history", "contactArea")

_KEYWORD_NAMES = {
    "pos": ("x1", "y1", "z1", "x2", "y2", "z2"),
    "vel": ("vx1", "vy1", "vz1", "vx2", "vy2", "vz2"),
    "id": ("id1", "id2", "periodic"),
    "force": ("fx", "fy", "fz"),
    "force_normal": ("fnx", "fny", "fnz"),
    "force_tangential": ("ftx", "fty", "ftz"),
    "torque": ("tx", "ty", "tz"),
    "contactArea": ("area",),
    "delta": ("delta",),
    "heatFlux": ("heat_flux",),
}


#: The contact columns of the positions of both particles (LIGGGHTS keyword ``pos``).
_POSITIONS = (("x1", "y1", "z1"), ("x2", "y2", "z2"))


def liggghts_local_columns(keywords, n_columns=None) -> list[str]:
    """Meaning of each column of a ``compute pair/gran/local`` dump.

    Parameters
    ----------
    keywords : sequence of str
        The keywords of the compute command, in any order (the values are
        always written in the order of :data:`PAIR_GRAN_LOCAL_ORDER`).
    n_columns : int, optional
        Number of columns in the file; needed to size ``history``.

    Returns
    -------
    list of str
        One name per column: ``x1 y1 z1 x2 y2 z2``, ``vx1 ... vz2``,
        ``id1 id2 periodic``, ``fx fy fz``, ``fnx fny fnz``, ``ftx fty ftz``,
        ``tx ty tz``, ``history[1..n]``, ``area``, ``delta``, ``heat_flux``.

    Examples
    --------
    >>> liggghts_local_columns(["force", "id", "pos"])
    ['x1', 'y1', 'z1', 'x2', 'y2', 'z2', 'id1', 'id2', 'periodic', 'fx', 'fy', 'fz']
    >>> liggghts_local_columns(["id", "history", "contactArea"], n_columns=7)
    ['id1', 'id2', 'periodic', 'history[1]', 'history[2]', 'history[3]', 'area']
    """
    keywords = list(keywords.split() if isinstance(keywords, str) else keywords)
    known = [k for k, _ in PAIR_GRAN_LOCAL_ORDER]
    unknown = [k for k in keywords if k not in known]
    if unknown:
        raise ValueError(f"unknown pair/gran/local keywords {unknown}; expected some of {known}")
    fixed = sum(c for k, c in PAIR_GRAN_LOCAL_ORDER if k in keywords and c is not None)
    n_hist = 0
    if "history" in keywords:
        if n_columns is None:
            raise ValueError("`n_columns` is needed to size the 'history' values")
        n_hist = n_columns - fixed
        if n_hist < 0:
            raise ValueError(f"keywords {keywords} need at least {fixed} columns; the file has "
                             f"{n_columns}")
    names: list[str] = []
    for k, _ in PAIR_GRAN_LOCAL_ORDER:
        if k not in keywords:
            continue
        if k == "history":
            names.extend(f"history[{h + 1}]" for h in range(n_hist))
        else:
            names.extend(_KEYWORD_NAMES[k])
    if n_columns is not None and len(names) != n_columns:
        raise ValueError(f"keywords {keywords} give {len(names)} columns but the file has "
                         f"{n_columns}")
    return names


def _semantic_names(header, keywords, columns, path, line):
    ncols = len(header)
    if columns is not None:
        if isinstance(columns, dict):
            unknown = [c for c in columns if c not in header]
            if unknown:
                raise DumpFormatError(f"`columns` names {unknown} that are not in the ENTRIES "
                                      f"header {header}", path=path, line=line)
            return [columns.get(h, h) for h in header]
        columns = list(columns.split() if isinstance(columns, str) else columns)
        if len(columns) != ncols:
            raise DumpFormatError(f"`columns` gives {len(columns)} names but the file has "
                                  f"{ncols} columns {header}", path=path, line=line)
        return [h if c is None else c for c, h in zip(columns, header)]
    if keywords is not None:
        try:
            return liggghts_local_columns(keywords, ncols)
        except ValueError as exc:
            raise DumpFormatError(f"{exc} (a layout other than LIGGGHTS pair/gran/local needs "
                                  f"columns=, --contact-columns on the command line)",
                                  path=path, line=line) from None
    if {"id1", "id2"} <= set(header) or set(_POSITIONS[0] + _POSITIONS[1]) <= set(header):
        return list(header)
    first = [h for h in header if h != "index"][:2] or ["c_1[1]", "c_1[2]"]
    pairs = " ".join(f"{h}=id{k + 1}" for k, h in enumerate(first))
    raise DumpFormatError("say what the contact file holds: for LIGGGHTS pair/gran/local the "
                          "keywords of the compute (keywords=['pos', 'id', 'force', ...]; "
                          "--contact-keywords 'pos id force' on the command line), for other "
                          "layouts such as LAMMPS property/local what each column is "
                          f"(columns={{{first[0]!r}: 'id1', ...}}; --contact-columns "
                          f"'{pairs} ...' on the command line)", path=path, line=line,
                          text=" ".join(header))


class _FrameLookup:
    """Atom frames by timestep from a Frame, a sequence, a Trajectory or a path."""

    def __init__(self, frames, radius):
        self._close = None
        if isinstance(frames, (str, os.PathLike)):
            frames = read_dump(frames, radius=radius)
            self._close = frames
        if isinstance(frames, Frame):
            frames = [frames]
        self.frames = frames
        if isinstance(frames, Trajectory):
            steps = frames.timesteps
        else:
            steps = np.array([f.timestep for f in frames], dtype=np.int64)
        self.index = {}
        for k, t in enumerate(steps.tolist()):
            self.index.setdefault(int(t), k)
        self.cache = {}

    def get(self, timestep):
        k = self.index.get(int(timestep))
        if k is None:
            return None
        if k not in self.cache:
            self.cache = {k: self.frames[k]}   # hold one frame at a time
        return self.cache[k]

    def close(self):
        if self._close is not None:
            self._close.close()


def read_dump_local(path, *, keywords=None, columns=None, frames=None, radius=None,
                    strict=True) -> dict:
    """Read contacts from a ``dump local`` file and join them to atom frames.

    Parameters
    ----------
    path : str or path-like
        The contact file (plain or compressed).
    keywords : sequence of str, optional
        The LIGGGHTS ``compute pair/gran/local`` keywords used (``pos vel id
        force force_normal force_tangential torque history contactArea delta
        heatFlux``, any order; the file order is fixed, see
        :data:`PAIR_GRAN_LOCAL_ORDER`).
    columns : dict or sequence, optional
        For other layouts: a map from header column to meaning, e.g.
        ``{"c_1[1]": "id1", "c_1[2]": "id2", "c_2[1]": "dist", "c_2[3]":
        "fx", "c_2[4]": "fy", "c_2[5]": "fz"}``, or one meaning per column
        (None to keep the header name). Meanings: ``id1 id2`` (required
        unless the positions ``x1 y1 z1 x2 y2 z2`` are given), ``periodic``,
        ``fx fy fz`` (force on particle 1), ``fnx fny fnz``, ``ftx fty ftz``,
        ``area``; anything else is kept in ``columns``.
    frames : Frame, sequence of Frame, Trajectory or path
        The atom frames (or the atom dump file) to join with; each contact
        frame needs an atom frame of the same timestep. Contacts are joined
        by particle id; when the atom dump had no ``id`` column (its ids 1..N
        were made up by the reader) or the contact file has no ids, they are
        matched by the dumped positions (``pos``): each matches the one
        particle whose centre lies within half the smallest radius, across
        periodic boundaries too. The contact file's ids are then kept in
        ``columns``.
    radius : float, optional
        Passed to :func:`read_dump` when ``frames`` is a path.
    strict : bool, optional
        With False a truncated last frame is skipped with a warning.

    Returns
    -------
    dict of int to Contacts
        Contacts of every frame by timestep, in file order. ``i``, ``j`` index
        the rows of the atom frame; ``branch`` is the minimum-image vector
        from ``i`` to ``j``; ``periodic`` marks contacts across a periodic
        boundary; forces are split into normal and tangential parts along the
        branch when only the total force was dumped; ``area`` is the dumped
        contact area when present.

    Raises
    ------
    DumpFormatError
        For malformed files, unknown particle ids, column counts that do not
        match ``keywords``, ids to join to an atom dump without ids when no
        positions were dumped, and dumped positions with no particle (or two)
        under them.
    ValueError
        If no atom frame has the timestep of a contact frame.

    Examples
    --------
    >>> import os, tempfile
    >>> from bedstruct import Contacts, Frame, read_dump_local, write_dump_local
    >>> frame = Frame([[0.5, 0.5, 0.5], [1.4, 0.5, 0.5]], [0.5, 0.5], box=[2, 1, 1])
    >>> c = Contacts(i=[0], j=[1], branch=[[0.9, 0, 0]], radii_i=[0.5], radii_j=[0.5],
    ...              force_normal=[[-1.0, 0, 0]], force_tangential=[[0, 0.1, 0]], n_particles=2)
    >>> path = os.path.join(tempfile.mkdtemp(), "contacts.dump")
    >>> kw = write_dump_local(path, frame, c)
    >>> back = read_dump_local(path, keywords=kw, frames=frame)[0]
    >>> back.n_contacts, back.branch[0].tolist(), back.force_normal[0].tolist()
    (1, [0.9, 0.0, 0.0], [-1.0, 0.0, 0.0])

    .. versionadded:: 0.1
    """
    if frames is None:
        raise ValueError("pass frames= (the atom Frame(s) or the atom dump path) to join contacts "
                         "to particles")
    paths = expand_paths(path)
    lookup = _FrameLookup(frames, radius)
    out = {}
    try:
        for p in paths:
            src = Source(p)
            try:
                scan = scan_text(src)
                stream_cut(src, strict, stacklevel=3)
                if not scan.starts and scan.cut_line is not None:
                    skip_or_raise(truncated("the file ends inside the header of its first frame",
                                            path=src.path, line=scan.cut_line), strict,
                                  f"skipping the truncated only frame of {src.path}")
                for k, start in enumerate(scan.starts):
                    at_eof = k == len(scan.starts) - 1
                    buf = src.read_range(start, scan.end(k) - start)
                    try:
                        raw = parse_text_frame(buf, path=src.path, line0=scan.lines[k],
                                               at_eof=at_eof,
                                               file_ends_with_newline=scan.ends_with_newline)
                    except TruncatedFrame as exc:
                        skip_or_raise(exc, strict,
                                      f"skipping the truncated last frame of {src.path}")
                        continue
                    if raw.partial_tail is not None:  # the data before it are complete
                        skip_or_raise(tail_truncation(raw, buf, scan.lines[k]), strict,
                                      f"ignoring a cut-off frame header at the end of {src.path}")
                    if raw.kind != "ENTRIES":
                        raise DumpFormatError("this is an atom dump (ITEM: ATOMS), not a 'dump "
                                              "local' file; read it with read_dump", path=src.path,
                                              line=raw.header_line)
                    out[raw.timestep] = _contacts_from_raw(raw, keywords, columns, lookup)
            finally:
                src.close()
    finally:
        lookup.close()
    return out


def _rows_by_id(ids, data, idx, raw):
    """Rows of the atom frame (ids ``ids``) of the ``id1`` and ``id2`` columns."""
    m = raw.n
    n_atoms = len(ids)
    if np.all(ids[1:] > ids[:-1]):  # the usual case: a frame read sorted by id
        order, sorted_ids = None, ids
    else:
        order = np.argsort(ids, kind="stable")
        sorted_ids = ids[order]
        twice = sorted_ids[1:][sorted_ids[1:] == sorted_ids[:-1]]
        if twice.size:   # a contact naming a repeated id could be either particle
            raise DumpFormatError(f"cannot join contacts by particle id: id {int(twice[0])} "
                                  f"appears more than once in the atom frame at timestep "
                                  f"{raw.timestep} ({np.unique(twice).size} ids repeat)",
                                  path=raw.path)
    # ids lo, lo + 1, ..., lo + n - 1: a particle's row is its id - lo (no search)
    lo = int(ids[0]) if n_atoms else 0
    dense = order is None and n_atoms > 0 and int(ids[-1]) - lo + 1 == n_atoms
    rows = []
    for name in ("id1", "id2"):
        col = data[:, idx[name]]
        with np.errstate(invalid="ignore"):
            as_int = col.astype(np.int64)
        ok = as_int == col
        if dense:
            pos = as_int - lo
            ok &= (pos >= 0) & (pos < n_atoms)
            pos_c = np.where(ok, pos, 0)
        else:
            pos = np.searchsorted(sorted_ids, as_int)
            pos_c = np.minimum(pos, max(n_atoms - 1, 0))
            ok &= n_atoms > 0
            if n_atoms:
                ok &= sorted_ids[pos_c] == as_int
        if m and not ok.all():
            r = int(np.flatnonzero(~ok)[0])
            shown = int(col[r]) if ok[r] or float(col[r]).is_integer() else float(col[r])
            raise DumpFormatError(f"contact row {r + 1}: particle id {shown!r} ({name}) "
                                  f"is not in the atom frame at timestep {raw.timestep}",
                                  path=raw.path, line=raw.data_line + r, text=raw.row_text(r))
        if not m:
            pos_c = np.zeros(0, dtype=np.int64)
        rows.append(pos_c if order is None else order[pos_c])
    return rows


def _rows_by_position(frame, data, idx, raw):
    """Rows of the atom frame of the particles at the dumped contact positions.

    A dumped position matches the one particle whose centre lies within half the smallest
    radius of it (across periodic boundaries: LIGGGHTS dumps the position of a periodic
    image for contacts across one); no such particle, or two, is an error naming the row.
    """
    from scipy.spatial import cKDTree

    m = raw.n
    n = frame.n_particles
    if not m:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    if n == 0:
        raise DumpFormatError(f"the atom frame at timestep {raw.timestep} has no particles to "
                              f"match the contacts to", path=raw.path, line=raw.header_line)
    box = frame.box
    tol = 0.5 * float(frame.radii.min())
    per = [a for a in range(3) if box.periodic[a] and box.lengths[a] > 0]
    wrap = box.wrap if len(per) == sum(box.periodic) else (lambda x: np.array(x, dtype=float))
    points = wrap(frame.positions)
    owner = np.arange(n)
    edges = box.matrix.T  # rows: the edge vectors a, b, c
    for a in per:  # copies of the particles near a periodic face, on its other side
        if box.is_triclinic:
            b, c = [k for k in range(3) if k != a]
            width = abs(box.volume) / float(np.linalg.norm(np.cross(edges[b], edges[c])))
            s = box.fractional(points)[:, a] * width   # distance from the low face
        else:
            width, s = float(box.lengths[a]), points[:, a] - box.lo[a]
        low, high = s < tol, s > width - tol
        points = np.concatenate([points, points[low] + edges[a], points[high] - edges[a]])
        owner = np.concatenate([owner, owner[low], owner[high]])
    tree = cKDTree(points)
    rows = []
    for which, names in enumerate(_POSITIONS):
        query = np.stack([data[:, idx[c]] for c in names], axis=1)
        finite = np.all(np.isfinite(query), axis=1)
        query = wrap(np.where(finite[:, None], query, 0.0))
        dist, k = tree.query(query, k=2, distance_upper_bound=tol)
        k = np.minimum(k, len(points) - 1)   # misses (k == len) are reported below
        found = np.isfinite(dist[:, 0]) & finite
        second = np.isfinite(dist[:, 1]) & (owner[k[:, 1]] != owner[k[:, 0]])
        bad = ~found | second
        if bad.any():
            r = int(np.flatnonzero(bad)[0])
            what = ("no particle" if not found[r] else "more than one particle")
            raise DumpFormatError(f"contact row {r + 1}: {what} of the atom frame at timestep "
                                  f"{raw.timestep} lies within {tol:.3g} (half the smallest "
                                  f"radius) of particle {which + 1}'s dumped position "
                                  f"({' '.join(names)}); the contacts are matched to particles "
                                  f"by position because the atom ids cannot be used",
                                  path=raw.path, line=raw.data_line + r, text=raw.row_text(r))
        rows.append(owner[k[:, 0]])
    return rows


def _contacts_from_raw(raw, keywords, columns, lookup) -> Contacts:
    names = _semantic_names(raw.names, keywords, columns, raw.path, raw.header_line)
    frame = lookup.get(raw.timestep)
    if frame is None:
        raise ValueError(f"{raw.path}: no atom frame at timestep {raw.timestep} to join the "
                         f"contacts to (atom timesteps: {sorted(lookup.index)[:10]}...)")
    idx = {}
    for k, name in enumerate(names):
        if name in idx:
            raise DumpFormatError(f"column meaning {name!r} given twice", path=raw.path,
                                  line=raw.header_line)
        idx[name] = k
    data = raw.data
    m = raw.n
    ids = frame.ids
    has_ids = {"id1", "id2"} <= set(idx)
    has_pos = all(c in idx for c in _POSITIONS[0] + _POSITIONS[1])
    made_up = SYNTHESISED_IDS_NOTE in frame.provenance.notes
    if has_pos and (made_up or not has_ids):
        i, j = _rows_by_position(frame, data, idx, raw)
    elif not has_ids:
        raise DumpFormatError("the contact columns must include particle ids 'id1' and 'id2' "
                              "(LIGGGHTS keyword 'id', or map them with columns=; "
                              "--contact-keywords or --contact-columns on the command line)",
                              path=raw.path, line=raw.header_line)
    elif made_up:
        raise DumpFormatError(f"the atom dump has no 'id' column (the reader numbered its "
                              f"particles 1..N in file order), so the particle ids of the "
                              f"contacts cannot be matched to particles at timestep "
                              f"{raw.timestep}; dump the atoms with 'id', or the contact "
                              f"positions (LIGGGHTS keyword 'pos') to match on",
                              path=raw.path, line=raw.header_line)
    else:
        i, j = _rows_by_id(ids, data, idx, raw)
    used = {"id1", "id2"} if has_ids and not made_up else set()
    box = frame.box
    raw_d = frame.positions[j] - frame.positions[i]
    branch = box.minimum_image(raw_d)
    periodic = np.any(np.abs(branch - raw_d) > 0.0, axis=1) if m else np.zeros(0, bool)
    if "periodic" in idx:
        periodic = periodic | (data[:, idx["periodic"]] != 0)
        used.add("periodic")
    dist = np.sqrt(np.einsum("ij,ij->i", branch, branch))
    with np.errstate(invalid="ignore", divide="ignore"):
        normal = np.nan_to_num(branch / dist[:, None])

    def vec(names3):
        if all(c in idx for c in names3):
            used.update(names3)
            return np.stack([data[:, idx[c]] for c in names3], axis=1)
        if any(c in idx for c in names3):
            raise DumpFormatError(f"incomplete force columns: need all of {list(names3)}",
                                  path=raw.path, line=raw.header_line)
        return None

    fn = vec(("fnx", "fny", "fnz"))
    ft = vec(("ftx", "fty", "ftz"))
    f = vec(("fx", "fy", "fz"))
    extra = {}
    if f is not None:
        if fn is None and ft is None:
            fn = np.einsum("ij,ij->i", f, normal)[:, None] * normal
            ft = f - fn
        else:
            extra["force"] = f
            if fn is None:
                fn = f - ft
            if ft is None:
                ft = f - fn
    area = None
    if "area" in idx:
        area = data[:, idx["area"]].copy()
        used.add("area")
    if "dist" in idx and m:
        dumped = data[:, idx["dist"]]
        scale = np.maximum(np.abs(dumped), np.abs(box.lengths).max() * 1e-5)
        worst = float(np.max(np.abs(dumped - dist) / scale))
        if worst > 1e-3:
            warnings.warn(f"{raw.path}: dumped contact distances differ from the atom frame's "
                          f"by up to {worst:.2g} (relative); are the frames matched?",
                          BedstructWarning, stacklevel=3)
    for k, name in enumerate(names):
        if name not in used:
            extra[name] = data[:, k].copy()
    return Contacts(i=i, j=j, branch=branch, radii_i=frame.radii[i], radii_j=frame.radii[j],
                    ids_i=ids[i], ids_j=ids[j], periodic=periodic, force_normal=fn,
                    force_tangential=ft, area=area, n_particles=frame.n_particles,
                    columns=extra, source=raw.path)


def write_dump_local(path, frame: Frame, contacts: Contacts, *, append=False,
                     compute_id: str | None = None) -> tuple:
    """Write contacts in the LIGGGHTS ``compute pair/gran/local`` layout.

    The columns are those of the keywords ``pos id force force_normal
    force_tangential contactArea`` (forces only when ``contacts`` has them), in
    the LIGGGHTS order. They are named by meaning (``x1 y1 z1 x2 y2 z2 id1 id2
    periodic fx fy fz fnx ... area``), so :func:`read_dump_local` needs no
    ``keywords`` for these files; with ``compute_id`` they are named
    ``c_<compute_id>[k]`` as LIGGGHTS names them. Positions are the frame's,
    floats are written round-trip exact.

    Parameters
    ----------
    path : path-like
        Output file (``.gz`` etc. compress).
    frame : Frame
        The atom frame the contacts index into.
    contacts : Contacts
        Contacts of ``frame``.
    append : bool, optional
        Append a frame to an existing file.
    compute_id : str, optional
        Name the columns ``c_<compute_id>[1..k]`` (LIGGGHTS style) instead of
        by meaning.

    Returns
    -------
    tuple of str
        The keywords written; pass them to :func:`read_dump_local`.

    Examples
    --------
    >>> import os, tempfile
    >>> from bedstruct import Contacts, Frame, write_dump_local
    >>> frame = Frame([[0.5, 0.5, 0.5], [1.4, 0.5, 0.5]], [0.5, 0.5], box=[2, 1, 1])
    >>> c = Contacts(i=[0], j=[1], branch=[[0.9, 0, 0]], radii_i=[0.5], radii_j=[0.5],
    ...              n_particles=2)
    >>> write_dump_local(os.path.join(tempfile.mkdtemp(), "pairs.local"), frame, c)
    ('pos', 'id', 'contactArea')

    .. versionadded:: 0.1
    """
    if not isinstance(frame, Frame) or not isinstance(contacts, Contacts):
        raise TypeError("write_dump_local(path, frame, contacts) needs a Frame and a Contacts")
    if contacts.n_particles != frame.n_particles:
        raise ValueError(f"`contacts` index {contacts.n_particles} particles but `frame` has "
                         f"{frame.n_particles}")
    i, j = contacts.i, contacts.j
    keywords = ["pos", "id"]
    arrays = [frame.positions[i, 0], frame.positions[i, 1], frame.positions[i, 2],
              frame.positions[j, 0], frame.positions[j, 1], frame.positions[j, 2],
              frame.ids[i], frame.ids[j], contacts.periodic.astype(np.int64)]
    if contacts.force is not None:
        keywords += ["force", "force_normal", "force_tangential"]
        fn = contacts.force_normal if contacts.force_normal is not None else np.zeros((len(i), 3))
        ft = (contacts.force_tangential if contacts.force_tangential is not None
              else np.zeros((len(i), 3)))
        for vecs in (fn + ft, fn, ft):
            arrays += [vecs[:, 0], vecs[:, 1], vecs[:, 2]]
    keywords.append("contactArea")
    arrays.append(np.asarray(contacts.contact_area, dtype=np.float64))
    if compute_id is None:
        names = liggghts_local_columns(keywords, len(arrays))
    else:
        names = [f"c_{compute_id}[{k + 1}]" for k in range(len(arrays))]
    head = (f"ITEM: TIMESTEP\n{frame.timestep}\nITEM: NUMBER OF ENTRIES\n{contacts.n_contacts}\n"
            + _box_header(frame.box) + "ITEM: ENTRIES " + " ".join(names) + "\n")
    with _open_write(path, append) as fh:
        fh.write(head.encode("ascii"))
        fh.write(_format_rows(arrays, contacts.n_contacts))
    return tuple(keywords)
