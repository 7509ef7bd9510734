"""A run library: the simulator runs of a diagnosis, run once into a folder on disk.

A diagnosis asks its simulator for the same kind of runs every time: the base point,
finite-difference steps of the recalibrated base parameters, each catalogue effect at a
few magnitudes, all at a few replicate seeds. Here those runs form a *design* run once
per simulator configuration, catalogue, observable design and code version, and an
emulator (:mod:`bedstruct.diagnose.emulator`) then serves every diagnosis from it.

The design (:mod:`bedstruct.diagnose.run_design`: :func:`design_spec`,
:func:`design_points`) is space-filling over the varied base parameters and the
catalogue effects' magnitudes, with replicate seeds for the run-to-run noise.

:func:`build_library` runs the design into a folder: ``library.json`` holds the
library key and the design; ``runs/<hash>.json`` one file per run (inputs, seed,
observations), written atomically as each run finishes, so a build that is killed
resumes where it stopped without redoing a finished run. The library key hashes what
the runs depend on (:func:`library_key_document`): the simulator's identity and
configuration, the catalogue's effects, the observables' kinds and conditions, the
bedstruct version and a hash of the source code of the engine and the observation
operators. A library whose key differs from the current one is refused with a message
naming what differs (:class:`StaleLibraryError`), never reused.

The simulator's part of the key: the settings of
:class:`~bedstruct.diagnose.SurrogateSimulator` and
:class:`~bedstruct.diagnose.engine_simulator.EngineSimulator` (and of their subclasses);
for any other simulator what its ``library_identity()`` method returns (JSON data: every
setting its runs depend on; an optional ``library_code`` attribute names package source
files they depend on), else its public attributes (a :func:`functools.partial`'s function
and arguments; attributes named ``_...`` are internal state, left out), which must then
have a JSON form: a simulator whose state has none is refused, asking for
``library_identity()``. The source file that defines a simulator outside the package is
hashed into the key's ``code``.

Runs execute in local worker processes (``spawn``-ed, exiting with the build's process)
or, with ``scheduler="tcp://host:port"`` (or a :class:`distributed.Client`), on a Dask
distributed cluster. One build works in a folder at a time (``build.lock``).

.. versionadded:: 0.1
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import json
import logging
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from .._json import to_jsonable, write_json_atomic
from .._numba import source_hash
from .._version import __version__
from ..errors import ConfigError
from .catalogue import catalogue as _catalogue
from .measurements import Observations
from .observables_registry import observable_kinds
from .run_design import DesignPoint, DesignSpec, design_points

__all__ = ["RunLibrary", "StaleLibraryError", "build_library", "load_library",
           "library_key_document", "library_key"]

log = logging.getLogger(__name__)

#: Version of the library's file layout (``library.json`` and the run files).
LIBRARY_SCHEMA = 1
_ROOT = Path(__file__).resolve().parents[1]   # the bedstruct package
#: Source the runs of each simulator kind depend on, relative to the package: the engine
#: and its workflows, the analyses the observation operators call, the operators, the
#: catalogue. A change to any of it makes a library stale.
_CODE = {
    "surrogate": ("diagnose/surrogate.py", "diagnose/catalogue.py", "diagnose/measurements.py"),
}


class StaleLibraryError(ConfigError):
    """A run library whose key differs from the current one (its message names what differs)."""


# ----------------------------------------------------------------------------- keys
def _hash(obj) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:20]


def _code_hash(rel: str) -> str:
    """Hash of a source file or folder of the package (its ``*.py`` and ``*.toml`` files)."""
    return source_hash((rel,), suffixes=(".py", ".toml"))


class _Unkeyable(Exception):
    """A part of a simulator's state with no JSON form (its path and type)."""


def _file_hash(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:20]


def _source_file(obj) -> Path | None:
    """The source file that defines ``obj`` (a function, or the class of an object)."""
    target = obj if inspect.isfunction(obj) or inspect.isclass(obj) else type(obj)
    try:
        f = inspect.getsourcefile(target)
    except (OSError, TypeError):
        return None
    return Path(f).resolve() if f and Path(f).is_file() else None


def _source_code(obj) -> dict[str, str]:
    """``{"simulator_source": hash}`` of the file defining ``obj`` when that file lies
    outside the package (the package's own code is keyed by its relative paths)."""
    f = _source_file(obj)
    if f is None or _ROOT in f.parents:
        return {}
    return {"simulator_source": _file_hash(f)}


def _is_simulator(obj) -> bool:
    from .engine_simulator import EngineSimulator
    from .surrogate import SurrogateSimulator
    return (isinstance(obj, (SurrogateSimulator, EngineSimulator, functools.partial))
            or getattr(obj, "library_identity", None) is not None)


