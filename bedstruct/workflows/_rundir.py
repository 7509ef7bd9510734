"""Run folders of the workflows: layout, identity, locking, stage output.

:class:`RunLayout` is the folder of one workflow run: its marker (``run.json``:
workflow, configuration, inputs and status), the resolved configuration, the
results written last, and the check that decides whether a folder is resumed,
refused (another run) or cleared (:func:`clear_run`); a lock keeps two processes
from writing one folder. :class:`StageWriter` writes the frames, contacts and wall
states of one stage. Resuming a stage from its checkpoint, bit for bit, is
:mod:`bedstruct.workflows._resume`.
"""

from __future__ import annotations

import contextlib
import copy
import functools
import json
import logging
import os
import re
import weakref
from pathlib import Path

from .._json import plain, write_json_atomic
from ..errors import ConfigError, RunFolderInUseError
from .config import _refuse_effects_section, config_to_toml
from .schema import WorkflowConfig, config_dict

try:
    import fcntl
except ImportError:  # no flock (Windows): runs in one folder are not guarded against each other
    fcntl = None

log = logging.getLogger("bedstruct.workflows._common")

__all__ = ["RunLayout", "StageWriter", "clear_run", "code_identity", "marks_failure",
           "RUN_MARKER", "RUN_LOCK"]


#: The marker of a run folder: workflow, configuration and inputs of the run, the code that
#: made it (:func:`code_identity`) and its status ("running" until results.json is written,
#: then "complete"; "failed", with the error, when the run stopped on an error).
RUN_MARKER = "run.json"

#: The parts of the package whose code decides a run's results (hashed by
#: :func:`code_identity`): the workflows, the engine, the decks of the external engines, the
#: measurements and the file formats.
_CODE_PARTS = ("workflows", "dem", "engines", "analysis", "core", "io")


@functools.lru_cache(maxsize=1)
def code_identity() -> dict:
    """The code that makes a run: ``{"bedstruct": version, "source": hash}``.

    ``source`` is a SHA-256 (16 hex digits) of the Python sources of the parts of the
    package that decide a run's results (:data:`_CODE_PARTS` and the package's top-level
    private modules; :func:`bedstruct._numba.source_hash`), so that a development build
    edited between two runs differs too. Computed once per process.
    """
    from .._numba import source_hash
    from .._version import __version__
    root = Path(__file__).resolve().parent.parent
    top = [f.name for f in sorted(root.glob("_*.py"))]
    return {"bedstruct": str(__version__), "source": source_hash((*top, *_CODE_PARTS))}


def _code_text(code) -> str:
    if not isinstance(code, dict):
        return "code not recorded"
    return f"bedstruct {code.get('bedstruct', '?')}, code {code.get('source', '?')}"


#: Configuration keys a run may be resumed with other values of (they change what is
#: written, or whether an external engine run is given time to finish, not the results).
_RESUME_FREE = (("output", "checkpoint"), ("output", "checkpoint_every"), ("external", "timeout"))

#: Keys that enter a run's identity only off their default: a run folder whose configuration
#: lacks them ran as with the default (its runs resume).
_DEFAULT_FREE = (("psd", "diameters", []), ("psd", "volume_fractions", []),
                 ("spread", "side_walls", False))

#: The lock file of a run folder: held (``flock``) by the process writing the run.
RUN_LOCK = ".bedstruct.lock"


_held_locks: "weakref.WeakValueDictionary[str, _FolderLock]" = weakref.WeakValueDictionary()


