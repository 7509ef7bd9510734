"""A diagnosis served by a run library: the emulator answers, the simulator confirms.

:func:`diagnose_with_library` builds (or resumes, or reuses) the run library of a
simulator and a catalogue (:func:`~bedstruct.diagnose.run_library.build_library`), fits
its emulator (:func:`~bedstruct.diagnose.emulator_fit.fit_emulator`), runs
:func:`~bedstruct.diagnose.diagnose` on the emulated simulator, then reruns the real
simulator at the chosen point (recalibrated base parameters plus the attributed
magnitudes) and says how well the emulator predicted that rerun. The library is paid
for once per simulator configuration, catalogue, measurement design and code version;
every later diagnosis on it costs the emulator's time and one confirming rerun.
"""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..errors import ConfigError
from .answer import _observable_words, quantity_text
from .bridge import engine_bridge
from .confirm import RERUN_SEED_STRIDE
from .diagnosis import diagnose
from .diagnosis_result import Diagnosis
from .emulator import EmulatedSimulator, EmulatorCheck
from .emulator_fit import fit_emulator
from .run_design import design_spec
from .run_library import build_library, load_library

__all__ = ["AmortisedDiagnosis", "diagnose_with_library", "library_emulator",
           "confirming_runs", "UNTRUSTED_LOO_RMSE_SIGMA", "UNTRUSTED_CONFIRM_RMSE_SIGMA"]

#: An emulator whose leave-one-point-out error (RMS of the standardised errors, 1 when
#: its stated uncertainty is right) is above this is overconfident: its answer is not to
#: be trusted.
UNTRUSTED_LOO_RMSE_SIGMA = 3.0
#: Likewise for the RMS of the standardised errors of its prediction of the confirming rerun.
UNTRUSTED_CONFIRM_RMSE_SIGMA = 3.0