def _state(value, where: str):
    """The JSON form of a piece of a simulator's state, for its library key."""
    from .measurements import MeasurementSet
    if isinstance(value, MeasurementSet):
        return "observables"   # keyed in the key document's own section
    if _is_simulator(value):
        return _simulator_identity(value)[0]
    if isinstance(value, Mapping):
        return {str(k): _state(v, f"{where}[{k!r}]") for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_state(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if inspect.isfunction(value) or inspect.isbuiltin(value):
        return _function_identity(value)
    try:
        return to_jsonable(value, keep_nonfinite=True)
    except (TypeError, ValueError) as exc:
        raise _Unkeyable(f"{where} (a {type(value).__name__})") from exc


def _function_identity(fn) -> dict:
    ident: dict[str, Any] = {"function": f"{getattr(fn, '__module__', '')}."
                                         f"{getattr(fn, '__qualname__', repr(fn))}"}
    try:
        ident["source"] = hashlib.sha256(inspect.getsource(fn).encode()).hexdigest()[:20]
    except (OSError, TypeError):
        ident["source"] = None
    return ident


def _instance_state(obj, skip: Sequence[str] = ()) -> dict:
    """The public attributes of ``obj`` (but its ``design``, ``name`` and ``skip``) as JSON
    (an attribute whose name starts with ``_`` is internal state, not a setting)."""
    attrs = getattr(obj, "__dict__", None)
    if attrs is None:
        slots = [n for c in type(obj).__mro__ for n in getattr(c, "__slots__", ())]
        attrs = {n: getattr(obj, n) for n in slots if hasattr(obj, n)}
    return {k: _state(v, k) for k, v in sorted(attrs.items())
            if k not in ("design", "name", *skip) and not k.startswith("_")}


def _simulator_identity(simulator) -> tuple[dict, tuple[str, ...], dict[str, str]]:
    """The simulator's identity document, the package source its runs depend on
    (package-relative paths) and the hashes of its own source outside the package.

    A simulator states its identity with a ``library_identity()`` method (JSON data:
    every setting its runs depend on) and, optionally, ``library_code`` (package-relative
    source paths). :class:`~bedstruct.diagnose.SurrogateSimulator` and
    :class:`~bedstruct.diagnose.engine_simulator.EngineSimulator` (and their subclasses)
    are keyed by their settings. A :func:`functools.partial` is keyed by its function and
    arguments; any other callable by its attributes, which must then have a JSON form.
    The file that defines the simulator is hashed when it lies outside the package.
    """
    from .engine_simulator import EngineSimulator
    from .surrogate import SurrogateSimulator
    cls = type(simulator)
    ident: dict[str, Any] = {"name": getattr(simulator, "name", cls.__name__),
                             "class": f"{cls.__module__}.{cls.__qualname__}"}
    try:
        own = getattr(simulator, "library_identity", None)
        if own is not None:   # a simulator that states its own identity
            ident["config"] = to_jsonable(own())
            return ident, tuple(getattr(simulator, "library_code", ())), _source_code(simulator)
        if isinstance(simulator, SurrogateSimulator):
            ident["config"] = {"noise": simulator.noise, "correlation": simulator.correlation}
            if cls is not SurrogateSimulator:
                ident["state"] = _instance_state(simulator, ("noise", "correlation"))
            return ident, _CODE["surrogate"], _source_code(simulator)
        if isinstance(simulator, EngineSimulator):
            from . import engine_cache
            ident["config"] = {
                "preset": simulator.preset, "overrides": list(simulator.overrides),
                "resolved_config": to_jsonable(simulator.base_cfg, keep_nonfinite=False),
                "scales": {k: getattr(simulator, k) for k in (
                    "cohesion_scale", "speed_scale", "ageing_time_scale", "blade_time_scale",
                    "capillary_scale", "fines_scale", "wide_box", "seed_offset")},
                "cache_schema": engine_cache._CACHE_SCHEMA,
                "model_revisions": dict(engine_cache._MODEL_REVISIONS),
                "deck_revision": engine_cache._DECK_REVISION}
            if simulator.options:   # options set on every call (none: the key as without)
                ident["config"]["options"] = to_jsonable(simulator.options, keep_nonfinite=True)
            return (ident, tuple(engine_cache._CODE["engine"])
                    + tuple(engine_cache._CODE["observation"]), _source_code(simulator))
        if isinstance(simulator, functools.partial):
            inner, code, own_code = _simulator_identity(simulator.func)
            ident["function"] = inner
            ident["args"] = _state(list(simulator.args), "args")
            ident["keywords"] = _state(dict(simulator.keywords), "keywords")
            ident["state"] = _instance_state(simulator)
            return ident, code, own_code
        if inspect.isfunction(simulator):
            ident.update(_function_identity(simulator))
            return ident, ("diagnose/catalogue.py",), _source_code(simulator)
        # any other callable: its class's source and its attributes
        ident["source"] = _function_identity(cls)["source"]
        ident["state"] = _instance_state(simulator)
        return ident, ("diagnose/catalogue.py",), _source_code(simulator)
    except _Unkeyable as exc:
        raise ConfigError(
            f"run library: the simulator {ident['name']!r} ({ident['class']}) cannot be keyed: "
            f"its state {exc} has no JSON form, so a library of other settings could be "
            f"reused for it; give it a library_identity() method that returns every setting "
            f"its runs depend on (see bedstruct.diagnose.run_library.build_library)") from None


def _observables_document(design) -> dict:
    out = {}
    for m in design:
        d: dict[str, Any] = {"kind": m.kind, "conditions": to_jsonable(m.conditions.as_dict()),
                             "n_components": int(m.n_components)}
        if m.windows is not None:
            d["windows"] = np.asarray(m.windows, float).round(12).tolist()
        if m.percentiles is not None:
            d["percentiles"] = np.asarray(m.percentiles, float).tolist()
        kind = {k.name: k for k in observable_kinds()}.get(m.kind)
        if kind is not None and kind.user:   # a user kind: its function and source hash
            d["function"] = kind.source
        out[m.name] = d
    return out


def library_key_document(simulator, spec: DesignSpec, *, design=None) -> dict:
    """What a run library's runs depend on, section by section.

    Parameters
    ----------
    simulator : callable
        The simulator (``sim(base, effects, seed) -> Observations``); its ``design``
        attribute, if any, gives the observables.
    spec : DesignSpec
        The design (its effects name the catalogue entries the key covers).
    design : MeasurementSet, optional
        The observables, when the simulator has no ``design`` attribute.

    Returns
    -------
    dict
        ``simulator`` (name, class, configuration), ``catalogue`` (each effect's
        magnitude, unit, prior and engine map), ``observables`` (kind, conditions,
        windows, percentiles of each), ``bedstruct_version``, ``code`` (a hash of each
        source file or folder the runs depend on), ``schema``.
    """
    design = design if design is not None else getattr(simulator, "design", None)
    if design is None:
        raise ConfigError("library key: the simulator has no `design` attribute; pass design=")
    ident, code, own_code = _simulator_identity(simulator)
    cat = {}
    for e in _catalogue(spec.effects):
        cat[e.name] = {"magnitude": e.magnitude, "unit": e.unit, "prior": list(e.prior),
                       "signed": e.signed, "engine_map": to_jsonable(e.engine_map)}
    return {"schema": LIBRARY_SCHEMA, "simulator": ident, "catalogue": cat,
            "observables": _observables_document(design), "bedstruct_version": __version__,
            "code": {**{rel: _code_hash(rel) for rel in code}, **own_code}}


def library_key(document: Mapping) -> str:
    """The library key: a hash of :func:`library_key_document`."""
    return _hash(document)


def _differences(old: Mapping, new: Mapping, prefix: str = "", limit: int = 6) -> list[str]:
    out: list[str] = []
    for k in sorted(set(old) | set(new), key=str):
        path = f"{prefix}{k}"
        if k not in old:
            out.append(f"{path} (new)")
        elif k not in new:
            out.append(f"{path} (gone)")
        elif isinstance(old[k], Mapping) and isinstance(new[k], Mapping):
            out += _differences(old[k], new[k], path + ".", limit)
        elif json.dumps(old[k], sort_keys=True, default=str) != json.dumps(new[k], sort_keys=True,
                                                                          default=str):
            a, b = (json.dumps(x, default=str) for x in (old[k], new[k]))
            out.append(f"{path}: {a[:40]} -> {b[:40]}" if len(a) + len(b) < 90 else path)
        if len(out) >= limit:
            return out[:limit] + ["..."]
    return out


# ----------------------------------------------------------------------------- library
@dataclass(frozen=True)
class RunLibrary:
    """The runs of a library folder.

    Attributes
    ----------
    path : Path
        The library folder.
    key : str
        Library key (see :func:`library_key_document`).
    key_document : dict
        What the key hashes.
    spec : DesignSpec
    points : tuple of DesignPoint
        The design's points.
    names : tuple of str
        Observable names, in component order.
    n_components : dict of str to int
    inputs : (N, d) ndarray
        Each run's inputs over :attr:`DesignSpec.input_names` (SI; effect magnitudes in
        their catalogue units).
    point_index : (N,) ndarray of int
        Each run's design point.
    seeds : (N,) ndarray of int
    outputs : (N, n) ndarray
        Each run's observations, components of :attr:`names` concatenated (NaN where a run
        could not observe a component).
    source : str
        The simulator's name.
    n_new : int
        Runs made by the call that returned this library (0 when loaded).
    wall_s : float
        Wall time of that call, s.
    run_wall_s, run_cpu_s : (N,) ndarray
        Wall and CPU time of each run in its process, s (NaN where not recorded).
    """

    path: Path
    key: str
    key_document: dict
    spec: DesignSpec
    points: tuple
    names: tuple
    n_components: dict
    inputs: np.ndarray
    point_index: np.ndarray
    seeds: np.ndarray
    outputs: np.ndarray
    source: str = ""
    n_new: int = 0
    wall_s: float = 0.0
    run_wall_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    run_cpu_s: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def n_runs(self) -> int:
        return int(len(self.seeds))

    @property
    def complete(self) -> bool:
        """Whether every run of the design is in the folder."""
        return self.n_runs == len(self.points) * self.spec.replicates


def _run_name(key: str, point: DesignPoint, seed: int) -> str:
    return _hash([key, point.base, point.effects, int(seed)]) + ".json"


def _run_one(simulator, point: DesignPoint, seed: int) -> dict:
    t0, c0 = time.perf_counter(), time.process_time()
    obs = simulator(dict(point.base), dict(point.effects), int(seed))
    if not isinstance(obs, Observations):
        raise TypeError(f"the simulator must return an Observations object; got {type(obs).__name__}")
    return {"observations": {k: np.asarray(v, float).tolist() for k, v in obs.values.items()},
            "source": obs.source, "wall_s": time.perf_counter() - t0,
            "cpu_s": time.process_time() - c0}


def _run_costs(simulator, todo: list) -> dict[int, float]:
    """The simulator's estimate of the cost of each design point of ``todo`` (runs
    ``(index, point, seed)``), by point index: ``relative_cost(base, effects)`` where the
    simulator has that method, else 1 for every point. An estimate that is not a positive
    finite number is a ConfigError naming the point (it would order the runs and move the
    progress bar wrongly)."""
    points = {i: p for i, p, _ in todo}   # each point once, whatever its seeds
    cost = getattr(simulator, "relative_cost", None)
    if cost is None:
        return dict.fromkeys(points, 1.0)
    out = {}
    for i, p in points.items():
        c = float(cost(dict(p.base), dict(p.effects)))
        if not (math.isfinite(c) and c > 0.0):
            raise ConfigError(f"{type(simulator).__name__}.relative_cost gave {c!r} for design "
                              f"point {i} (effects {dict(p.effects)}): a run's cost estimate "
                              "must be a positive finite number")
        out[i] = c
    return out


def _longest_first(simulator, todo: list, costs: dict[int, float] | None = None) -> list:
    """The runs ``(index, point, seed)`` in decreasing order of the simulator's estimate of
    their cost (:func:`_run_costs`, or ``costs`` by point index; design order among equals
    and without an estimate), so that no worker is left running a long run alone at the
    end of a build."""
    if len(todo) < 2 or (costs is None and getattr(simulator, "relative_cost", None) is None):
        return list(todo)
    rel = _run_costs(simulator, todo) if costs is None else costs
    return sorted(todo, key=lambda t: -rel[t[0]])


def _read_meta(path: Path) -> dict:
    """A library folder's ``library.json``; a ConfigError naming it when it is unreadable."""
    f = path / "library.json"
    try:
        meta = json.loads(f.read_text())
        if not isinstance(meta, dict) or not all(k in meta for k in ("key", "key_document",
                                                                     "spec")):
            raise ValueError("no key, key_document or spec")
        DesignSpec.from_json(meta["spec"])
        meta["key_document"]["observables"]
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as exc:
        raise ConfigError(f"run library {path}: {f} is unreadable ({type(exc).__name__}: "
                          f"{exc}); it holds the library's key and design, so the runs cannot "
                          f"be used without it: remove the folder and build it again") from None
    return meta


def _check_key(path: Path, key: str, doc: Mapping, spec: DesignSpec) -> None:
    meta = _read_meta(path)
    if meta.get("key") != key:
        diff = _differences(meta.get("key_document", {}), doc)
        raise StaleLibraryError(
            f"run library {path}: key {meta.get('key')} differs from the current key {key} in "
            f"{'; '.join(diff) or 'its key document'}; it is stale and not reused (build a new "
            f"library in another folder, or remove this one)")
    old = DesignSpec.from_json(meta["spec"])
    if old != spec:
        diff = _differences(old.to_json(), spec.to_json())
        raise ConfigError(f"run library {path}: its design differs from the one asked for in "
                          f"{'; '.join(diff)}; build the new design in another folder")


#: Sections of a library's key document that a replay lets differ (the code it was made by)
_REPLAY_SECTIONS = ("code", "bedstruct_version")


def _check_replay(path: Path, meta: Mapping, doc: Mapping) -> None:
    """Refuse a library to be replayed unless its key document equals ``doc`` outside
    :data:`_REPLAY_SECTIONS`; warn naming the code that differs."""
    old = dict(meta.get("key_document", {}))
    if meta.get("key") != library_key(old):
        raise StaleLibraryError(f"run library {path}: its key is not the hash of its key "
                                f"document (library.json edited); it cannot be replayed")

    def beyond_code(d: Mapping) -> dict:
        return {k: v for k, v in d.items() if k not in _REPLAY_SECTIONS}

    if beyond_code(old) != beyond_code(doc):
        diff = _differences(beyond_code(old), beyond_code(doc))
        raise StaleLibraryError(
            f"run library {path}: made for another simulator, catalogue or design, not only "
            f"by other code ({'; '.join(diff) or 'its key document'}); it cannot be replayed")
    diff = _differences({k: old.get(k) for k in _REPLAY_SECTIONS},
                        {k: doc.get(k) for k in _REPLAY_SECTIONS})
    if diff:
        log.warning("run library %s: replayed as recorded, made by other code (%s)", path,
                    "; ".join(diff))


class _CostBar:
    """A progress bar over a build's runs that advances by each run's estimated cost
    (:func:`_run_costs`), so that its remaining time holds when the costly runs go first;
    the runs done are shown beside it (``run library (12/50 runs)``)."""

    def __init__(self, todo: list, costs: dict[int, float]):
        from tqdm import tqdm
        self.n = len(todo)
        self.done = 0
        self.costs = costs
        self.bar = tqdm(total=sum(costs[i] for i, _, _ in todo), desc=self._desc(),
                        bar_format="{desc}: {percentage:3.0f}%|{bar}| [{elapsed}<{remaining}]")

    def _desc(self) -> str:
        return f"run library ({self.done}/{self.n} runs)"

    def update(self, i: int) -> None:
        self.done += 1
        self.bar.set_description_str(self._desc(), refresh=False)
        self.bar.update(self.costs[i])

    def close(self) -> None:
        self.bar.close()


def build_library(simulator, design_spec: DesignSpec, out_dir, *, workers: int = 1,
                  scheduler=None, progress: bool = True, design=None) -> RunLibrary:
    """Run a design into a library folder (resuming a build that was cut short).

    Parameters
    ----------
    simulator : callable
        ``simulator(base, effects, seed) -> Observations`` with a ``design`` attribute
        (the observables), e.g. :class:`~bedstruct.diagnose.SurrogateSimulator` or
        :class:`~bedstruct.diagnose.engine_simulator.EngineSimulator`. Must be picklable
        for ``workers > 1`` or a ``scheduler``. Its settings are part of the library key:
        a simulator of another kind states them with a ``library_identity()`` method
        (see the module's description).
    design_spec : DesignSpec
        The design (:func:`~bedstruct.diagnose.run_design.design_spec`).
    out_dir : path-like
        The library folder (created if absent).
    workers : int
        Local worker processes (1: run in this process).
    scheduler : str or distributed.Client, optional
        Address of a Dask distributed scheduler (``"tcp://host:port"``) or a client:
        the runs go to its workers instead of local processes (requires
        ``dask[distributed]``). Not contacted when no run is missing.
    progress : bool
        Show a progress bar over the runs still to do (tqdm), advancing by each run's
        estimated cost so that its remaining time holds when the costly runs go first.
    design : MeasurementSet, optional
        The observables, when the simulator has no ``design`` attribute.

    Returns
    -------
    RunLibrary
        Every run of the folder; ``n_new`` says how many this call made.

    Raises
    ------
    StaleLibraryError
        The folder holds a library of another key (the message names what differs).
    ConfigError
        The folder holds another design; another build runs in it (the message names its
        process); its ``library.json`` is unreadable; the simulator's settings cannot be
        keyed; the scheduler cannot be reached (the message names the address).

    Notes
    -----
    Each run is written to ``runs/<hash>.json`` as soon as it returns (atomically: a
    file is complete or absent); called again a build runs only the missing ones, and
    redoes a run whose file cannot be read (moved aside as ``<name>.unreadable``). With
    several workers, at most one run per worker is handed out at a time: Ctrl-C (or a
    failed run) starts nothing more, and the runs in flight finish and are saved (a
    warning names them; a second Ctrl-C stops them, and they are lost). On a Dask cluster
    likewise: the runs not yet started are cancelled, those finished on the cluster are
    saved, and those running finish and are saved. The workers are started with
    ``spawn`` (a script must build under ``if __name__ == "__main__":``), ignore Ctrl-C
    and exit when the build's process is killed. With several workers, runs are started
    longest first where the simulator estimates their cost (a
    ``relative_cost(base, effects)`` method, as
    :class:`~bedstruct.diagnose.engine_simulator.EngineSimulator` has).

    Examples
    --------
    >>> import tempfile
    >>> from bedstruct.diagnose import BASE_PARAMETERS, SurrogateSimulator
    >>> from bedstruct.diagnose import measurement_from_dict, MeasurementSet, design_spec
    >>> m = measurement_from_dict({"name": "aor", "kind": "static_angle", "role": "calibrate",
    ...                            "uncertainty": 0.5, "value": 33.0})
    >>> sim = SurrogateSimulator(MeasurementSet((m,)))
    >>> spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=4, n_per_effect=4,
    ...                    replicates=2)
    >>> lib = build_library(sim, spec, tempfile.mkdtemp(), progress=False)
    >>> lib.n_runs, lib.n_new, lib.complete
    (22, 22, True)
    """
    t0 = time.perf_counter()
    out = Path(out_dir)
    spec = design_spec
    doc = library_key_document(simulator, spec, design=design)
    key = library_key(doc)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    meta = {"schema": LIBRARY_SCHEMA, "key": key, "key_document": doc, "spec": spec.to_json(),
            "source": getattr(simulator, "name", "")}
    if not _create_exclusive(out / "library.json", meta):
        _check_key(out, key, doc, spec)   # made by an earlier (or a concurrent) build
    points = design_points(spec)

    def missing() -> list:
        return [(i, p, s) for i, p in enumerate(points) for s in spec.seeds
                if not _usable_run(out, _run_name(key, p, s), key)]

    todo = missing()
    lock = None
    if todo:
        lock = _BuildLock(out)
        todo = missing()   # another build may have finished some runs meanwhile
    try:
        _run_todo(simulator, todo, out, key, workers=workers, scheduler=scheduler,
                  progress=progress)
    finally:
        if lock is not None:
            lock.release()
    lib = load_library(out, key=key)   # the key checked above, whatever the runs changed
    return _replace_stats(lib, n_new=len(todo), wall_s=time.perf_counter() - t0)


def _run_todo(simulator, todo: list, out: Path, key: str, *, workers, scheduler,
              progress) -> None:
    """Run ``todo`` (``(index, point, seed)``) into ``out/runs``, each run saved as it returns."""
    if not todo:
        return
    parallel = scheduler is not None or int(workers) > 1
    costs = _run_costs(simulator, todo) if progress or parallel else {}
    if parallel:
        todo = _longest_first(simulator, todo, costs)
    bar = _CostBar(todo, costs) if progress else None

    def save(i, p, s, rec):
        write_json_atomic(out / "runs" / _run_name(key, p, s),
                          {"key": key, "point": i, "group": p.group, "base": p.base,
                           "effects": p.effects, "seed": int(s), **rec}, keep_nan=True)
        if bar is not None:
            bar.update(i)

    try:
        if scheduler is not None:
            _build_dask(simulator, todo, scheduler, save, out)
        elif int(workers) > 1 and len(todo) > 1:
            _build_local(simulator, todo, int(workers), save, out)
        else:
            for i, p, s in todo:
                save(i, p, s, _run_one(simulator, p, s))
    finally:
        if bar is not None:
            bar.close()


def _create_exclusive(path: Path, document: Mapping) -> bool:
    """Write ``document`` to ``path`` unless the file exists (complete or absent, never
    overwritten: of two builds starting together only one creates it); whether it did."""
    if path.exists():
        return False
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(to_jsonable(document), indent=1))
    try:
        os.link(tmp, path)
    except FileExistsError:
        return False
    except OSError:   # no hard links here: an exclusive create
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            return False
        with os.fdopen(fd, "w") as fh:
            fh.write(tmp.read_text())
    finally:
        tmp.unlink(missing_ok=True)
    return True


class _BuildLock:
    """``build.lock`` in a library folder while a build runs there: a second build of the
    folder is refused, naming the process that holds the lock. A lock left by a process
    of this host that is gone is taken over."""

    NAME = "build.lock"

    def __init__(self, folder: Path):
        import socket
        self.path = folder / self.NAME
        self.mine = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.time()}
        for _ in range(3):
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
            except FileExistsError:
                other = self._holder()
                if other is not None and other.get("host") == self.mine["host"] \
                        and not _alive(other.get("pid")):
                    log.warning("run library %s: %s was left by process %s, which is gone; "
                                "taken over", folder, self.NAME, other.get("pid"))
                    self.path.unlink(missing_ok=True)
                    continue
                who = ("another process" if other is None else
                       f"process {other.get('pid')} on {other.get('host')}")
                raise ConfigError(
                    f"run library {folder}: another build is running in this folder ({who}, "
                    f"{self.path}); wait for it to finish, or remove {self.NAME} if no build "
                    f"runs there") from None
            with os.fdopen(fd, "w") as fh:
                json.dump(self.mine, fh)
            return
        raise ConfigError(f"run library {folder}: could not take {self.path}")

    def _holder(self) -> dict | None:
        try:
            return json.loads(self.path.read_text())
        except (OSError, ValueError):
            return None

    def release(self) -> None:
        if self._holder() == self.mine:
            self.path.unlink(missing_ok=True)


