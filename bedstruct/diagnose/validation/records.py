"""Twin records of a validation: what one holds, which method made it, which are done.

A validation appends one record (a JSON object on a line) per diagnosed twin to its records
file as it goes; a later run with the same settings resumes from them, and
:func:`~bedstruct.diagnose.validation.scores.score_twins` scores them.

.. versionadded:: 0.1
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

from ...errors import ConfigError
from ..._json import to_jsonable
from ..separation import not_told_apart

__all__ = ["METHOD_VERSION", "method_version_of", "records_done", "twin_record"]

log = logging.getLogger("bedstruct.diagnose.validation.validate")

#: Version of the method a twin record was made by: how twins are made (sized in the
#: metric of the fit, with the scatter of their own parameter point and the trials their
#: files state), how the simulation scatter is pooled and how the diagnosis fits, confirms
#: and checks an attribution. It is in every record and in every LIGGGHTS twin's
#: ``truth.json``; records and twins of another version are not resumed. Change it whenever
#: a change to :mod:`~bedstruct.diagnose.validation.twins`, :mod:`~bedstruct.diagnose.diagnosis` or
#: the modules they call changes a twin's file or its diagnosis; the validations behind the
#: documented numbers are kept in ``docs/records`` with the version they were made by.
METHOD_VERSION = 1

#: Fields by which records written before :data:`METHOD_VERSION` existed name their method,
#: at the values of version 1. A record that carries some of them at other values was made
#: by an earlier method (no version: never resumed).
_LEGACY_FIELDS = {"twin_rule": 7, "fit_rule": 14, "scatter_rule": 2, "liggghts_twin_rule": 1}


def method_version_of(doc: dict) -> int | None:
    """The :data:`METHOD_VERSION` a twin record (or a twin's ``truth.json``) was made by.

    ``None`` for a record of a method older than version 1.

    Examples
    --------
    >>> method_version_of({"method_version": 1})
    1
    >>> method_version_of({"twin_rule": 7, "fit_rule": 14, "scatter_rule": 2})
    1
    >>> method_version_of({"twin_rule": 7, "fit_rule": 13, "scatter_rule": 2}) is None
    True
    """
    if "method_version" in doc:
        return doc["method_version"]
    legacy = {k: doc[k] for k in _LEGACY_FIELDS if k in doc}
    if legacy and all(v == _LEGACY_FIELDS[k] for k, v in legacy.items()):
        return 1
    return None


#: Signature keys added after records were first written, with the value older records had.
_SIGNATURE_DEFAULTS = {"twin_repeats": 1}


def records_done(records, signature: dict) -> dict:
    """Twin records of the same validation already in ``records``, by (twin, type).

    A record is of the same validation when it agrees with ``signature`` on every key;
    its ``method_version`` is read by :func:`method_version_of`.
    """
    if records is None or not Path(records).exists():
        return {}
    done, other, why = {}, 0, ""
    for n, line in enumerate(Path(records).read_text(encoding="utf-8").splitlines(), 1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
        except json.JSONDecodeError as exc:
            raise ConfigError(f"{records}, line {n}: not a JSON twin record ({exc.msg})") from None
        if not (isinstance(rec, dict) and isinstance(rec.get("twin"), int)
                and rec.get("type") in ("effect", "null", "out_of_catalogue")):
            raise ConfigError(f"{records}, line {n}: not a twin record (expected an object with an "
                              "integer 'twin' and a 'type' of effect, null or out_of_catalogue)")
        rec = dict(rec, method_version=method_version_of(rec))
        differ = [k for k, v in signature.items() if rec.get(k, _SIGNATURE_DEFAULTS.get(k)) != v]
        if not differ:
            done[(int(rec["twin"]), rec["type"])] = rec
        else:
            other += 1
            why = why or ", ".join(f"{k} {rec.get(k)!r} (this run: {signature[k]!r})" for k in differ[:3])
    if other:
        # a resumed long validation that silently reran everything would cost hours: say so
        log.warning("%s: %d record(s) of another validation ignored, e.g. %s", records, other, why)
    if done:
        log.info("%s: %d twin record(s) of this validation taken as done", records, len(done))
    return done


def _label(diag) -> str:
    att = diag.attribution
    if att.verdict == "attributed":
        return "+".join(e.effect for e in att.selected)
    return att.verdict


def twin_record(diag, i: int, kind: str, signature: dict, truth: dict, *, records=None,
                identifiable: dict | None = None) -> dict:
    """One twin's record (scores, verdict, rerun checks), appended to ``records`` if given.

    ``signature`` holds the settings that make two validations the same (records of
    another are not resumed); ``truth`` the withheld effect and magnitude;
    ``identifiable`` the validation's fingerprints' judgement per effect
    (``fingerprint_identifiable``: records that carry it are scored without them).
    """
    att = diag.attribution
    rec = {"twin": i, "type": kind, **signature, **truth, "predicted": _label(diag),
           "verdict": att.verdict, "gap_significant": diag.where.significant,
           "shrink": diag.shrink.fraction, "shrink_rms": diag.shrink.fraction_rms,
           "gap_before": diag.shrink.before_excess, "gap_after": diag.shrink.after_excess,
           "p_gap_heldout_before": diag.shrink.p_before,
           "p_rerun_calibration": diag.shrink.p_rerun_calibration,
           "p_rerun_heldout": diag.shrink.p_rerun_heldout,
           "p_rerun_trials": diag.shrink.p_rerun_trials,
           "refits": len(diag.shrink.refits), "reason": att.reason,
           "where_top": [(w["observable"], w["component"], round(w["z"], 2))
                         for w in diag.where.ranked(3)],
           "rerun_worst": [(w["observable"], w["component"], w["role"], round(w["z"], 2))
                           for w in diag.shrink.rerun_worst]}
    if identifiable is not None:
        rec["fingerprint_identifiable"] = {k: bool(v) for k, v in identifiable.items()}
    if att.selected:
        top = att.selected[0]
        rec.update(fitted_magnitude=top.magnitude, interval=list(top.interval),
                   confidence=top.confidence,
                   not_told_apart=[c["effect"] for c in not_told_apart(att, diag.fingerprints)])
    log.info("twin %d %s %s -> %s", i, kind, truth.get("true_effect"), rec["predicted"])
    if records is not None:
        with open(records, "a", encoding="utf-8") as fh:
            fh.write(json.dumps(to_jsonable(rec)) + "\n")
    return rec