@dataclass(frozen=True)
class AmortisedDiagnosis:
    """A diagnosis made on an emulator, with the real simulator's confirming rerun.

    Attributes
    ----------
    diagnosis : Diagnosis
        The answer (its simulator is the emulator).
    check : EmulatorCheck
        How well the emulator predicted the real simulator's rerun at the chosen point,
        per component (:meth:`confirm_rows`) and in summary (``rmse_sigma``: RMS of the
        standardised errors, 1 when calibrated; ``within_2sigma``: the fraction within
        2 standard deviations, 0.95 when calibrated).
    point : dict
        The base parameters of the rerun (recalibrated).
    magnitudes : dict
        The effect magnitudes of the rerun (empty when no effect was attributed).
    library : Path
        The run library's folder.
    library_runs : int
        Runs in the library.
    loo_rmse_sigma, loo_within_2sigma : float
        The emulator's leave-one-point-out error in units of its predictive sigma, and
        the fraction of left-out runs within 2 sigma.
    names, n_components : tuple of str, dict
        The emulator's observables and their numbers of components (the order of the
        check's components, :meth:`confirm_rows`).
    """

    diagnosis: Diagnosis
    check: EmulatorCheck
    point: dict
    magnitudes: dict
    library: Path
    library_runs: int
    loo_rmse_sigma: float
    loo_within_2sigma: float
    names: tuple = ()
    n_components: dict = None

    def confirm_rows(self) -> list[dict]:
        """Per observable component: the emulator's prediction against the confirming rerun.

        Each row: ``observable``, ``component``, ``kind``, ``role`` (the measurement file's,
        or ``"candidate"``), ``unit`` (SI), ``predicted`` and ``predicted_sd`` (the
        emulator's prediction of the rerun's mean, made before the rerun, and its
        predictive standard deviation), ``rerun`` (the mean of the simulator's runs) and
        ``z`` (standardised error, ``(rerun - predicted) / predicted_sd``), in the
        emulator's component order.
        """
        design = self.diagnosis.fingerprints.design
        meta = {m.name: m for m in tuple(design.measurements) + tuple(design.unmeasured)}
        meas = {m.name: m for m in self.diagnosis.measurements}
        c = self.check
        rows, i = [], 0
        for name in self.names:
            m = meas.get(name) or meta.get(name)
            for j in range(self.n_components[name]):
                label = str(m.labels[j]) if m is not None and j < len(m.labels) else str(j)
                rows.append({"observable": name, "component": label,
                             "kind": m.kind if m is not None else "",
                             "role": m.role if name in meas else "candidate",
                             "unit": m.unit if m is not None else "",
                             "predicted": float(c.predicted[i]),
                             "predicted_sd": float(c.predicted_sd[i]),
                             "rerun": float(c.observed[i]), "z": float(c.z_mean[i])})
                i += 1
        return rows

    @property
    def caveat(self) -> str | None:
        """Why the answer is not to be trusted, or ``None``: the emulator is overconfident
        when its leave-one-point-out error is above :data:`UNTRUSTED_LOO_RMSE_SIGMA` or
        its prediction of the confirming rerun is off by more than
        :data:`UNTRUSTED_CONFIRM_RMSE_SIGMA` (RMS, in units of its stated uncertainty)."""
        why = []
        if np.isfinite(self.loo_rmse_sigma) and self.loo_rmse_sigma > UNTRUSTED_LOO_RMSE_SIGMA:
            why.append(f"its leave-one-out error is {self.loo_rmse_sigma:.3g} times its stated "
                       "uncertainty")
        rz = float(self.check.rmse_sigma)
        if np.isfinite(rz) and rz > UNTRUSTED_CONFIRM_RMSE_SIGMA:
            why.append(f"it missed the confirming rerun by {rz:.3g} times its stated "
                       "uncertainty (RMS)")
        if not why:
            return None
        return ("the emulator is overconfident (" + "; ".join(why) + "): rebuild the run "
                "library (more runs, or a narrower design) or diagnose without --library")

    @property
    def trusted(self) -> bool:
        """Whether the emulator's answer may be trusted (no :attr:`caveat`)."""
        return self.caveat is None

    def emulator_line(self) -> str:
        """One plain line: the emulator's leave-one-point-out error."""
        v = self.loo_rmse_sigma
        figure = f"{v:.0f}" if v >= 10 else f"{v:.2f}"
        return (f"Emulator: leave-one-out error {figure} of its stated uncertainty "
                f"({100 * self.loo_within_2sigma:.0f} % within 2 sigma)")

    def to_json(self) -> dict:
        """The emulator's part of a diagnosis' JSON (the ``emulator`` block)."""
        return {"library": str(self.library), "library_runs": int(self.library_runs),
                "loo_rmse_sigma": float(self.loo_rmse_sigma),
                "loo_within_2sigma": float(self.loo_within_2sigma),
                "trusted": self.trusted, "caveat": self.caveat,
                "confirm_point": dict(self.point), "confirm_magnitudes": dict(self.magnitudes),
                "confirm_runs": int(self.check.n_runs),
                "confirm_rmse_sigma": float(self.check.rmse_sigma),
                "confirm_within_2sigma": float(self.check.within_2sigma),
                "confirm": self.confirm_rows()}

    def summary_line(self) -> str:
        """One plain sentence: how well the emulator predicted the simulator's rerun."""
        c = self.check
        n = int(np.sum(np.isfinite(c.z_mean)))
        if n == 0:
            return (f"Check: the simulator was rerun at the answer ({c.n_runs} runs), but no "
                    "observable could be compared with the emulator's prediction.")
        inside = int(np.sum(np.abs(c.z_mean[np.isfinite(c.z_mean)]) <= 2.0))
        text = (f"Check: the simulator, rerun at the answer ({c.n_runs} runs), gave {inside} of "
                f"{n} observable values within 2 standard deviations of what the emulator "
                f"({self.library_runs} library runs) predicted before the rerun")
        k = int(np.nanargmax(np.abs(c.z_mean)))
        row = self.confirm_rows()[k]
        if abs(row["z"]) > 2.0:
            what = _observable_words(row)
            text += (f"; furthest off: {what}, predicted "
                     f"{quantity_text(row['predicted'], row['unit'], row['kind'], sigma=row['predicted_sd'])}"
                     f", rerun {quantity_text(row['rerun'], row['unit'], row['kind'])}")
        return text + "."