def _alive(pid) -> bool:
    try:
        os.kill(int(pid), 0)
    except ProcessLookupError:
        return False
    except (PermissionError, TypeError, ValueError, OverflowError):
        return True
    try:   # a zombie has finished
        return " Z " not in Path(f"/proc/{int(pid)}/stat").read_text().split(")", 1)[1][:4]
    except (OSError, IndexError):
        return True


#: Fields every run file has.
_RUN_FIELDS = ("key", "point", "base", "effects", "seed", "observations")


def _read_run(f: Path) -> dict:
    """A run file's record; ValueError naming what is wrong when it is unreadable."""
    try:
        rec = json.loads(f.read_text())
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise ValueError(str(exc)) from None
    if not isinstance(rec, dict):
        raise ValueError("not a JSON object")
    lacking = [k for k in _RUN_FIELDS if k not in rec]
    if lacking:
        raise ValueError(f"no {', '.join(lacking)}")
    if not isinstance(rec["observations"], dict) or not isinstance(rec["base"], dict) \
            or not isinstance(rec["effects"], dict):
        raise ValueError("its observations, base or effects are not tables")
    return rec


def _usable_run(out: Path, name: str, key: str) -> bool:
    """Whether ``out/runs/name`` holds a run; an unreadable one is moved aside
    (``<name>.unreadable``) so that the build redoes that run."""
    f = out / "runs" / name
    if not f.is_file():
        return False
    try:
        _read_run(f)
    except ValueError as exc:
        aside = f.with_name(f.name + ".unreadable")
        f.replace(aside)
        log.warning("run library %s: run file %s is unreadable (%s); moved to %s and run again",
                    out, name, exc, aside.name)
        return False
    return True