class _FolderLock:
    """An exclusive ``flock`` on ``<folder>/.bedstruct.lock``, released when this object is
    released or collected, or when its process ends (killed too: the kernel drops it).

    The lock file exists only while a run holds it: it is removed, still locked, when the
    lock is released. A process that opened the file before it was removed and locks it
    afterwards sees that the path no longer names its file and opens the path anew.
    """

    def __init__(self, folder: Path):
        self.path = folder / RUN_LOCK
        while True:
            self._file = open(self.path, "a+")
            try:
                fcntl.flock(self._file.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                self._file.seek(0)
                holder = self._file.read().strip() or "another process"
                self._file.close()
                raise RunFolderInUseError(
                    f"{folder} is in use: a run is being written there ({holder}). Wait for it "
                    "to end, or choose another --out.") from None
            try:
                same = os.stat(self.path).st_ino == os.fstat(self._file.fileno()).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            self._file.close()  # locked a file its holder had just removed: try the path again
        self._file.seek(0)
        self._file.truncate()
        self._file.write(f"pid {os.getpid()}\n")
        self._file.flush()

    def release(self) -> None:
        if not self._file.closed:
            try:
                os.unlink(self.path)  # while still held, so that no one locks a stale file
            except FileNotFoundError:
                pass
            self._file.close()  # closing the file drops the flock

    def __del__(self):
        self.release()


def _lock_folder(folder: Path):
    """The lock of run folder ``folder`` for this process (shared by the layouts of one
    process, which may reopen a folder; another process gets RunFolderInUseError)."""
    if fcntl is None:
        return None
    key = str(folder.resolve())
    lock = _held_locks.get(key)
    if lock is None or lock._file.closed:
        lock = _FolderLock(folder)
        _held_locks[key] = lock
    return lock


_STAGE_DIR = re.compile(r"^(rep\d+|layer\d+|pile|k[0-9.eE+-]+)$")
_RUN_FILES = (RUN_MARKER, "config.toml", "results.json", "progress.npz", "points.json")


def _identity(workflow: str, cfg: dict, inputs) -> dict:
    c = copy.deepcopy(cfg)
    for sec, key in _RESUME_FREE:
        if isinstance(c.get(sec), dict):
            c[sec].pop(key, None)
    for sec, key, default in _DEFAULT_FREE:
        if isinstance(c.get(sec), dict) and c[sec].get(key, default) == default:
            c[sec].pop(key, None)
    return plain({"workflow": workflow, "config": c, "inputs": dict(inputs or {})})


def _differences(old, new, prefix: str = "") -> list[str]:
    """``key: old -> new`` for every leaf that differs between two nested mappings."""
    out = []
    for k in sorted(set(old) | set(new), key=str):
        a, b = old.get(k, "(missing)"), new.get(k, "(missing)")
        name = f"{prefix}{k}"
        if isinstance(a, dict) and isinstance(b, dict):
            out += _differences(a, b, prefix=f"{name}.")
        elif a != b:
            out.append(f"`{name}`: {a!r} in the folder, {b!r} now")
    return out


_TOML_HEADER = "# bedstruct workflow configuration"


def _is_run_toml(path: Path) -> bool:
    """``path`` is a config.toml written by :func:`~bedstruct.workflows.config_to_toml`."""
    try:
        with open(path) as fh:
            return fh.readline().startswith(_TOML_HEADER)
    except (OSError, UnicodeDecodeError):
        return False


def clear_run(path) -> None:
    """Remove a bedstruct run from folder ``path`` (``--overwrite``): its marker,
    configuration, results, checkpoints and stage folders (``rep*``, ``layer*``,
    ``pile``, ``k<cohesion>``). Other files are left alone; a folder that holds no run
    (no ``run.json`` or ``config.toml``) is not touched."""
    import shutil
    path = Path(path)
    if not ((path / RUN_MARKER).is_file() or _is_run_toml(path / "config.toml")):
        return
    for name in _RUN_FILES:
        (path / name).unlink(missing_ok=True)
    for p in path.iterdir():
        if p.is_dir() and _STAGE_DIR.match(p.name):
            shutil.rmtree(p)
        elif p.is_file() and p.name.startswith(".") and p.name.endswith(".tmp"):
            p.unlink()
    log.info("%s: the earlier run was removed (overwrite)", path)


class RunLayout:
    """The folder of one workflow run.

    Layout::

        OUT/run.json               workflow, configuration, inputs, code and status of the
                                   run ("running" until the results are written, then
                                   "complete"; "failed" with the error, or "interrupted")
        OUT/config.toml            the resolved configuration
        OUT/results.json           results (written atomically, last; removed when a run starts)
        OUT/progress.npz           spreading: the resume checkpoint (removed at the end)
        OUT/<stage>/frames.dump.gz LIGGGHTS dump custom frames (SI, ITEM: UNITS si)
        OUT/<stage>/contacts.dump.gz  pair/gran/local dump local of the same timesteps
        OUT/<stage>/walls.jsonl    wall (plate, blade, roller) position/velocity/force per frame
        OUT/<stage>/final.dump.gz, final_contacts.dump.gz  the state at the end of the stage
        OUT/<stage>/progress.npz   resume checkpoint of an unfinished repose replicate
        OUT/<stage>/result.json    a finished repose replicate (reused when resuming)
        OUT/<stage>/checkpoint.npz engine checkpoint at the end of the stage
                                   (output.checkpoint = true)
        OUT/.bedstruct.lock        held by the process writing the run; removed when the
                                   results are written

    ``<stage>`` is ``rep00``, ``rep01``... for repose replicates,
    ``pile`` and ``layer01``... for spreading, ``k<value>/rep00`` for
    calibration points.

    Parameters
    ----------
    path : path
        The run folder (created).
    cfg : dict or WorkflowConfig, optional
        The resolved configuration (a WorkflowConfig is written as its dict,
        :func:`~bedstruct.workflows.schema.config_dict`). Without it the folder is only
        created.
    workflow : str
        ``"repose"``, ``"spread"``, ``"calibrate"`` ("" for callers that do not resume).
    inputs : dict, optional
        What else decides the results (arguments beyond the configuration).
    overwrite : bool
        Remove an earlier run in the folder first (:func:`clear_run`).

    Raises
    ------
    ConfigError
        The folder holds a run of another workflow, configuration or inputs (the message
        lists the differences), or one made by other code (another bedstruct version or
        source, :func:`code_identity`; finished or not), and ``overwrite`` is false.
    RunFolderInUseError
        Another process is writing a run in the folder (it holds the folder's lock,
        ``.bedstruct.lock``, until its run ends, fails or is killed).

    Notes
    -----
    A folder that holds a run of the same workflow, configuration (``output.checkpoint``,
    ``output.checkpoint_every`` and ``external.timeout`` aside), inputs and code is resumed:
    :attr:`resumed` is true and the workflow reuses what was finished (:attr:`complete`:
    all of it, with :attr:`previous_results`; :meth:`reuse_results`). Either way
    ``results.json`` is removed before anything runs and ``run.json`` says ``"running"``
    until the new results are written, so a stale result never sits beside a new
    configuration.
    """

    def __init__(self, path, cfg=None, *, workflow: str = "", inputs=None,
                 overwrite: bool = False):
        self.path = Path(path)
        if isinstance(cfg, WorkflowConfig):
            cfg = config_dict(cfg)
        self.cfg = cfg
        self.workflow = workflow
        self.resumed = False
        self.complete = False
        self.previous_results = None
        self._lock = None
        self._written = False
        if cfg is None:
            self.path.mkdir(parents=True, exist_ok=True)
            return
        self.path.mkdir(parents=True, exist_ok=True)
        # before anything is read or cleared: two processes must not resume, overwrite or
        # write one folder at the same time
        self._lock = _lock_folder(self.path)
        if overwrite:
            clear_run(self.path)
        self._identity = _identity(workflow, cfg, inputs)
        self._check_previous()
        (self.path / "results.json").unlink(missing_ok=True)
        self._mark("running")
        (self.path / "config.toml").write_text(config_to_toml(cfg))

    def _check_previous(self) -> None:
        marker = self.path / RUN_MARKER
        hint = (" Resume it with the same configuration, choose another --out, or pass "
                "--overwrite (overwrite=True) to replace it.")
        if marker.is_file():
            try:
                old = json.loads(marker.read_text())
                # normalised as now: a marker written before a key became resume-free matches
                ident = _identity(old["workflow"], old["config"], old["inputs"])
                status = old["status"]
            except (ValueError, KeyError, TypeError, AttributeError) as exc:
                raise ConfigError(f"{marker}: not a readable run marker ({exc}).{hint}") from None
            try:
                _refuse_effects_section(old["config"])
            except ConfigError as exc:
                raise ConfigError(f"{marker}: the folder's run has {exc}.{hint}") from None
            if ident != self._identity:
                diff = []
                if ident["workflow"] != self._identity["workflow"]:
                    diff.append(f"workflow: {ident['workflow'] or '?'} in the folder, "
                                f"{self._identity['workflow'] or '?'} now")
                diff += _differences(ident["config"], self._identity["config"])
                diff += _differences({"inputs": ident["inputs"]},
                                     {"inputs": self._identity["inputs"]})
                shown = "; ".join(diff[:6]) + (f"; and {len(diff) - 6} more" if len(diff) > 6 else "")
                raise ConfigError(f"{self.path} holds another run ({shown}).{hint}")
            if old.get("code") != code_identity():
                done = status == "complete"
                raise ConfigError(
                    f"{self.path} holds {'a finished' if done else 'an unfinished'} run of this "
                    f"configuration made by other code ({_code_text(old.get('code'))} in the "
                    f"folder; {_code_text(code_identity())} now): "
                    + ("its results are not this code's. " if done else
                       "resuming it would mix stages of both. ")
                    + "Pass --overwrite (overwrite=True) to run it again with this code, or "
                    "choose another --out.")
            self.resumed = True
            self.complete = status == "complete"
            res = self.path / "results.json"
            if self.complete and res.is_file():
                try:
                    self.previous_results = json.loads(res.read_text())
                except ValueError:
                    self.complete = False
            else:
                self.complete = False
            log.info("%s: resuming the %s run found there (%s)", self.path, self.workflow,
                     "complete" if self.complete else "unfinished")
            return
        toml = self.path / "config.toml"
        if toml.is_file() and not _is_run_toml(toml):
            raise ConfigError(f"{toml} was not written by bedstruct; a run would replace it: "
                              "choose another --out")
        if toml.is_file():  # a folder written before run.json existed: no resume data
            import tomllib
            from .config import load_config
            try:
                old_cfg = load_config(tomllib.loads(toml.read_text()))
            except (ConfigError, ValueError) as exc:
                raise ConfigError(f"{toml}: the folder holds a run whose configuration cannot "
                                  f"be read ({exc}).{hint}") from None
            old = _identity(self.workflow, old_cfg, self._identity["inputs"])
            if old["config"] != self._identity["config"]:
                diff = _differences(old["config"], self._identity["config"])
                raise ConfigError(f"{self.path} holds another run ({'; '.join(diff[:6])})."
                                  f"{hint}")
            log.info("%s: an earlier run of this configuration (without resume data) is "
                     "replaced", self.path)

    def _mark(self, status: str, **extra) -> None:
        write_json_atomic(self.path / RUN_MARKER, {"status": status, **self._identity,
                                                   "code": code_identity(), **extra},
                          keep_nan=True)

    def fail(self, error: BaseException) -> None:
        """Mark the run failed (``run.json``: status ``"failed"`` and the error) and release
        the folder; an interrupt (Ctrl-C, a stop signal raised as ``KeyboardInterrupt`` or
        ``SystemExit``) marks it ``"interrupted"``. Running it again resumes it, as an
        unfinished run."""
        if self.cfg is not None and not self._written:
            if isinstance(error, Exception):
                self._mark("failed", error=f"{type(error).__name__}: {error}")
            else:
                self._mark("interrupted", error=type(error).__name__)
        self.release()

    def reuse_results(self, from_dict):
        """The result of the complete run resumed here, or None.

        ``from_dict(previous_results)`` rebuilds the result; its ``results.json`` is
        written back (the run is complete again) and nothing needs to run. None when the
        run is not complete, or when its results cannot be read back (then it runs again).
        """
        if not self.complete:
            return None
        try:
            res = from_dict(self.previous_results)
        except (KeyError, TypeError, ValueError) as exc:
            log.warning("%s: the finished run's results cannot be read back (%s); it runs "
                        "again", self.path, exc)
            return None
        self.write_results(self.previous_results)
        return res

    def stage(self, name: str, *, reset: bool = True) -> "StageWriter":
        out = self.cfg["output"] if self.cfg else {"frames": True, "contacts": True,
                                                    "compress": True, "checkpoint": False}
        return StageWriter(self.path / name, out, reset=reset)

    def write_results(self, data) -> Path:
        """Write ``results.json`` atomically, then mark the run complete."""
        p = write_json_atomic(self.path / "results.json", data)
        if self.cfg is not None:
            self._mark("complete")
            self._written = True
        self.release()
        return p

    def release(self) -> None:
        """Release the folder's lock (done by :meth:`write_results`, and when the layout is
        collected or its process ends)."""
        self._lock = None  # the last layout of this process holding it lets it go


@contextlib.contextmanager
def marks_failure(layout: RunLayout | None):
    """A block whose exception (or interrupt) marks ``layout``'s run folder failed
    (:meth:`RunLayout.fail`) before it propagates; nothing with ``layout`` None.

    Examples
    --------
    >>> import tempfile, json
    >>> from pathlib import Path
    >>> from bedstruct.workflows import load_config
    >>> from bedstruct.workflows._rundir import RunLayout, marks_failure
    >>> out = Path(tempfile.mkdtemp()) / "run"
    >>> layout = RunLayout(out, load_config(preset="tiny"), workflow="repose")
    >>> try:
    ...     with marks_failure(layout):
    ...         raise KeyboardInterrupt
    ... except KeyboardInterrupt:
    ...     pass
    >>> json.loads((out / "run.json").read_text())["status"]
    'interrupted'
    """
    try:
        yield layout
    except (Exception, KeyboardInterrupt, SystemExit) as exc:   # a kill leaves "running"
        if layout is not None:
            layout.fail(exc)
        raise


class StageWriter:
    """Writes frames, contacts and wall states of one stage (see :class:`RunLayout`).

    With ``reset`` (default) earlier frames, contacts and wall states of the stage are
    removed (:meth:`reset`); a resumed stage keeps them.
    """

    def __init__(self, path: Path, out: dict, *, reset: bool = True):
        self.path = Path(path)
        self.path.mkdir(parents=True, exist_ok=True)
        self.out = out
        ext = ".dump.gz" if out.get("compress", True) else ".dump"
        self.frames_path = self.path / f"frames{ext}"
        self.contacts_path = self.path / f"contacts{ext}"
        self.walls_path = self.path / "walls.jsonl"
        self._ext = ext
        if reset:
            self.reset()

    def reset(self) -> None:
        """Remove the stage's frames, contacts and wall states (a stage that starts over)."""
        for p in (self.frames_path, self.contacts_path, self.walls_path):
            if p.exists():
                p.unlink()

    def record(self, sim, *, frame=None) -> None:
        """Append the current frame (``ITEM: UNITS si``), contacts and wall states of ``sim``."""
        from ..dem.output import write_walls
        from ..io import write_dump, write_dump_local
        frame = sim.frame() if frame is None else frame
        if self.out.get("frames", True):
            write_dump(self.frames_path, frame, append=self.frames_path.exists(), units_item=True)
        if self.out.get("contacts", True):
            write_dump_local(self.contacts_path, frame, sim.contacts(),
                             append=self.contacts_path.exists())
        write_walls(self.walls_path, sim)

    def write_frame(self, name: str, frame, contacts=None) -> None:
        """Write ``<name>.dump.gz`` (and ``<name>_contacts.dump.gz``) atomically (as
        :func:`bedstruct.io.write_dump` writes every file)."""
        from ..io import write_dump, write_dump_local
        write_dump(self.path / f"{name}{self._ext}", frame, units_item=True)
        if contacts is not None:
            write_dump_local(self.path / f"{name}_contacts{self._ext}", frame, contacts)

    def final(self, sim, name: str = "final"):
        """Write the final state (atoms and contacts) and a checkpoint when configured."""
        frame = sim.frame()
        self.write_frame(name, frame, sim.contacts())
        if self.out.get("checkpoint", False):
            sim.save_checkpoint(self.path / "checkpoint.npz")
        return frame