def confirming_runs(simulator, base, effects, seeds, workers: int = 1) -> list:
    """The simulator's runs at one point, one per seed (in ``workers`` local processes)."""
    if workers > 1 and len(seeds) > 1:
        with ProcessPoolExecutor(min(workers, len(seeds))) as pool:
            return list(pool.map(simulator, [base] * len(seeds), [effects] * len(seeds), seeds))
    return [simulator(base, effects, s) for s in seeds]


def library_emulator(simulator, *, base: Mapping[str, float], library,
                     effects: Sequence | None = None,
                     nuisance: Sequence[str] = ("cohesion_energy_density",),
                     vary: Mapping | None = None, n_base: int = 16, n_per_effect: int = 16,
                     library_replicates: int = 3, workers: int = 1, scheduler=None,
                     progress: bool = False, replay: bool = False):
    """The emulator of a simulator's run library: built (or resumed, or reused) and fitted.

    The library's design varies each ``nuisance`` base parameter over ``vary`` (default
    +-25 %) and each catalogue effect over its prior
    (:func:`~bedstruct.diagnose.run_design.design_spec`). Parameters as
    :func:`diagnose_with_library`; ``replay`` fits the library's runs as recorded when it
    was made by other code (:func:`~bedstruct.diagnose.run_library.load_library`) and
    runs nothing: the library must hold the whole design.

    Returns
    -------
    Emulator
        Fitted on the library (``emulator.n_runs`` runs, ``emulator.key`` its key).
    """
    effects = tuple(effects) if effects is not None else None
    if vary is None:
        vary = {name: 0.25 for name in nuisance}
    spec = design_spec(dict(base), vary=vary, effects=effects, n_base=n_base,
                       n_per_effect=n_per_effect, replicates=library_replicates)
    if replay:
        lib = load_library(Path(library), simulator, replay=True)
        if lib.spec != spec or not lib.complete:
            raise ConfigError(f"run library {library}: it does not hold the design asked for "
                              f"({lib.n_runs} runs; complete: {lib.complete}); a replay runs "
                              f"nothing")
    else:
        lib = build_library(simulator, spec, Path(library), workers=workers,
                            scheduler=scheduler, progress=progress)
    return fit_emulator(lib, progress=progress)