def _run_label(i: int, p: DesignPoint, s: int) -> str:
    eff = ", ".join(f"{k} {v:.3g}" for k, v in p.effects.items()) or "no effect"
    return f"design point {i} ({eff}), seed {s}"


def _spawn_can_load(simulator) -> bool:
    """False when ``simulator`` refers to objects of a main module that a ``spawn``-ed
    process cannot import (one without a file: a notebook, ``python -c``)."""
    import pickle
    main = sys.modules.get("__main__")
    if main is None or getattr(main, "__file__", None):
        return True
    try:
        return b"__main__" not in pickle.dumps(simulator)
    except Exception:       # not picklable at all: spawn reports it by name
        return True


def _build_local(simulator, todo: list, workers: int, save, out: Path) -> None:
    """Run ``todo`` in ``workers`` local processes, each run saved as it returns.

    At most ``workers`` runs are handed to the processes at a time, so that an interrupt
    (Ctrl-C) or a failed run starts nothing more: the runs in flight are waited for (the
    warning names them) and saved; a second Ctrl-C stops them at once (they are lost).
    The processes are started with ``spawn`` (``fork`` for a simulator defined in a main
    module that a new process cannot import, e.g. a notebook's), ignore Ctrl-C (the build
    decides) and exit when the build's process is gone
    (:mod:`bedstruct.diagnose.process_pool`).
    """
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    from .process_pool import _init_worker

    n = min(workers, len(todo))
    method = "spawn" if _spawn_can_load(simulator) else "fork"
    pool = ProcessPoolExecutor(n, mp_context=multiprocessing.get_context(method),
                               initializer=_init_worker, initargs=(os.getpid(), True))
    queue, running = list(todo), {}
    try:
        try:
            while queue or running:
                while queue and len(running) < n:
                    i, p, s = queue.pop(0)
                    # the simulator travels with each run (its configuration, not its state)
                    running[pool.submit(_run_one, simulator, p, s)] = (i, p, s, time.time())
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                for f in done:
                    i, p, s, _ = running.pop(f)
                    save(i, p, s, f.result())
        except BrokenProcessPool as exc:
            pool.shutdown(wait=False, cancel_futures=True)
            raise ConfigError(
                f"run library {out}: a worker process of the build stopped ({exc}); the runs "
                f"go to processes started with spawn, which import the main module again, so "
                f"a script that builds with workers > 1 must do so under "
                f"`if __name__ == \"__main__\":` (the runs saved so far are kept)") from None
        except BaseException as exc:
            _finish_in_flight(running, save, out, exc)
            pool.shutdown(wait=True, cancel_futures=True)
            raise
    except KeyboardInterrupt:
        for proc in list((getattr(pool, "_processes", None) or {}).values()):
            proc.terminate()
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown(wait=True)


