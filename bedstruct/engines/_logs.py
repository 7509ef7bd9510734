"""Reading what LIGGGHTS and LAMMPS print: thermo tables (:func:`parse_log`) and the
records that bedstruct's spreading decks write into the log.

:func:`parse_log` reads any LIGGGHTS 3.x or LAMMPS log. The spreading decks
(:func:`~bedstruct.engines.spread_layers_deck`) print one marker line per layer,
``MARKER layer=K key=value ...``: the steps waited for flying powder to land
(:func:`landing_offsets`), the load of the powder on the tool averaged over the stroke
(:func:`tool_loads`) and, as their last command, that the run got to its end
(:func:`run_finished`). The markers are defined here, beside their readers.
Both engines print the same records; no engine is needed to read them.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

__all__ = ["ThermoRun", "EngineLog", "parse_log", "landing_offsets", "run_finished", "tool_loads"]


# --------------------------------------------------------------------------- log parsing
def _column_index(columns, name: str) -> int | None:
    if name in columns:
        return columns.index(name)
    alt = name[2:] if name[:2] in ("v_", "c_", "f_") else None
    if alt and alt in columns:
        return columns.index(alt)
    for prefix in ("v_", "c_", "f_"):
        if prefix + name in columns:
            return columns.index(prefix + name)
    return None


@dataclass(frozen=True)
class ThermoRun:
    """One ``run`` command of a log: its thermo table and its 'Loop time' line.

    Parameters
    ----------
    columns : tuple of str
        Thermo column names as printed (``Step``, ``KinEng``, ``v_name`` ...).
    data : (n_rows, n_columns) ndarray of float
        Thermo rows (engine units; SI for every deck bedstruct writes).
    loop_time : float or None
        Wall-clock seconds of the run loop (excludes setup), None if the run
        did not finish.
    n_procs, n_steps, n_atoms : int or None
        From ``Loop time of X on N procs for S steps with A atoms``.
    neighbors_per_atom : float or None
        ``Ave neighs/atom`` printed after the run (half list: contacts + near pairs).
    atoms_per_proc : (float, float, float) or None
        The atoms each rank owned at the end of the run, ``(mean, max, min)`` over the ranks
        (``Nlocal: A ave B max C min`` printed after the run): how evenly the domain
        decomposition shared them.
    """

    columns: tuple[str, ...]
    data: np.ndarray
    loop_time: float | None = None
    n_procs: int | None = None
    n_steps: int | None = None
    n_atoms: int | None = None
    neighbors_per_atom: float | None = None
    atoms_per_proc: tuple[float, float, float] | None = None

    def has_column(self, name: str) -> bool:
        """Whether ``name`` (or its LIGGGHTS/LAMMPS spelling) is a column."""
        return _column_index(self.columns, name) is not None

    def column(self, name: str) -> np.ndarray:
        """The values of thermo column ``name`` (KeyError lists the columns).

        LIGGGHTS prints variables and computes without their ``v_``/``c_``
        prefix (``dist`` for ``v_dist``); either spelling is accepted.
        """
        k = _column_index(self.columns, name)
        if k is None:
            raise KeyError(f"no thermo column {name!r}; columns are {list(self.columns)}")
        return self.data[:, k]


@dataclass(frozen=True)
class EngineLog:
    """A parsed LIGGGHTS or LAMMPS log.

    Parameters
    ----------
    engine : str
        ``"liggghts"``, ``"lammps"`` or ``""`` if the header was not found.
    version : str
        Version text from the first line.
    runs : tuple of ThermoRun
        One entry per ``run`` in order.
    errors : tuple of str
        Lines starting with ``ERROR``.
    warnings : tuple of str
        Lines starting with ``WARNING``. A message whose text is on the indented lines
        below it (LIGGGHTS' ``WARNING:`` paragraphs) is joined into one line.
    """

    engine: str
    version: str
    runs: tuple[ThermoRun, ...]
    errors: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()

    @property
    def last(self) -> ThermoRun:
        """The last run (IndexError if the log has none)."""
        if not self.runs:
            raise IndexError("the log contains no run")
        return self.runs[-1]

    def column(self, name: str) -> np.ndarray:
        """Thermo column ``name`` concatenated over all runs that print it."""
        parts = [r.column(name) for r in self.runs if r.has_column(name)]
        if not parts:
            raise KeyError(f"no run prints thermo column {name!r}")
        return np.concatenate(parts)


_LOOP_RE = re.compile(
    r"^Loop time of\s+(?P<t>[-+0-9.eE]+)\s+on\s+(?P<p>\d+)\s+procs?\s+(?:\(\d+ OpenMP threads\)\s+)?"
    r"for\s+(?P<s>\d+)\s+steps\s+with\s+(?P<a>\d+)\s+atoms")
_NEIGH_RE = re.compile(r"^Ave neighs/atom\s*=\s*(?P<n>[-+0-9.eE]+)")
_NLOCAL_RE = re.compile(r"^Nlocal:\s*(?P<ave>[-+0-9.eE]+)\s+ave\s+(?P<max>[-+0-9.eE]+)\s+max\s+"
                        r"(?P<min>[-+0-9.eE]+)\s+min")
_NUM_RE = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^[-+]?(nan|inf)$", re.IGNORECASE)


def _is_number(tok: str) -> bool:
    return bool(_NUM_RE.match(tok))


def _with(run: ThermoRun, **values) -> ThermoRun:
    """``run`` with ``values`` set (what the log prints after its ``Loop time`` line)."""
    return ThermoRun(**{**{f.name: getattr(run, f.name) for f in fields(run)}, **values})


def parse_log(source) -> EngineLog:
    """Parse a LIGGGHTS 3.x or LAMMPS log file (or its text).

    Thermo tables are recognised by their header line starting with ``Step``;
    rows are the following all-numeric lines with the header's column count
    (``WARNING``/``INFO`` lines inside a table are skipped). Each table is
    closed by its ``Loop time of ...`` line.

    Parameters
    ----------
    source : str or os.PathLike
        A path to a log file, or the log text itself (any string containing
        a newline is taken as text).

    Returns
    -------
    EngineLog

    Examples
    --------
    >>> text = '''LAMMPS (22 Jul 2025 - Update 4)
    ...    Step          KinEng
    ...          0   1.5
    ...         10   0.5
    ... Loop time of 0.25 on 2 procs for 10 steps with 100 atoms
    ... Ave neighs/atom = 6.5
    ... '''
    >>> lg = parse_log(text)
    >>> lg.engine, lg.last.n_steps, lg.last.loop_time, lg.last.column("KinEng").tolist()
    ('lammps', 10, 0.25, [1.5, 0.5])
    >>> lg.last.neighbors_per_atom
    6.5
    >>> two = text.replace("Ave neighs", "Nlocal:  50 ave 51 max 49 min" + chr(10) + "Ave neighs")
    >>> parse_log(two).last.atoms_per_proc    # after the run: (mean, max, min) over the ranks
    (50.0, 51.0, 49.0)
    """
    if isinstance(source, (str, os.PathLike)) and not (isinstance(source, str) and "\n" in source):
        text = Path(source).read_text(errors="replace")
    else:
        text = str(source)
    engine, version = "", ""
    runs: list[ThermoRun] = []
    errors: list[str] = []
    warnings_: list[str] = []
    cols: tuple[str, ...] | None = None
    rows: list[list[float]] = []
    pending: ThermoRun | None = None

    def close(loop=None):
        nonlocal cols, rows, pending
        if cols is None and loop is None:
            return
        data = np.array(rows, dtype=np.float64).reshape(len(rows), len(cols or ()))
        kw = {}
        if loop is not None:
            kw = dict(loop_time=float(loop["t"]), n_procs=int(loop["p"]),
                      n_steps=int(loop["s"]), n_atoms=int(loop["a"]))
        run = ThermoRun(tuple(cols or ()), data, **kw)
        runs.append(run)
        pending = run if loop is not None else None
        cols, rows = None, []

    cont = None   # the message list and index of an ERROR/WARNING whose text follows it
    for raw in text.splitlines():
        line = raw.strip()
        if cont is not None:
            if line and raw[:1].isspace():   # LIGGGHTS: "WARNING: " then indented lines
                msgs, i = cont
                msgs[i] = f"{msgs[i]} {line}"
                continue
            cont = None
        if not line:
            continue
        if not engine:
            if line.startswith("LIGGGHTS"):
                engine, version = "liggghts", line
                continue
            if line.startswith("LAMMPS ("):
                engine, version = "lammps", line
                continue
        if line.startswith(("ERROR", "WARNING")):
            msgs = errors if line.startswith("ERROR") else warnings_
            msgs.append(line)
            if line.endswith(":"):
                cont = (msgs, len(msgs) - 1)
            continue
        m = _LOOP_RE.match(line)
        if m:
            close(m)
            continue
        m = _NLOCAL_RE.match(line)
        if m and runs and pending is runs[-1]:   # before "Ave neighs/atom"
            pending = runs[-1] = _with(pending, atoms_per_proc=(
                float(m["ave"]), float(m["max"]), float(m["min"])))
            continue
        m = _NEIGH_RE.match(line)
        if m and runs and pending is runs[-1]:
            runs[-1] = _with(pending, neighbors_per_atom=float(m["n"]))
            pending = None
            continue
        toks = line.split()
        if toks[0] == "Step" and len(toks) > 1 and not any(_is_number(t) for t in toks[1:]):
            if cols is not None:  # a table with no Loop line (a crash): keep what was read
                close()
            cols, rows = tuple(toks), []
            continue
        if cols is not None and len(toks) == len(cols) and all(_is_number(t) for t in toks):
            rows.append([float(t) for t in toks])
    if cols is not None:
        close()
    return EngineLog(engine, version, tuple(runs), tuple(errors), tuple(warnings_))


# --------------------------------------------------------------------------- spreading records
_OFFSET_LINE = "BEDSTRUCT_OFFSET"
_LOAD_LINE = "BEDSTRUCT_TOOL_FORCE"
_DONE_LINE = "BEDSTRUCT_DONE"


def _log_records(log_path, marker: str, keys) -> dict:
    """``{layer: {key: value}}`` of the ``MARKER layer=K key=value ...`` lines a deck printed
    (the last line of a layer wins; a line with another set of keys is not one of them)."""
    num = r"([-+0-9.eEnaNinf]+)"
    pat = re.compile(rf"^{marker} layer=(\d+)" + "".join(f" {k}={num}" for k in keys) + r"\s*$")
    found = {}
    with open(log_path, errors="replace") as fh:
        for line in fh:
            m = pat.match(line.strip())
            if m:
                found[int(m.group(1))] = {k: float(m.group(i + 2)) for i, k in enumerate(keys)}
    return found


def landing_offsets(log_path, n_layers: int) -> tuple:
    """Steps waited for flying powder to land before each layer's tool motion, in all.

    Reads the ``BEDSTRUCT_OFFSET layer=K steps=N`` lines that
    :func:`spread_layers_deck` prints into the engine's log.

    Parameters
    ----------
    log_path : str or os.PathLike
    n_layers : int

    Returns
    -------
    tuple of int
        One cumulative offset per layer (add it to the layer's planned steps).

    Raises
    ------
    ValueError
        When a layer's line is missing (the run stopped early, or the deck was
        not written by :func:`spread_layers_deck`).
    """
    found = {k: int(round(v["steps"])) for k, v in _log_records(log_path, _OFFSET_LINE,
                                                                ("steps",)).items()}
    missing = [k + 1 for k in range(n_layers) if k + 1 not in found]
    if missing:
        raise ValueError(f"{log_path}: no '{_OFFSET_LINE} layer=K steps=N' line for layer(s) "
                         f"{missing}; the run did not reach their tool motion")
    return tuple(found[k + 1] for k in range(n_layers))


def tool_loads(log_path, n_layers: int) -> tuple:
    """Load of the powder on the tool averaged over each layer's stroke (N), from the log.

    The decks of :func:`spread_layers_deck` print ``BEDSTRUCT_TOOL_FORCE layer=K
    fx=.. fy=.. fz=..`` after each stroke: the force of the particles on the tool
    averaged over the stroke's steps by ``fix ave/time ... ave running`` (LIGGGHTS: the
    tool is a ``mesh/surface/stress``; LAMMPS: the per-atom forces of the tool's
    ``wall/gran/region ... contacts``, summed and negated).

    Returns
    -------
    tuple of (3,) tuple of float
        One per layer; NaN where the log has no line for it.
    """
    found = {k: (v["fx"], v["fy"], v["fz"])
             for k, v in _log_records(log_path, _LOAD_LINE, ("fx", "fy", "fz")).items()}
    nan = (float("nan"),) * 3
    return tuple(found.get(k + 1, nan) for k in range(n_layers))


def run_finished(log_path, n_layers: int) -> bool:
    """Whether the run of a :func:`spread_layers_deck` deck of ``n_layers`` layers got to its end.

    The deck's last command prints ``BEDSTRUCT_DONE layer=K`` (K = ``n_layers``) after
    the dumps of the last layer are closed, so a log holding it belongs to a run that
    finished every layer and left every dump complete; a killed, failed or timed-out
    run, or a missing log, gives False.
    """
    try:
        return n_layers in _log_records(log_path, _DONE_LINE, ())
    except FileNotFoundError:
        return False