def diagnose_with_library(measurements, simulator, *, base: Mapping[str, float], library,
                          effects: Sequence | None = None,
                          nuisance: Sequence[str] = ("cohesion_energy_density",),
                          vary: Mapping | None = None, n_base: int = 16, n_per_effect: int = 16,
                          library_replicates: int = 3, workers: int = 1, scheduler=None,
                          confirm_seeds: int = 2, bridge: Mapping | None = None,
                          engine: Mapping | None = None, progress: bool = False,
                          **diagnose_kwargs) -> AmortisedDiagnosis:
    """Diagnose on the emulator of a run library, then confirm with the real simulator.

    Parameters
    ----------
    measurements : MeasurementSet
    simulator : callable
        The real simulator, ``simulator(base, effects, seed) -> Observations``.
    base : mapping
        Calibrated base parameters (SI).
    library : path-like
        Folder of the run library: built there when absent, resumed when cut short,
        reused when its key matches, refused (:class:`~bedstruct.diagnose.run_library.StaleLibraryError`)
        when it was made for another simulator, catalogue, design or code.
    effects : sequence of Effect, optional
        Catalogue (default: all).
    nuisance : sequence of str
        Base parameters the recalibration may change; each is varied in the library.
    vary : mapping, optional
        Ranges of the varied base parameters, ``(lo, hi)`` or a relative half-width
        (default: each nuisance parameter +-25 %).
    n_base, n_per_effect, library_replicates : int
        Size of the library's design (see :func:`~bedstruct.diagnose.run_design.design_spec`).
    workers : int
        Local processes for the library's runs and the confirming rerun.
    scheduler : str, optional
        Address of a Dask distributed scheduler (``tcp://...``) for the library's runs.
    confirm_seeds : int
        Seeds of the confirming rerun.
    bridge : mapping, optional
        A ``[bridge]`` table (:mod:`bedstruct.diagnose.bridge`): the measurements are
        compared with that engine's baseline, bridged to the emulator at ``base``; its
        runs are kept in the table's ``cache``, else in ``library/bridge``.
    engine : mapping, optional
        The ``[engine]`` table the bridge runs start from.
    **diagnose_kwargs
        Passed on to :func:`~bedstruct.diagnose.diagnose` (``replicates``, ``alpha``...).

    Returns
    -------
    AmortisedDiagnosis

    Raises
    ------
    ConfigError
        When the diagnosis leaves the library's design box (the message names the
        parameter or magnitude): widen ``vary`` and build again.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import bedstruct.diagnose as dg
    >>> from bedstruct.diagnose.amortised import diagnose_with_library
    >>> ms = dg.load_measurements(pathlib.Path(dg.__file__).parents[2] / "data/measurements/seed.toml")
    >>> effects = dg.catalogue(["missing_fines", "wall_friction"])
    >>> sim = dg.SurrogateSimulator(dg.diagnosis_design(ms, effects))
    >>> res = diagnose_with_library(ms, sim, base=dg.BASE_PARAMETERS, effects=effects,
    ...                             library=tempfile.mkdtemp(), n_base=6, n_per_effect=6,
    ...                             replicates=2, refine=0)
    >>> res.diagnosis.shrink.model, res.library_runs > 0
    ('missing_fines', True)
    """
    if confirm_seeds < 1:
        raise ConfigError(f"confirm_seeds must be >= 1; got {confirm_seeds}")
    effects = tuple(effects) if effects is not None else None
    emulator = library_emulator(simulator, base=base, library=library, effects=effects,
                                nuisance=nuisance, vary=vary, n_base=n_base,
                                n_per_effect=n_per_effect, library_replicates=library_replicates,
                                workers=workers, scheduler=scheduler, progress=progress)
    emulated = EmulatedSimulator(emulator)
    if bridge:
        diagnose_kwargs["bridge"] = engine_bridge(
            measurements, emulated, base=base, bridge=bridge, engine=engine,
            cache=bridge.get("cache") or Path(library) / "bridge", effects=effects,
            workers=workers, progress=progress)
    diag = diagnose(measurements, emulated, base=base, effects=effects, nuisance=nuisance,
                    progress=progress, **diagnose_kwargs)
    sh = diag.shrink
    point = dict(base)
    point.update({k: float(base[k]) + float(v) for k, v in sh.nuisance.items()})
    magnitudes = {k: float(v) for k, v in sh.magnitudes.items()}
    # the emulator's prediction at the answer is made first; the rerun then tests it
    emulator.predict(point, magnitudes)
    seeds = [RERUN_SEED_STRIDE + i for i in range(int(confirm_seeds))]
    runs = confirming_runs(simulator, point, magnitudes, seeds, workers)
    check = emulator.check(runs, point, magnitudes)
    return AmortisedDiagnosis(diag, check, point, magnitudes, Path(library),
                              emulator.n_runs,
                              float(emulator.loo.loo_rmse_sigma),
                              float(emulator.loo.loo_within_2sigma), tuple(emulator.names),
                              dict(emulator.n_components))