def _finish_in_flight(running: dict, save, out: Path, why: BaseException,
                      wait_first=None) -> None:
    """Wait for the runs in flight after an interrupt or a failed run and save each
    (a KeyboardInterrupt while waiting is passed on: the runs left are lost).

    Parameters
    ----------
    running : dict
        Future -> ``(index, point, seed, t0)``, ``t0`` the time the run was handed out
        (None: not known).
    save : callable
        ``save(index, point, seed, record)``.
    out : Path
        The library folder (for the messages).
    why : BaseException
        The interrupt or the failure of a run.
    wait_first : callable, optional
        ``wait_first(futures) -> done``: those of ``futures`` done once one is
        (default: :func:`concurrent.futures.wait` with ``FIRST_COMPLETED``).
    """
    from concurrent.futures import FIRST_COMPLETED, wait
    if not running:
        return
    if wait_first is None:
        def wait_first(futures):
            return wait(futures, return_when=FIRST_COMPLETED)[0]
    now = time.time()
    what = "; ".join(_run_label(i, p, s) + ("" if t0 is None else
                                            f", handed out {now - t0:.0f} s ago")
                     for i, p, s, t0 in running.values())
    cause = "interrupted" if isinstance(why, KeyboardInterrupt) else f"a run failed ({why!r})"
    log.warning("run library %s: %s; nothing more is started. Waiting for the %d run(s) in "
                "flight to finish and be saved: %s. Press Ctrl-C again to stop them now "
                "(they are then lost)", out, cause, len(running), what)
    while running:
        for f in wait_first(list(running)):
            _save_done(f, running.pop(f), save, out)


