"""The observation cache of the engine simulator: keys, entries, and the code they hold for.

With ``cache = DIR`` in the ``[engine]`` table every call's observations are
stored on disk (``DIR/<hash>.json``, one file per call, named by the fully
resolved workflow configuration of the call, i.e. preset, overrides, base
parameters, effects and seed, plus each observable's kind and conditions): a
rerun, a validation twin or another measurement file with observables of the
same kinds and conditions reuses them instead of simulating again. Each entry
states the code it was made by (:func:`code_versions`: the bedstruct version and
hashes of the engine's and the observation operators' source); an entry of other
code is refused with a warning naming what differs, and the call simulated again.

:func:`call_key` names an entry, :func:`read_entry` reads one (refusing it when
unreadable or written by other code) and :func:`write_entry` writes one whole;
the simulator that uses them is :class:`~bedstruct.diagnose.engine_simulator.EngineSimulator`.

.. versionadded:: 0.1
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from pathlib import Path
from typing import Any, Mapping

from .._numba import source_hash
from .._version import __version__

__all__ = ["code_versions", "call_key", "read_entry", "write_entry"]

log = logging.getLogger(__name__)

#: Version of the cache entry's layout and key (the hashed document of :func:`call_key`).
_CACHE_SCHEMA = 4
#: Workflow options at whose neutral value no run changes: left out of the cache key.
_NEUTRAL_OPTIONS = {("repose", "rest_time"): 0.0}
#: Contact-model versions: a call with the model switched on carries its version in the key.
_MODEL_REVISIONS = {"contact.ageing": 2}
#: Version of the LIGGGHTS/LAMMPS decks the external workflows write (in the keys of
#: external-engine calls, and in a LIGGGHTS twin's ``truth.json``).
_DECK_REVISION = 2
#: The code an engine call's observations depend on, hashed into :func:`code_versions`
#: and into a run library's key: the engine (its kernels, the external engines' decks,
#: workflows, presets and the catalogue's mapping of effects onto them) and the
#: observation (the operators and the analyses and readers they use).
_CODE = {"engine": ("dem", "engines", "workflows", "_numba.py", "diagnose/catalogue.py",
                    "diagnose/engine_simulator.py", "diagnose/engine_cache.py"),
         "observation": ("analysis", "io", "core", "diagnose/engine_runs.py",
                         "diagnose/observables.py", "diagnose/observables_image.py",
                         "diagnose/observables_registry.py",
                         "diagnose/measurements.py")}


def code_versions() -> dict[str, str]:
    """The versions an engine call's cached observations are valid for.

    ``bedstruct``: the package version; ``engine`` and ``observation``: SHA-256 (16 hex
    digits) of the source files (``*.py``, ``*.toml``) of the engine and of the observation
    operators (:data:`_CODE`). A cache entry written under other versions is refused.

    Returns
    -------
    dict of str to str
    """
    return {"bedstruct": __version__,
            **{part: source_hash(paths, suffixes=(".py", ".toml")) for part, paths in _CODE.items()}}


def call_key(cfg: Mapping[str, Any], *, wide_box: float, speed_scale: float) -> str:
    """Hash of one call: its fully resolved workflow configuration ``cfg`` and the scale model.

    Workflow options at their neutral value (:data:`_NEUTRAL_OPTIONS`) are left out of
    ``cfg`` (which is modified), contact models switched on add their revision, and
    calls of an external engine the revision of its decks.

    Returns
    -------
    str
        32 hex digits.
    """
    for (sec, key), neutral in _NEUTRAL_OPTIONS.items():
        if cfg.get(sec, {}).get(key, neutral) == neutral:
            cfg[sec].pop(key, None)
    doc = {"schema": _CACHE_SCHEMA, "config": cfg,
           "wide_box": wide_box, "speed_scale": speed_scale}
    revised = {m: r for m, r in _MODEL_REVISIONS.items()
               if cfg[m.partition(".")[0]].get(m.partition(".")[2])}
    if revised:
        doc["revisions"] = revised
    if cfg.get("engine", "embedded") != "embedded":
        doc["deck_revision"] = _DECK_REVISION
    text = json.dumps(doc, sort_keys=True, default=float)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def read_entry(folder: Path | None, key: str, versions: Mapping[str, str] | None) -> dict:
    """The cached observations of call ``key`` in ``folder``, by observable spec.

    Empty when there is no cache, no entry, an unreadable one (a warning) or one written
    by code whose :func:`code_versions` differ from ``versions`` (a warning naming what
    differs): such an entry is never reused. ``versions=None`` reads an entry whatever
    code wrote it (a replay of recorded runs, which never runs the engine).
    """
    if folder is None:
        return {}
    f = folder / f"{key}.json"
    if not f.is_file():
        return {}
    try:
        doc = json.loads(f.read_text(encoding="utf-8"))
        have = (doc.get("meta") or {}).get("versions") or {}
        observables = doc.get("observables", {})
    except (OSError, ValueError, AttributeError):
        log.warning("engine cache: unreadable entry %s ignored", f)
        return {}
    differ = [k for k in (versions or {}) if have.get(k) != versions[k]]
    if differ:
        # observations of other code: never reused, the call is simulated again
        log.warning("engine cache: entry %s refused: written by other code (%s); the call "
                    "is simulated again and the entry replaced", f.name,
                    "; ".join(f"{k} {have.get(k) or 'not stated'}, this code "
                              f"{versions[k]}" for k in differ))
        return {}
    return observables


def write_entry(folder: Path | None, key: str, entries: dict, meta: dict) -> None:
    """Write the entry of call ``key`` (observations by spec, and ``meta``) whole, or not at all."""
    if folder is None:
        return
    folder.mkdir(parents=True, exist_ok=True)
    f = folder / f"{key}.json"
    tmp = f.with_suffix(f".tmp{os.getpid()}")
    tmp.write_text(json.dumps({"meta": meta, "observables": entries}, indent=0,
                              sort_keys=True), encoding="utf-8")
    os.replace(tmp, f)
