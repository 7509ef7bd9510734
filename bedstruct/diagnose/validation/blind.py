"""Blind benchmark of the diagnosis: truth drawn and sealed first, then diagnosed.

The validation (:func:`~bedstruct.diagnose.validation.validate.validate`) is in-sample: its rules were
tuned on its twins. A blind benchmark draws new twins from a seed, writes their truth and a
seal before any diagnosis runs, and then diagnoses each twin's measurement file once, with
the diagnosis' frozen default settings, on a diagnosing simulator separate from the one
that made the twins:

1. **draw** ``n`` twins (:func:`~bedstruct.diagnose.validation.blind_twins.draw_twins`): at least half
   effect twins, a quarter null twins, a quarter out-of-catalogue twins
   (:data:`~bedstruct.diagnose.validation.blind_twins.OUT_OF_CATALOGUE`). Effect magnitudes are drawn
   uniformly where the diagnosing model detects the effect with 95 % power in a twin's
   noise (``draw="detectable"``: the diagnosing configuration's fingerprints on the
   benchmark's design, :func:`~bedstruct.diagnose.validation.blind_twins.detectable_ranges`; an effect
   it detects nowhere in its prior is not drawn), and out-of-catalogue changes where the
   twin engine's twins of them were seen to leave a gap
   (:attr:`~bedstruct.diagnose.validation.blind_twins.OutOfCatalogueChange.visible`); or over the
   whole prior and the changes' full ranges (``draw="prior"``); the ranges go into the
   truth;
2. **truth first**: ``DIR/truth.json`` (twin id -> kind, effect or change, magnitude; the
   code commit, the bedstruct version, the settings), each twin's file
   ``DIR/twins/twin-XXX.toml`` (nothing of the truth), then ``DIR/seal.json`` (SHA-256 of
   ``truth.json`` and of every twin file, and the time);
3. **diagnose** each twin file (:func:`diagnose_file`), its result written atomically to
   ``DIR/results/twin-XXX.json``; a killed run resumes with the finished ones, and a rerun
   into a folder whose truth or seal differ from this one's is refused;
4. **score** (:func:`score_benchmark`): top-1 among effect twins (and among those whose
   gap the "is there a gap" test finds significant; ``top1_partial_count``: how many of
   the top-1 answers are partial explanations), false attribution among
   null twins, ``unexplained`` among out-of-catalogue twins and magnitude-interval
   coverage, each with its Clopper-Pearson 95 % interval (:func:`proportion_interval`);
   the median held-out gap shrink over the effect twins where the held-out gap before is
   beyond noise, with a distribution-free order-statistic interval
   (:func:`median_interval`); the confusion matrix; written to ``DIR/summary.json`` and
   ``DIR/report.html``.

:func:`pool_benchmarks` scores several sealed batches together (their counts added).

.. versionadded:: 0.1
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..._json import to_jsonable, write_json_atomic
from ..._version import __version__
from ...errors import ConfigError
from ..amortised import library_emulator
from ..bridge import engine_bridge
from .report import benchmark_html, confusion_figure
from .blind_twins import (DETECT_POWER, OUT_OF_CATALOGUE, TWIN_ENGINES, benchmark_design,
                          detectable_ranges, draw_twins, split_counts, twin_measurements)
from ..catalogue import CATALOGUE
from ..config import load_sim_config, make_simulator
from ..diagnosis import diagnose, diagnosis_design
from ..fingerprint_runs import compute_fingerprints
from ..fingerprints import selection_threshold
from ..emulator import EmulatedSimulator
from ..measurement_io import load_measurements

__all__ = ["PROTOCOL", "DRAWS", "SHRINK_ALPHA", "BenchmarkResult", "run_benchmark", "diagnose_file",
           "score_benchmark", "load_benchmark", "pool_benchmarks", "rediagnose_benchmark", "proportion_interval", "median_interval", "confusion_figure",
           "add_benchmark_arguments", "run_benchmark_command"]

#: Revision of the protocol, in ``truth.json`` (2: the ``draw`` setting, effect magnitudes
#: where the diagnosing model detects them; 3: in that draw, out-of-catalogue changes over
#: the magnitudes where the twin engine's twins of them are seen; 4: a DEM twin's file leaves
#: out an observable fewer than two of its repeats read, and states the uncertainty of a mean
#: over the repeats that read it).
PROTOCOL = "bedstruct.blind/4"
#: How effect magnitudes may be drawn (:func:`run_benchmark`).
DRAWS = ("detectable", "prior")
#: Level of the held-out gap test before: shrink counts where ``p_before`` is below it.
SHRINK_ALPHA = 0.05


def proportion_interval(k: int, n: int, *, level: float = 0.95) -> tuple[float, float]:
    """Clopper-Pearson (exact binomial) interval of ``k`` successes in ``n`` trials.

    ``(nan, nan)`` when ``n`` is 0.

    Examples
    --------
    >>> [round(x, 3) for x in proportion_interval(9, 10)]
    [0.555, 0.997]
    >>> [round(x, 3) for x in proportion_interval(0, 10)]
    [0.0, 0.308]
    """
    if n == 0:
        return (float("nan"), float("nan"))
    from scipy.stats import binomtest
    ci = binomtest(int(k), int(n)).proportion_ci(confidence_level=level, method="exact")
    return (float(ci.low), float(ci.high))


def median_interval(values, *, level: float = 0.95) -> tuple[float, float, float]:
    """Distribution-free interval of a median from order statistics.

    The ``j``-th smallest and ``j``-th largest values, ``j`` the largest rank whose
    interval still covers the median with probability >= ``level`` (the number of values
    below the median is binomial(m, 1/2)). With too few values for ``level`` (m < 6 at
    95 %), the smallest and largest value and the coverage they achieve.

    Returns
    -------
    (lo, hi, coverage)

    Examples
    --------
    >>> lo, hi, cov = median_interval(range(1, 21))
    >>> lo, hi, round(cov, 3)
    (6.0, 15.0, 0.959)
    """
    x = np.sort(np.asarray([v for v in values if v is not None and np.isfinite(v)], float))
    m = len(x)
    if m == 0:
        return (float("nan"), float("nan"), float("nan"))
    from scipy.stats import binom
    best = 1
    for j in range(1, m // 2 + 1):
        if 1.0 - 2.0 * binom.cdf(j - 1, m, 0.5) >= level:
            best = j
    cov = 1.0 - 2.0 * binom.cdf(best - 1, m, 0.5)
    return (float(x[best - 1]), float(x[m - best]), float(cov))


def _commit() -> str | None:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                             cwd=Path(__file__).resolve().parent, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return (out.stdout.strip() or None) if out.returncode == 0 else None


def _sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _answer(diag) -> str:
    att = diag.attribution
    return "+".join(e.effect for e in att.selected) if att.verdict == "attributed" else att.verdict


def _finite(x) -> float | None:
    return float(x) if x is not None and np.isfinite(x) else None


def diagnose_file(path, sim: str = "surrogate", *, settings: dict | None = None,
                  emulator=None, bridge=None) -> dict:
    """Diagnose one measurement file as ``bedstruct diagnose --sim SIM --real PATH`` does.

    ``sim`` is ``"surrogate"`` or a simulation config path (:func:`load_sim_config`);
    ``settings`` replaces fields of that config (``replicates``, ``refine``...: for tests
    only; the protocol uses the config's, i.e. the diagnosis' defaults). With ``emulator``
    (an :class:`~bedstruct.diagnose.emulator.Emulator` of that configuration's run
    library, :func:`~bedstruct.diagnose.amortised.library_emulator`) the diagnosis runs
    on the emulator, as ``--library`` answers, without the confirming rerun. The file is
    read with ``check_range=False`` (a twin's numbers need not lie in a kind's plausible
    range). ``bridge`` (an :class:`~bedstruct.diagnose.bridge.EngineBridge`, made once for
    the benchmark from the configuration's ``[bridge]``) compares the file with that engine's
    baseline.

    Returns
    -------
    dict
        The result record: ``answer`` (leading effects joined by ``+``, or the verdict),
        ``verdict``, ``partial`` (an attribution that leaves part of the held-out gap),
        ``effects`` (each effect, magnitude, interval, confidence),
        ``magnitude`` and ``interval`` of the leading effect, ``shrink`` (held-out excess
        gap shrink), ``p_heldout_before``, ``n_heldout``, ``shrink_measured``,
        ``gap_significant`` and ``p_gap`` (the "is there a gap" test over all measured
        observables), ``reason``, ``seconds``.
    """
    t0 = time.perf_counter()
    cfg = _sim_config(sim, settings)
    ms = load_measurements(path, check_range=False)
    if emulator is not None:
        simulator = EmulatedSimulator(emulator)
    else:
        simulator = make_simulator(cfg, diagnosis_design(ms, cfg.effects))
    diag = diagnose(ms, simulator, base=cfg.base, effects=cfg.effects, nuisance=cfg.nuisance,
                    bridge=bridge, **cfg.diagnose_settings())
    att, sh = diag.attribution, diag.shrink
    effects = [{"effect": e.effect, "magnitude": float(e.magnitude),
                "interval": [float(v) for v in e.interval], "confidence": _finite(e.confidence)}
               for e in att.selected] if att.verdict == "attributed" else []
    p_before = _finite(sh.p_before)
    shrink = _finite(sh.fraction)
    return {"twin": Path(path).stem, "answer": _answer(diag), "verdict": att.verdict,
            "partial": bool(att.partial), "effects": effects,
            "magnitude": effects[0]["magnitude"] if effects else None,
            "interval": effects[0]["interval"] if effects else None,
            "shrink": shrink, "p_heldout_before": p_before, "n_heldout": int(sh.n_heldout),
            "gap_significant": bool(diag.where.significant),
            "p_gap": _finite(diag.where.p_value),
            "shrink_measured": bool(shrink is not None and p_before is not None
                                    and p_before < SHRINK_ALPHA),
            "reason": att.reason, "simulator": diag.simulator,
            "seconds": round(time.perf_counter() - t0, 2)}


def rediagnose_benchmark(folder, *, twins=None, sim=None, progress: bool = False) -> dict:
    """Diagnose a sealed benchmark's twin files again with this code, from the benchmark's
    own run library and bridge runs as recorded (no simulator run), and compare with the
    recorded diagnoses.

    What a validation record's answers owe to the diagnosis, apart from the simulator:
    the library (``DIR/library``) and the bridge's engine runs are read whatever engine code
    made them (:func:`~bedstruct.diagnose.run_library.load_library` with ``replay``), so
    the comparison holds after the engine's code changes; a library made for another
    simulator, catalogue or design is refused.

    Parameters
    ----------
    folder : path-like
        A sealed benchmark folder run with ``--library DIR/library`` (or the library in
        ``DIR/library``).
    twins : sequence of str, optional
        Twin ids (default: every twin of the seal).
    sim : str, optional
        The diagnosing simulation config (default: the one ``truth.json`` records,
        relative to the working directory).
    progress : bool
        A bar over the twins.

    Returns
    -------
    dict
        ``n``, ``same`` (twins whose answer and partial flag are the recorded ones),
        ``differ`` (id -> ``{"recorded": ..., "now": ...}``: answer, partial flag,
        magnitude, shrink, for the others), ``magnitude_rel_diff`` (the largest relative
        difference of a leading effect's magnitude where both answers name the same
        effect; 0.0 where none), ``results`` (id -> this code's record, as
        :func:`diagnose_file`).

    Notes
    -----
    The answers of a twin near a decision threshold, and the magnitudes of a weakly
    identified fit, can change with the floating-point platform (the BLAS kernels numpy
    runs on): compare on the platform a record was diagnosed on to see the code's own
    changes.

    Raises
    ------
    ConfigError
        The folder is not a sealed benchmark, its twins are not all diagnosed, it has no
        ``library`` folder, or its simulation config cannot be found.
    """
    folder = Path(folder)
    truth, results = load_benchmark(folder)
    ids = list(twins) if twins is not None else sorted(truth["twins"])
    unknown = [t for t in ids if t not in truth["twins"]]
    if unknown:
        raise ConfigError(f"{folder}: no twin {unknown[0]!r} in truth.json")
    missing = [t for t in ids if t not in results]
    if missing:
        raise ConfigError(f"{folder}: twin {missing[0]} has no recorded diagnosis to compare with")
    library = folder / "library"
    if not (library / "library.json").is_file():
        raise ConfigError(f"{folder}: no run library in {library} (rediagnosing needs the "
                          f"benchmark's own library)")
    sim = sim if sim is not None else truth["settings"]["sim"]
    if sim != "surrogate" and not Path(sim).is_file():
        raise ConfigError(f"{folder}: its simulation config {sim} is not found from "
                          f"{Path.cwd()}; pass sim= (or run from the folder it was run in)")
    settings = _settings_of(truth)
    design = benchmark_design(truth["settings"]["twins_engine"])
    emu = _emulator(sim, settings, design, library, 1, None, False, replay=True)
    bridge = _benchmark_bridge(sim, settings, design, emu, library, False, replay=True)
    keys = ("answer", "partial", "magnitude", "shrink")
    now, differ, rel = {}, {}, 0.0
    it = ids
    if progress:
        from tqdm import tqdm
        it = tqdm(ids, desc="rediagnose", unit="twin")
    for t in it:
        r = diagnose_file(folder / "twins" / f"{t}.toml", sim, settings=settings,
                          emulator=emu, bridge=bridge)
        now[t] = r
        was = results[t]
        if (r["answer"], r["partial"]) != (was["answer"], was["partial"]):
            differ[t] = {"recorded": {k: was.get(k) for k in keys},
                         "now": {k: r.get(k) for k in keys}}
        elif r.get("magnitude") is not None and was.get("magnitude"):
            rel = max(rel, abs(r["magnitude"] / was["magnitude"] - 1.0))
    return {"n": len(ids), "same": len(ids) - len(differ), "differ": differ,
            "magnitude_rel_diff": rel, "results": now}


def _settings_of(truth: dict) -> dict | None:
    """The diagnosis settings a benchmark replaced (``--diagnose-setting``), from its truth."""
    ds = truth.get("settings", {}).get("diagnose_settings")
    return dict(ds) if isinstance(ds, dict) and ds else None


def _sim_config(sim, settings):
    cfg = load_sim_config(sim)
    return dataclasses.replace(cfg, **settings) if settings else cfg


@dataclass(frozen=True)
class BenchmarkResult:
    """A blind benchmark's scores (:func:`run_benchmark`); ``summary`` is ``summary.json``.

    Proportions are ``(k, n)`` counts with their value and Clopper-Pearson 95 % interval.
    """

    out: Path
    n: int
    counts: dict
    top1: tuple[int, int]
    null_false: tuple[int, int]
    ooc_unexplained: tuple[int, int]
    coverage: tuple[int, int]
    shrink_median: float
    shrink_ci: tuple[float, float]
    shrink_n: int
    confusion: dict
    summary: dict

    def figure(self):
        """The confusion matrix (truth rows x answer columns) as a matplotlib Figure."""
        return confusion_figure(self.confusion)

    def json_line(self) -> dict:
        """The keys the CLI's ``--json`` prints."""
        s = self.summary
        return {k: s[k] for k in ("n", "top1", "top1_ci", "top1_detected", "top1_detected_ci",
                                  "null_false", "null_false_ci",
                                  "ooc_unexplained", "ooc_ci", "ooc_detected", "ooc_detected_ci",
                                  "shrink_median", "shrink_ci",
                                  "shrink_ci_method", "shrink_n", "coverage", "coverage_ci",
                                  "commit", "out")}


def _truth_label(t: dict) -> str:
    if t["kind"] == "effect":
        return t["effect"]
    if t["kind"] == "null":
        return "null"
    return f"{t['change']} (out of catalogue)"


def score_benchmark(truth: dict, results: dict) -> dict:
    """Scores of a benchmark from its truth (``truth.json``) and results (twin -> record).

    Returns the summary dict (see the module docstring); twins without a result are listed
    in ``not_diagnosed`` and left out of every score.
    """
    twins = truth["twins"]
    eff = [t for t in twins if twins[t]["kind"] == "effect" and t in results]
    null = [t for t in twins if twins[t]["kind"] == "null" and t in results]
    ooc = [t for t in twins if twins[t]["kind"] == "out_of_catalogue" and t in results]
    lead = {t: results[t]["answer"].split("+")[0] for t in results}
    k_top1 = sum(lead[t] == twins[t]["effect"] for t in eff)
    # named first, but as a partial explanation (the rerun leaves part of the held-out gap)
    k_partial = sum(lead[t] == twins[t]["effect"] and bool(results[t].get("partial"))
                    for t in eff)
    # effect twins whose gap the data show (records made before the gap test was stored
    # have no such key and are left out of this score)
    seen = [t for t in eff if results[t].get("gap_significant")]
    k_seen = sum(lead[t] == twins[t]["effect"] for t in seen)
    k_null = sum(results[t]["verdict"] == "attributed" for t in null)
    k_ooc = sum(results[t]["verdict"] == "unexplained" for t in ooc)
    # out-of-catalogue twins whose gap the data show: the only ones "unexplained" can name
    ooc_seen = [t for t in ooc if results[t].get("gap_significant")]
    k_ooc_seen = sum(results[t]["verdict"] == "unexplained" for t in ooc_seen)
    covered = [t for t in eff if lead[t] == twins[t]["effect"] and results[t]["interval"]]
    k_cov = sum(results[t]["interval"][0] <= twins[t]["magnitude"] <= results[t]["interval"][1]
                for t in covered)
    shrinks = [results[t]["shrink"] for t in eff if results[t]["shrink_measured"]]
    lo, hi, cov_level = median_interval(shrinks)
    effects = [e.name for e in CATALOGUE]
    changes = sorted({twins[t]["change"] for t in twins if twins[t]["kind"] == "out_of_catalogue"})
    rows = effects + ["null"] + [f"{c} (out of catalogue)" for c in changes]
    cols = effects + ["none", "unexplained"]
    mat = np.zeros((len(rows), len(cols)), dtype=int)
    for t in results:
        if t not in twins:
            continue
        a = lead[t] if lead[t] in cols else "unexplained"
        mat[rows.index(_truth_label(twins[t])), cols.index(a)] += 1

    def prop(k, n):
        return (k / n if n else float("nan")), list(proportion_interval(k, n)), [int(k), int(n)]

    top1, top1_ci, top1_count = prop(k_top1, len(eff))
    td, td_ci, td_count = prop(k_seen, len(seen))
    nf, nf_ci, nf_count = prop(k_null, len(null))
    ou, ou_ci, ou_count = prop(k_ooc, len(ooc))
    od, od_ci, od_count = prop(k_ooc_seen, len(ooc_seen))
    cv, cv_ci, cv_count = prop(k_cov, len(covered))
    per_twin = []
    for t in sorted(twins):
        r = results.get(t, {})
        per_twin.append({"twin": t, "truth_label": _truth_label(twins[t]),
                         "truth_magnitude": twins[t]["magnitude"], "answer": r.get("answer", "-"),
                         "partial": bool(r.get("partial")),
                         "magnitude": r.get("magnitude"), "interval": r.get("interval"),
                         "shrink": r.get("shrink"), "shrink_measured": r.get("shrink_measured")})
    return {"protocol": truth["protocol"], "n": len(twins),
            "counts": {k: sum(v["kind"] == k for v in twins.values())
                       for k in ("effect", "null", "out_of_catalogue")},
            "top1": top1, "top1_ci": top1_ci, "top1_count": top1_count,
            "top1_partial_count": [int(k_partial), int(k_top1)],
            "top1_detected": td, "top1_detected_ci": td_ci, "top1_detected_count": td_count,
            "null_false": nf, "null_false_ci": nf_ci, "null_false_count": nf_count,
            "ooc_unexplained": ou, "ooc_ci": ou_ci, "ooc_count": ou_count,
            "ooc_detected": od, "ooc_detected_ci": od_ci, "ooc_detected_count": od_count,
            "coverage": cv, "coverage_ci": cv_ci, "coverage_count": cv_count,
            "shrink_median": float(np.median(shrinks)) if shrinks else float("nan"),
            "shrink_ci": [lo, hi], "shrink_n": len(shrinks),
            "shrink_ci_method": (f"order statistics (distribution-free), coverage "
                                 f"{cov_level:.3f}" if shrinks else "order statistics"),
            "confusion": {"rows": rows, "columns": cols, "matrix": mat.tolist()},
            "not_diagnosed": sorted(set(twins) - set(results)),
            "commit": truth.get("commit"), "version": truth.get("version"),
            "settings": truth["settings"], "twins": per_twin}


def load_benchmark(folder) -> tuple[dict, dict]:
    """The truth and the results of a benchmark folder.

    Parameters
    ----------
    folder : path-like
        A folder :func:`run_benchmark` wrote (``truth.json``, ``results/twin-XXX.json``).

    Returns
    -------
    truth, results : dict
        ``truth.json`` as read, and twin id -> its result record (twins not yet diagnosed
        have none).

    Raises
    ------
    ConfigError
        When the folder has no ``truth.json``; has no ``seal.json`` (its twins are still
        being made: a benchmark is scored once, after its seal); or when ``truth.json`` or
        a result's twin file is not the one the seal holds.
    """
    folder = Path(folder)
    if not (folder / "truth.json").is_file():
        raise ConfigError(f"{folder}: no truth.json (not a benchmark folder)")
    if not (folder / "seal.json").is_file():
        made = len(list((folder / "twins").glob("twin-*.toml")))
        raise ConfigError(f"{folder}: not sealed ({made} twin files made, no seal.json): its "
                          f"twins are still being made, and a benchmark is scored after its seal")
    seal = json.loads((folder / "seal.json").read_text())
    if seal.get("truth_sha256") != _sha256(folder / "truth.json"):
        raise ConfigError(f"{folder}: truth.json is not the one seal.json holds; refused")
    truth = json.loads((folder / "truth.json").read_text())
    results = {p.stem: json.loads(p.read_text())
               for p in sorted((folder / "results").glob("twin-*.json"))}
    for twin, r in results.items():
        if r.get("twin_sha256") != seal["twins_sha256"].get(twin):
            raise ConfigError(f"{folder}: results/{twin}.json is the diagnosis of a twin file "
                              f"other than the sealed one; refused")
    return truth, results


def pool_benchmarks(folders) -> dict:
    """Scores of several benchmarks taken together, as one batch of all their twins.

    Every twin of every folder is scored once by :func:`score_benchmark` (its id prefixed
    by its folder's name): the counts add up, each proportion's Clopper-Pearson interval is
    that of the pooled counts, and the median held-out shrink and its interval are over
    every shrink measured. Pool batches of one method for that method's rate; pooling
    batches of different methods (for instance the null twins of every bridged batch)
    answers a question about all of them, which the caller states.

    Parameters
    ----------
    folders : sequence of path-like
        Benchmark folders (:func:`load_benchmark`).

    Returns
    -------
    dict
        :func:`score_benchmark`'s summary, with ``batches`` (folder names), ``commits``
        and ``protocols`` (one per batch) in place of the one batch's ``commit``,
        ``protocol`` and ``settings``.

    Examples
    --------
    >>> from pathlib import Path
    >>> import bedstruct
    >>> records = Path(bedstruct.__file__).parents[1] / "docs" / "records"
    >>> s = pool_benchmarks([records / "blind-liggghts-partial-2026-12-05",
    ...                      records / "blind-liggghts-visible-2026-12-05"])
    >>> s["top1_count"], [round(x, 2) for x in s["top1_ci"]]
    ([26, 40], [0.48, 0.79])
    """
    folders = [Path(f) for f in folders]
    if not folders:
        raise ConfigError("pool_benchmarks: no benchmark folder given")
    names = [f.resolve().name for f in folders]
    if len(set(names)) != len(names):
        raise ConfigError(f"pool_benchmarks: a folder is given twice ({names})")
    twins, results, commits, protocols = {}, {}, [], []
    for name, folder in zip(names, folders):
        truth, res = load_benchmark(folder)
        commits.append(truth.get("commit"))
        protocols.append(truth.get("protocol"))
        twins.update({f"{name}/{t}": v for t, v in truth["twins"].items()})
        results.update({f"{name}/{t}": r for t, r in res.items()})
    pooled = score_benchmark({"twins": twins, "protocol": None, "settings": None}, results)
    for key in ("protocol", "commit", "version", "settings"):
        pooled.pop(key, None)
    pooled.update(batches=names, commits=commits, protocols=protocols)
    return pooled


def _truth_doc(n, seed, twins_engine, preset, sim, settings, specs, library,
               draw: str = "prior", ranges=None) -> dict:
    n_eff, n_null, n_ooc = split_counts(n)
    if draw == "detectable":
        how = {"effect_magnitudes": (f"uniform over the magnitudes the diagnosing model detects "
                                     f"with {DETECT_POWER:.0%} power in a twin's noise, the tenth "
                                     f"of the prior nearest 0 left out"),
               "detectable_ranges": {k: [list(r) for r in v] for k, v in ranges.items()},
               "out_of_catalogue_magnitudes": (
                   "log-uniform (factors) or uniform over the ranges where the twin engine's "
                   "twins of the change were seen to leave a gap beyond noise on this design"),
               "out_of_catalogue_ranges": {
                   c.name: [list(r) for r in c.drawable(twins_engine, True)]
                   for c in OUT_OF_CATALOGUE if twins_engine in c.realised}}
    else:
        how = {"effect_magnitudes": "uniform over the prior, the tenth of its range nearest 0 "
                                    "left out"}
    return {"protocol": PROTOCOL, "commit": _commit(), "version": __version__,
            "settings": {"n": int(n), "seed": int(seed), "twins_engine": twins_engine,
                         "preset": preset, "sim": str(sim),
                         "diagnose_settings": dict(settings or {}) or "defaults",
                         "diagnosed_on": "simulator" if library is None else
                         {"emulator_of_run_library": _library_doc(sim, settings)},
                         "split": {"effect": n_eff, "null": n_null, "out_of_catalogue": n_ooc},
                         "draw": draw, **how,
                         "out_of_catalogue_changes": [
                             c.name for c in OUT_OF_CATALOGUE if twins_engine in c.realised
                             and c.drawable(twins_engine, draw == "detectable")],
                         "cohesion": "calibrated x (1 + U(-0.02, 0.02))",
                         "design": benchmark_design(twins_engine).names,
                         **_bridge_doc(sim, settings)},
            "twins": {s.twin: s.as_dict() for s in specs}}


def _bridge_doc(sim, settings) -> dict:
    """The diagnosing configuration's ``[bridge]`` (engine and runs), when it has one."""
    tab = _sim_config(sim, settings).bridge
    if not tab:
        return {}
    keys = ("engine", "runs", "seed") + (("probe_runs",) if tab.get("probe_runs") else ()) \
        + (("probes",) if tab.get("probes", "top") != "top" else ())
    return {"bridge": {k: tab[k] for k in keys}}


def _library_doc(sim, settings) -> dict:
    """The run library's design settings of the diagnosing configuration (for the truth)."""
    lib = _sim_config(sim, settings).library_settings()
    lib["effects"] = [e.name for e in lib["effects"]]
    lib["nuisance"] = list(lib["nuisance"])
    return lib


def _emulator(sim, settings, design, library, workers, scheduler, progress, replay=False):
    """Build (or resume, or reuse) the diagnosing configuration's run library on the
    benchmark's measurement design, and fit its emulator (``replay``: the library's runs
    as recorded, whatever code made them; nothing is run)."""
    cfg = _sim_config(sim, settings)
    simulator = make_simulator(cfg, diagnosis_design(design, cfg.effects))
    return library_emulator(simulator, base=cfg.base, library=library, workers=workers,
                            scheduler=scheduler, progress=progress, replay=replay,
                            **cfg.library_settings())


def _detectable(sim, settings, twins_engine, simulator, progress=False):
    """The effects' detectable magnitudes (:func:`detectable_ranges`) on the diagnosing
    configuration's fingerprints at its base point, on the benchmark's design."""
    cfg = _sim_config(sim, settings)
    design = diagnosis_design(benchmark_design(twins_engine), cfg.effects)
    fps = compute_fingerprints(simulator, design, cfg.base, cfg.effects, nuisance=cfg.nuisance,
                               replicates=cfg.replicates, seed=cfg.seed, alpha=cfg.select_alpha,
                               progress=progress)
    return detectable_ranges(fps, threshold=selection_threshold(cfg.select_alpha,
                                                                len(cfg.effects)),
                             repeats=1 if twins_engine == "surrogate" else 3)


def _benchmark_bridge(sim, settings, design, emulator, library, progress, workers=1,
                      replay=False):
    """The diagnosing configuration's engine bridge on the benchmark's design (``None``
    without a ``[bridge]``): made once, its runs kept in the table's ``cache``, else in the
    library's folder (``replay``: read from there whatever code made them; none is run)."""
    cfg = _sim_config(sim, settings)
    if not cfg.bridge:
        return None
    if emulator is not None:
        simulator = EmulatedSimulator(emulator)
    else:
        simulator = make_simulator(cfg, diagnosis_design(design, cfg.effects))
    cache = cfg.bridge.get("cache") or (Path(library) / "bridge" if library is not None else None)
    return engine_bridge(design, simulator, base=cfg.base, bridge=cfg.bridge, engine=cfg.engine,
                         effects=cfg.effects, cache=cache, workers=workers, progress=progress,
                         replay=replay)


def _bridge_once(out, sim, settings, twins_engine, emulator, library, progress, workers):
    """The benchmark's engine bridge (:func:`_benchmark_bridge`), written to
    ``out/bridge.json``."""
    bridge = _benchmark_bridge(sim, settings, benchmark_design(twins_engine), emulator, library,
                               progress is not None, workers)
    if bridge is not None:
        out.mkdir(parents=True, exist_ok=True)
        write_json_atomic(out / "bridge.json", bridge.as_dict())
    return bridge


def _dump(doc) -> bytes:
    return (json.dumps(doc, indent=1, sort_keys=True) + "\n").encode("utf-8")


def _make_twin(spec, twins_engine, preset, out: Path) -> None:
    """Make one twin's measurement file, atomically (a process of its own may run it)."""
    p = out / "twins" / f"{spec.twin}.toml"
    tmp = p.with_suffix(".toml.tmp")
    twin_measurements(spec, twins_engine, benchmark_design(twins_engine), tmp, preset=preset)
    tmp.replace(p)


def _prepare(out: Path, truth: dict, specs, twins_engine, preset, progress=None,
             workers: int = 1) -> dict:
    """Write truth, twin files and seal (or check those there); returns the seal.

    A run killed while making the twins resumes with the twin files already written (each
    is written atomically, so one that exists is complete); the seal is written once every
    twin file exists.
    """
    out.mkdir(parents=True, exist_ok=True)
    tpath, spath = out / "truth.json", out / "seal.json"
    body = _dump(truth)
    if tpath.exists():
        if tpath.read_bytes() != body:
            raise ConfigError(f"{out}: holds the truth of another benchmark (truth.json differs "
                              f"from this run's: settings, seed or code commit); refused — use a "
                              f"new folder")
    elif spath.exists() or (out / "results").exists():
        raise ConfigError(f"{out}: has a seal or results but no truth.json; refused")
    else:
        tmp = tpath.with_suffix(".json.tmp")
        tmp.write_bytes(body)
        tmp.replace(tpath)
    sealed = json.loads(spath.read_text()) if spath.exists() else None
    if sealed is not None and sealed.get("truth_sha256") != _sha256(tpath):
        raise ConfigError(f"{out}: seal.json does not match truth.json; refused")
    if sealed is None:
        # a twin file is written atomically: one that exists is a finished twin
        (out / "twins").mkdir(exist_ok=True)
        missing = [s for s in specs if not (out / "twins" / f"{s.twin}.toml").exists()]
        if workers > 1 and len(missing) > 1:
            with ProcessPoolExecutor(min(int(workers), len(missing))) as pool:
                jobs = {pool.submit(_make_twin, s, twins_engine, preset, out): s for s in missing}
                for job in as_completed(jobs):
                    job.result()
                    if progress is not None:
                        progress(f"{jobs[job].twin}: measurement file written")
        else:
            for s in missing:
                _make_twin(s, twins_engine, preset, out)
                if progress is not None:
                    progress(f"{s.twin}: measurement file written")
    files = {}
    for s in specs:
        p = out / "twins" / f"{s.twin}.toml"
        if sealed is not None and (not p.exists()
                                   or _sha256(p) != sealed["twins_sha256"].get(s.twin)):
            raise ConfigError(f"{out}: twin file {p.name} is missing or differs from its seal; "
                              f"refused")
        files[s.twin] = _sha256(p)
    if sealed is None:
        sealed = {"truth_sha256": _sha256(tpath), "twins_sha256": files,
                  "sealed_at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
        write_json_atomic(spath, sealed)
    return sealed


def run_benchmark(out, *, n: int = 40, seed: int = 0, twins_engine: str = "surrogate",
                  preset: str = "tiny", sim: str = "surrogate",
                  diagnose_settings: dict | None = None, library=None, workers: int = 1,
                  scheduler=None, draw: str = "detectable", progress=None) -> BenchmarkResult:
    """Run the blind benchmark into folder ``out`` (see the module docstring).

    Parameters
    ----------
    out : path
        The benchmark's folder; a killed run resumes in it, a different benchmark is refused.
    n : int
        Number of twins (>= 4; 40 gives 20 effect, 10 null, 10 out-of-catalogue).
    seed : int
        Seed of the draw, the twins' runs and their noise.
    twins_engine : {"surrogate", "embedded", "liggghts", "lammps"}
        What makes the twins' data (DEM engines on the workflow ``preset``).
    preset : str
        Workflow preset of a DEM twins engine (ignored by the surrogate, recorded).
    sim : str
        Diagnosing simulator: ``"surrogate"`` or a simulation config path.
    diagnose_settings : dict, optional
        Fields of the simulation config replaced for the diagnosis (tests only: the
        protocol diagnoses with the defaults); recorded in ``truth.json``.
    library : path, optional
        Diagnose every twin on the emulator of the diagnosing configuration's run library
        in this folder (its ``[library]`` table sizes the design; built after the twins
        are sealed, resumed or reused as ``bedstruct diagnose --library`` does), without
        a confirming rerun. Recorded in ``truth.json`` (the design, not the folder).
    workers : int
        Local processes making the twins (one twin each), and for the library's runs.
    scheduler : str, optional
        A Dask scheduler address for the library's runs.
    draw : {"detectable", "prior"}
        Effect magnitudes drawn where the diagnosing model detects the effect with 95 %
        power in a twin's noise (its fingerprints at the base point, on the library's
        emulator when ``library`` is given, which is then built before the twins), or over
        the whole prior.
    progress : callable, optional
        Called with a line per twin made and per twin diagnosed.

    Returns
    -------
    BenchmarkResult
    """
    if twins_engine not in TWIN_ENGINES:
        raise ConfigError(f"twins engine: expected one of {', '.join(TWIN_ENGINES)}; "
                          f"got {twins_engine!r}")
    if draw not in DRAWS:
        raise ConfigError(f"draw: expected one of {', '.join(DRAWS)}; got {draw!r}")
    out = Path(out)
    emulator, ranges = None, None
    bridge, bridged = None, False
    if draw == "detectable":
        if library is not None:
            emulator = _emulator(sim, diagnose_settings, benchmark_design(twins_engine),
                                 library, workers, scheduler, progress is not None)
            simulator = EmulatedSimulator(emulator)
        else:
            cfg = _sim_config(sim, diagnose_settings)
            simulator = make_simulator(cfg, diagnosis_design(benchmark_design(twins_engine),
                                                             cfg.effects))
        if _sim_config(sim, diagnose_settings).bridge.get("probe_runs"):
            # the effects' responses are the bridged engine's: their detectable magnitudes too
            bridge = _bridge_once(out, sim, diagnose_settings, twins_engine, emulator, library,
                                  progress, workers)
            bridged = True
            simulator = bridge.simulator(simulator)
        ranges = _detectable(sim, diagnose_settings, twins_engine, simulator,
                             progress is not None)
    specs = draw_twins(n, seed, twins_engine, ranges)
    truth = _truth_doc(n, seed, twins_engine, preset, sim, diagnose_settings, specs, library,
                       draw, ranges)
    seal = _prepare(out, truth, specs, twins_engine, preset, progress, workers)
    rdir = out / "results"
    rdir.mkdir(exist_ok=True)
    results = {}
    for s in specs:
        rp = rdir / f"{s.twin}.json"
        if rp.exists():
            results[s.twin] = json.loads(rp.read_text())
            continue
        if library is not None and emulator is None:
            emulator = _emulator(sim, diagnose_settings, benchmark_design(twins_engine),
                                 library, workers, scheduler, progress is not None)
        if not bridged:
            bridge = _bridge_once(out, sim, diagnose_settings, twins_engine, emulator, library,
                                  progress, workers)
            bridged = True
        rec = diagnose_file(out / "twins" / f"{s.twin}.toml", sim, settings=diagnose_settings,
                            emulator=emulator, bridge=bridge)
        rec["twin_sha256"] = seal["twins_sha256"][s.twin]
        write_json_atomic(rp, rec)
        results[s.twin] = json.loads(rp.read_text())  # as a resumed run reads it
        if progress is not None:
            progress(f"{s.twin}: {rec['answer']} ({rec['seconds']:.0f} s)")
    summary = score_benchmark(truth, results)
    summary["truth_sha256"] = seal["truth_sha256"]
    summary["sealed_at"] = seal["sealed_at"]
    summary["out"] = str(out)
    write_json_atomic(out / "summary.json", summary)
    res = BenchmarkResult(out=out, n=summary["n"], counts=summary["counts"],
                          top1=tuple(summary["top1_count"]),
                          null_false=tuple(summary["null_false_count"]),
                          ooc_unexplained=tuple(summary["ooc_count"]),
                          coverage=tuple(summary["coverage_count"]),
                          shrink_median=summary["shrink_median"],
                          shrink_ci=tuple(summary["shrink_ci"]), shrink_n=summary["shrink_n"],
                          confusion=summary["confusion"], summary=summary)
    (out / "report.html").write_text(benchmark_html(summary, res.figure()), encoding="utf-8")
    return res


# ---------------------------------------------------------------------------------- CLI
def add_benchmark_arguments(parser) -> None:
    """Arguments of ``bedstruct diagnose benchmark`` on an argparse (sub)parser.

    On a parser of its own (a subcommand) every option is added. On a parser that already
    defines some of them (``--sim``, ``--out``, ``--preset``, ``--seed``, ``--json`` of
    ``bedstruct diagnose``) those are left as they are, and :func:`run_benchmark_command`
    takes their value, ``None`` meaning this module's default.
    """
    import argparse

    def add(*names, **kw):
        try:
            parser.add_argument(*names, **kw)
        except argparse.ArgumentError:  # the parser has it already: shared with its command
            pass

    add("--twins-engine", choices=TWIN_ENGINES, default="surrogate",
        help="benchmark: what makes the twins' data (default surrogate)")
    add("--preset", default="tiny", help="workflow preset of a DEM twins engine (default tiny)")
    add("--n", type=int, default=40,
        help="benchmark: number of twins (>= 4; default 40: 20 effect, 10 null, 10 "
             "out-of-catalogue)")
    add("--seed", type=int, default=0, help="seed of the draw (default 0)")
    add("--draw", choices=DRAWS, default="detectable",
        help="benchmark: effect magnitudes where the diagnosing model detects them "
             "(default) or over the whole prior")
    add("--sim", default="surrogate",
        help="diagnosing simulator: 'surrogate' or a simulation config TOML")
    add("--out", default=None,
        help="benchmark folder (resumed if it holds this benchmark; another is refused)")
    add("--score", nargs="+", metavar="DIR", default=None,
        help="score sealed benchmark folders (together when several); run nothing")
    add("--rediagnose", nargs="+", metavar=("DIR", "TWIN"), default=None,
        help="diagnose a sealed folder's twins (all, or the TWINs named) again with this "
             "code from its own library as recorded, compare with its diagnoses; run nothing")
    add("--json", action="store_true", help="print the summary as one line of JSON (last line)")
    add("--library", default=None, metavar="DIR",
        help="diagnose on the emulator of the diagnosing config's run library in DIR")
    add("--workers", type=int, default=None, help="--library: local processes for its runs")
    add("--scheduler", default=None, help="--library: Dask scheduler address for its runs")
    add("--diagnose-setting", action="append", default=[], metavar="KEY=VALUE",
        help="benchmark: replace a diagnosis setting (replicates, refine, ...); for tests "
             "only, recorded in truth.json")


def _settings(pairs) -> dict:
    out = {}
    for p in pairs:
        k, sep, v = p.partition("=")
        if not sep:
            raise ConfigError(f"--diagnose-setting: expected KEY=VALUE; got {p!r}")
        out[k.strip()] = int(v) if v.strip().lstrip("-").isdigit() else float(v)
    return out


def run_benchmark_command(args) -> int:
    """Run ``bedstruct diagnose benchmark`` from parsed arguments; returns the exit status."""

    def arg(name, default):
        v = getattr(args, name, None)
        return default if v is None else v

    if getattr(args, "score", None):
        return _score_command(args)
    if getattr(args, "rediagnose", None):
        return _rediagnose_command(args)
    if not getattr(args, "out", None):
        raise ConfigError("benchmark: --out DIR is required (or --score DIR to score folders)")
    ignored = [f"--{n.replace('_', '-')}" for n in ("real", "np", "jobs", "cache", "records",
                                                    "refine", "top_up", "twin_jobs")
               if getattr(args, n, None) not in (None, False)]
    if ignored:
        raise ConfigError(f"benchmark: {', '.join(ignored)} "
                          f"{'does' if len(ignored) == 1 else 'do'} not apply (the protocol's "
                          f"settings are frozen; see docs/diagnose-validation.md)")
    engine, sim = arg("twins_engine", "surrogate"), arg("sim", "surrogate")
    res = run_benchmark(args.out, n=arg("n", 40), seed=arg("seed", 0), twins_engine=engine,
                        preset=arg("preset", "tiny"), sim=sim,
                        diagnose_settings=_settings(arg("diagnose_setting", [])) or None,
                        library=arg("library", None), workers=arg("workers", 1),
                        scheduler=arg("scheduler", None), draw=arg("draw", "detectable"),
                        progress=None if arg("json", False) else print)
    if arg("json", False):
        print(json.dumps(to_jsonable(res.json_line())))
    else:
        _print_scores(res.summary, f"blind benchmark: {res.summary['n']} twins on {engine}, "
                                   f"diagnosed on {sim}")
        print(f"  {Path(args.out) / 'report.html'}")
    return 0


def _score_command(args) -> int:
    """``bedstruct diagnose benchmark --score DIR [DIR ...]``: the folders' scores, pooled."""
    used = [f"--{n.replace('_', '-')}" for n in ("out", "sim", "twins_engine", "n", "library",
                                                  "workers", "scheduler", "draw")
            if getattr(args, n, None) not in (None, False, "surrogate", 40, "detectable")]
    if used:
        raise ConfigError(f"benchmark --score: {', '.join(used)} "
                          f"{'does' if len(used) == 1 else 'do'} not apply (scoring runs nothing)")
    s = pool_benchmarks(args.score)
    missing = s["not_diagnosed"]
    if missing:
        what = "1 sealed twin has" if len(missing) == 1 else f"{len(missing)} sealed twins have"
        print(f"warning: {what} no diagnosis yet, left out of every score ({missing[0]}"
              f"{', ...' if len(missing) > 1 else ''}); the benchmark command, run again with "
              f"that folder's arguments, diagnoses them", file=sys.stderr)
    if getattr(args, "json", False):
        keys = ("n", "top1", "top1_ci", "top1_detected", "top1_detected_ci", "null_false",
                "null_false_ci", "ooc_unexplained", "ooc_ci", "ooc_detected", "ooc_detected_ci",
                "shrink_median", "shrink_ci", "shrink_ci_method", "shrink_n", "coverage",
                "coverage_ci", "not_diagnosed", "batches", "commits")
        print(json.dumps(to_jsonable({k: s[k] for k in keys})))
    else:
        what = (f"{len(s['batches'])} benchmark folders scored together" if len(s["batches"]) > 1
                else f"benchmark folder {s['batches'][0]}")
        _print_scores(s, f"{what}: {s['n']} twins")
    return 0


def _rediagnose_command(args) -> int:
    """``bedstruct diagnose benchmark --rediagnose DIR``: exit 0 when every answer is the
    recorded one, 1 otherwise."""
    used = [f"--{n.replace('_', '-')}" for n in ("out", "twins_engine", "n", "library",
                                                  "workers", "scheduler", "draw")
            if getattr(args, n, None) not in (None, False, "surrogate", 40, "detectable")]
    if used:
        raise ConfigError(f"benchmark --rediagnose: {', '.join(used)} "
                          f"{'does' if len(used) == 1 else 'do'} not apply (it reads the "
                          f"folder's own settings and library)")
    sim = getattr(args, "sim", None)
    folder, twins = args.rediagnose[0], args.rediagnose[1:] or None
    r = rediagnose_benchmark(folder, twins=twins, sim=None if sim in (None, "surrogate") else sim,
                             progress=not getattr(args, "json", False))
    if getattr(args, "json", False):
        print(json.dumps(to_jsonable({k: r[k] for k in ("n", "same", "differ",
                                                         "magnitude_rel_diff")})))
    else:
        print(f"{folder}: {r['same']} of {r['n']} twins given the recorded answer (magnitudes "
              f"within {100 * r['magnitude_rel_diff']:.3g} % of the recorded ones)")
        for t, d in r["differ"].items():
            print(f"  {t}: recorded {d['recorded']['answer']}, now {d['now']['answer']}")
    return 0 if not r["differ"] else 1


def _print_scores(s: dict, header: str) -> None:
    """The scores of a summary in plain lines."""

    def ci(key):
        lo, hi = s[key]
        return "n/a" if lo is None or not math.isfinite(lo) else f"{lo:.3f}-{hi:.3f}"

    k, n = s["top1_count"]
    print(header)
    kd, nd = s["top1_detected_count"]
    kp = s["top1_partial_count"][0]
    partial = f", {kp} of them partial" if kp else ""
    print(f"  top-1 {k}/{n} ({ci('top1_ci')}{partial}; {kd}/{nd} where the gap is "
          f"significant); "
          f"null false {s['null_false_count'][0]}/"
          f"{s['null_false_count'][1]} ({ci('null_false_ci')}); out-of-catalogue "
          f"unexplained {s['ooc_count'][0]}/{s['ooc_count'][1]} ({ci('ooc_ci')}; "
          f"{s['ooc_detected_count'][0]}/{s['ooc_detected_count'][1]} where the gap is "
          f"significant)")
    print(f"  shrink median {s['shrink_median']:.3g} over {s['shrink_n']} ({ci('shrink_ci')}); "
          f"coverage {s['coverage_count'][0]}/{s['coverage_count'][1]} ({ci('coverage_ci')})")