def _save_done(f, run: tuple, save, out: Path) -> None:
    """Save the run ``run`` (``(index, point, seed, ...)``) of the done future ``f``; a run
    that failed (or was cancelled) is logged, not saved."""
    i, p, s = run[:3]
    failed = "cancelled" if f.cancelled() else f.exception()
    if failed is None:
        save(i, p, s, f.result())
    else:   # that run is lost, the others kept
        log.warning("run library %s: %s failed (%r); not saved", out, _run_label(i, p, s),
                    failed)


def _replace_stats(lib: RunLibrary, **kw) -> RunLibrary:
    from dataclasses import replace
    return replace(lib, **kw)


def _build_dask(simulator, todo: list, scheduler, save, out: Path) -> None:
    """Run ``todo`` on a Dask cluster, each run saved as it returns.

    An interrupt (Ctrl-C) or a failed run cancels the runs not yet started, saves those
    that finished on the cluster and waits for those running to finish and be saved
    (:func:`_settle_dask`; a second Ctrl-C stops the wait, and those runs are lost).
    """
    try:
        from distributed import Client, as_completed
    except ImportError as exc:  # pragma: no cover - optional dependency
        raise ImportError("scheduler=: running a library on Dask needs dask[distributed] "
                          "(pip install 'bedstruct[dask]')") from exc
    own = not hasattr(scheduler, "submit")
    if own:
        try:
            client = Client(scheduler)
        except Exception as exc:  # noqa: BLE001 - any failure to reach it: named
            raise ConfigError(f"--scheduler (scheduler=) {scheduler!r}: no Dask scheduler "
                              f"could be reached at that address ({type(exc).__name__}: "
                              f"{exc}); give tcp://host:port of a running scheduler") from None
    else:
        client = scheduler
    try:
        sim = client.scatter(simulator, broadcast=True)
        futs = {client.submit(_run_one, sim, p, s, pure=False): (i, p, s) for i, p, s in todo}
        try:
            for f in as_completed(list(futs)):
                save(*futs[f], f.result())
                del futs[f]   # once saved: a run interrupted before is left to _settle_dask
        except BaseException as exc:
            try:
                _settle_dask(client, futs, save, out, exc)
            finally:
                client.cancel(list(futs))
            raise
    finally:
        if own:
            client.close()


def _settle_dask(client, futs: dict, save, out: Path, why: BaseException) -> None:
    """After an interrupt or a failed run on Dask: cancel the runs not yet started, save
    those that finished on the cluster and wait for those running on a worker to finish
    and be saved (:func:`_finish_in_flight`: a second Ctrl-C while waiting is passed on).

    Parameters
    ----------
    client : distributed.Client
    futs : dict
        Future -> ``(index, point, seed)`` of each run not saved yet.
    save : callable
        ``save(index, point, seed, record)``.
    out : Path
        The library folder (for the messages).
    why : BaseException
        The interrupt or the failure of a run.
    """
    from distributed import wait
    done = [f for f in futs if f.done()]
    left = [f for f in futs if not f.done()]
    busy: set = set()
    if left:   # the runs executing now (one queued on a worker has not started)
        try:
            busy = {k for stacks in client.call_stack(futures=left).values() for k in stacks}
        except Exception as exc:  # noqa: BLE001 - the cluster cannot say: none waited for
            log.warning("run library %s: the Dask cluster could not say which runs are "
                        "running (%r); the runs not finished are cancelled", out, exc)
    client.cancel([f for f in left if f.key not in busy])
    for f in done:   # finished on the cluster, not saved yet
        _save_done(f, futs[f], save, out)
    _finish_in_flight({f: (*futs[f], None) for f in left if f.key in busy}, save, out, why,
                      wait_first=lambda fs: wait(fs, return_when="FIRST_COMPLETED").done)


def load_library(path, simulator=None, *, design=None, key: str | None = None,
                 replay: bool = False) -> RunLibrary:
    """Read a library folder, refusing it if its key differs from the current one.

    Parameters
    ----------
    path : path-like
        The library folder.
    simulator : callable, optional
        The current simulator: the library's key must match the key its configuration,
        the catalogue, the observables and the code give now.
    design : MeasurementSet, optional
        Observables, when the simulator has no ``design`` attribute.
    key : str, optional
        An expected key (checked when no simulator is given).
    replay : bool
        Read a library that differs from the current key only in the code it was made by
        (``code``, ``bedstruct_version``): its runs as recorded, for diagnosing again
        with today's diagnosis what a validation record diagnosed (a warning names the
        code that differs). Any other difference is refused as without ``replay``.

    Returns
    -------
    RunLibrary

    Raises
    ------
    StaleLibraryError
        Library key differs from the current one (the message names what differs), or
        a run file of the design holds another key.
    ConfigError
        ``library.json`` or a run file of the design cannot be read (the message names it).

    Notes
    -----
    Only the run files of the stored design's points and seeds are read; any other file
    in ``runs`` is ignored, with a warning.
    """
    path = Path(path)
    if not (path / "library.json").is_file():
        raise ConfigError(f"run library {path}: no library.json (not a run library)")
    meta = _read_meta(path)
    spec = DesignSpec.from_json(meta["spec"])
    if simulator is not None:
        doc = library_key_document(simulator, spec, design=design)
        if replay:
            _check_replay(path, meta, doc)
        else:
            _check_key(path, library_key(doc), doc, spec)
    elif key is not None and meta["key"] != key:
        raise StaleLibraryError(f"run library {path}: key {meta['key']} differs from {key}")
    lib_key = meta["key"]
    points = design_points(spec)
    names = list(meta["key_document"]["observables"])
    ncomp = {n: int(v["n_components"]) for n, v in meta["key_document"]["observables"].items()}
    # the design's runs, by file name: any other file is not read
    expected = {_run_name(lib_key, p, s): (i, p, s) for i, p in enumerate(points)
                for s in spec.seeds}
    files = sorted((path / "runs").glob("*.json"))
    foreign = [f.name for f in files if f.name not in expected]
    if foreign:
        log.warning("run library %s: %d run file(s) not of its design ignored (%s%s)", path,
                    len(foreign), ", ".join(foreign[:3]), ", ..." if len(foreign) > 3 else "")
    rows, pidx, seeds, ys, walls, cpus = [], [], [], [], [], []
    inputs = spec.input_names
    for f in files:
        if f.name not in expected:
            continue
        i, point, seed = expected[f.name]
        try:
            rec = _read_run(f)
        except ValueError as exc:
            raise ConfigError(f"run library {path}: run file {f.name} is unreadable ({exc}); "
                              f"remove it, and a build runs it again") from None
        if rec.get("key") != lib_key:
            raise StaleLibraryError(f"run library {path}: run file {f.name} has key "
                                    f"{rec.get('key')}, the library {lib_key}; not reused")
        try:
            x = [float(rec["base"].get(k, spec.base.get(k, 0.0))) for k in spec.varied]
            x += [float(rec["effects"].get(e, 0.0)) for e in spec.effects]
            obs = rec["observations"]
            y = []
            for n in names:
                v = obs.get(n)
                y += ([np.nan] * ncomp[n] if v is None
                      else [np.nan if a is None else float(a) for a in v])
            if len(y) != sum(ncomp.values()):
                raise ValueError("observations of other sizes than the library's observables")
        except (TypeError, ValueError, AttributeError) as exc:
            raise ConfigError(f"run library {path}: run file {f.name} is unreadable ({exc}); "
                              f"remove it, and a build runs it again") from None
        rows.append(x)
        pidx.append(int(i))
        seeds.append(int(seed))
        ys.append(y)
        walls.append(float(rec.get("wall_s", np.nan)))
        cpus.append(float(rec.get("cpu_s", np.nan)))
    order = np.lexsort((np.asarray(seeds), np.asarray(pidx))) if pidx else np.zeros(0, int)
    ncol = sum(ncomp.values())
    return RunLibrary(path=path, key=lib_key, key_document=meta["key_document"], spec=spec,
                      points=points, names=tuple(names), n_components=ncomp,
                      inputs=np.asarray(rows, float).reshape(-1, len(inputs))[order],
                      point_index=np.asarray(pidx, int)[order], seeds=np.asarray(seeds, int)[order],
                      outputs=np.asarray(ys, float).reshape(-1, ncol)[order],
                      source=str(meta.get("source", "")),
                      run_wall_s=np.asarray(walls, float)[order],
                      run_cpu_s=np.asarray(cpus, float)[order])
