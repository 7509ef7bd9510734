"""The engine bridge: measurements compared with the baseline of the user's own engine.

The diagnosis learns how each catalogue effect moves the observables from the
diagnosing simulator (the embedded engine, or the emulator of its run library). When
the user's simulation runs on another code (LIGGGHTS, LAMMPS), the two codes' baselines
differ by a systematic offset that is no effect of the catalogue: at the same nominal
parameters one code's bed may be denser at the stroke's start or its surface smoother.
Read as a gap, that offset is attributed to whichever effect resembles it, or left
``unexplained``.

A bridge removes it. The user's engine is run ``n`` times at the base point; the offset
of each observable component is

.. math::

    \\delta = \\bar y_\\text{engine}(\\theta_0) - \\mu_\\text{diagnosing}(\\theta_0),

with :math:`\\mu_\\text{diagnosing}` the emulator's predicted mean (or the mean of as
many runs of the diagnosing simulator). The measurements are then diagnosed as
:math:`y - \\delta`, with uncertainty :math:`\\sqrt{u^2 + \\sigma_\\delta^2}`,

.. math::

    \\sigma_\\delta^2 = \\max(s_\\text{engine}^2, s_\\text{diagnosing}^2) / n
    + \\sigma_\\mu^2,

:math:`s` the run-to-run standard deviations (the larger of the two, as ``n`` runs
estimate a variance poorly) and :math:`\\sigma_\\mu` the emulator's own uncertainty at
the base point. This is the first-order (constant-offset) model discrepancy of
multi-fidelity modelling: the effects' responses and the recalibrated parameters'
sensitivities still come from the diagnosing simulator, and the offset is taken to be
the same over the small region the recalibration explores.

The offset alone assumes that the two codes realise each effect alike. They need not:
LIGGGHTS' capillary bridges (Soulié) replace the particles' cohesion where the embedded
engine's (Willett) act on top of it, and the same fraction of missing fines changes a
coarse layer differently in the two codes. With ``probe_runs`` the user's engine is also
run at one **probe magnitude** :math:`a_p` of each catalogue effect it realises (the
effect's larger reference magnitude), on the first ``probe_runs`` seeds of the base runs,
and the difference of the two codes' responses to it,

.. math::

    \\Delta_e = \\overline{[y_\\text{engine}(a_p) - y_\\text{engine}(0)]}
    - [\\mu_\\text{diagnosing}(a_p) - \\mu_\\text{diagnosing}(0)],

(the engine's runs paired by seed) corrects the diagnosing simulator wherever that
effect is on: a run at magnitude :math:`a` returns its own value plus
:math:`(a / a_p)\\,\\Delta_e` (:meth:`EngineBridge.simulator`), so the fingerprints,
refinement and reruns of the diagnosis all see the user's engine's response to the
effect, interpolated linearly in the magnitude between 0 and the probe. With ``probes =
"reference"`` the engine is also run at the effect's smaller reference magnitude (half the
prior's top), and the correction is interpolated piecewise-linearly through 0 and both
probes: an effect whose response in the user's engine is not proportional to its
magnitude (LIGGGHTS' bridges, which take the place of the cohesion already at a small
liquid content; a few missing fines) is then followed between the probes. The correction's
standard deviation :math:`\\sigma_\\Delta` (engine scatter of the paired differences over
the probe runs, plus the emulator's own uncertainty at both points) is counted in full:
the correction, kept at its measured value, enters as added scatter of the bridged runs,
:math:`(a/a_p)\\,\\sigma_\\Delta` per run, and, shared by every run, in the
prediction a confirming rerun is checked against
(:func:`~bedstruct.diagnose.confirm.confirm_attribution`). Effects the user's engine does
not realise keep the diagnosing simulator's response.

In a simulation configuration::

    [bridge]
    engine = "liggghts"     # the engine whose baseline the measurements are compared with
    runs = 6                # its runs at the base point (>= 2)
    seed = 0                # first seed of those runs
    probe_runs = 4          # optional: runs at each effect's probe magnitude (0: offset only)
    probes = "top"          # optional: probe at the top reference magnitude ("top", default)
                            # or at both reference magnitudes ("reference")
    cache = "bridge-runs"   # optional: folder keeping the runs (relative to the file)

:func:`engine_bridge` makes the runs and the offset; :func:`bridge_offset` computes it
from runs made elsewhere; :meth:`EngineBridge.apply` translates a measurement set.

.. versionadded:: 0.1
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping, Sequence

import json
import zlib

import numpy as np

from ..errors import ConfigError
from .measurements import MeasurementSet, Observations

__all__ = ["EngineBridge", "bridge_offset", "engine_bridge", "bridge_runs", "bridge_table",
           "bridge_seeds", "BRIDGE_KEYS",
           "BRIDGE_SEED_STRIDE", "BridgedSimulator", "effect_probes"]

#: Keys of the ``[bridge]`` table and their types.
BRIDGE_KEYS = {"engine": str, "runs": int, "seed": int, "cache": str, "probe_runs": int,
               "probes": str}
#: Values of the ``[bridge]`` key ``probes``: the reference magnitudes probed.
PROBE_SETS = ("top", "reference")
#: Seeds of the bridge runs start here (plus the table's ``seed``): apart from the
#: diagnosis' replicate and rerun seeds.
BRIDGE_SEED_STRIDE = 500_000


@dataclass(frozen=True)
class EngineBridge:
    """The offset between the user's engine and the diagnosing simulator at the base point.

    Attributes
    ----------
    engine : str
        The bridged engine (``"liggghts"``, ``"lammps"``, ``"embedded"``).
    offset : dict of str to (k,) ndarray
        Per observable, engine minus diagnosing simulator (canonical units).
    offset_sd : dict of str to (k,) ndarray
        Standard deviation of each offset.
    n_runs : int
        Runs of the engine at the base point.
    base : dict
        The base point (SI).
    reference : str
        What the engine was compared with (``"emulator"`` or ``"simulator, n runs"``).
    left_out : tuple of str
        Observables the engine's runs could not observe: no offset, left out of a
        bridged measurement set.
    seeds : tuple of int
        The engine runs' seeds.
    runs : dict of str to (n_runs, k) ndarray
        The engine runs' observations of each bridged observable.
    probe_magnitudes : dict of str to float
        Per probed effect, the magnitude the engine was run at (empty: offset only).
    effect_shift : dict of str to dict
        Per probed effect and observable, :math:`\\Delta_e`: the engine's response to the
        probe minus the diagnosing simulator's (canonical units).
    effect_shift_sd : dict of str to dict
        Its standard deviation.
    probe_runs : int
        Engine runs at each probe magnitude.
    inner_probes : dict of str to tuple
        Per effect probed below its probe magnitude too (``probes = "reference"``), its
        inner probes as ``(magnitude, shift, shift_sd)`` in increasing magnitude, shift and
        its standard deviation per observable as in :attr:`effect_shift`.
    unprobed : tuple of str
        Catalogue effects the engine does not realise: the diagnosing simulator's
        response is used as it is.
    """

    engine: str
    offset: dict
    offset_sd: dict
    n_runs: int
    base: dict
    reference: str
    left_out: tuple = ()
    seeds: tuple = ()
    runs: dict = field(default_factory=dict, repr=False)
    probe_magnitudes: dict = field(default_factory=dict)
    effect_shift: dict = field(default_factory=dict, repr=False)
    effect_shift_sd: dict = field(default_factory=dict, repr=False)
    probe_runs: int = 0
    unprobed: tuple = ()
    inner_probes: dict = field(default_factory=dict, repr=False)

    def _weights(self, e: str, a: float) -> list:
        """``(weight, shift, sd)`` of each probe of effect ``e`` at magnitude ``a``: the
        piecewise-linear interpolation through 0, the inner probes and the probe
        magnitude, the last segment extended beyond it."""
        knots = [(0.0, None, None)] + list(self.inner_probes.get(e, ())) + [
            (float(self.probe_magnitudes[e]), self.effect_shift[e], self.effect_shift_sd[e])]
        k = 1
        while k < len(knots) - 1 and a > knots[k][0]:
            k += 1
        (a0, s0, d0), (a1, s1, d1) = knots[k - 1], knots[k]
        t = (a - a0) / (a1 - a0)
        out = [(t, s1, d1)]
        if s0 is not None:
            out.append((1.0 - t, s0, d0))
        return out

    def correction(self, effects: Mapping[str, float]) -> tuple[dict, dict]:
        """The correction of a diagnosing-simulator run at effect magnitudes ``effects``.

        Returns
        -------
        shift, sd : dict of str to (k,) ndarray
            Per bridged observable, :math:`\\sum_e (a_e / a_{p,e})\\,\\Delta_e` and its
            standard deviation (the effects' terms independent). With inner probes
            (:attr:`inner_probes`) each effect's term is the piecewise-linear interpolation
            through 0 and its probes (the last segment extended beyond the probe
            magnitude), its variance the weighted sum of the two neighbouring probes'
            (taken as independent, though both pair with the same base runs). Empty
            without probes or with no probed effect on.

        Examples
        --------
        >>> import numpy as np
        >>> from bedstruct.diagnose.bridge import EngineBridge
        >>> b = EngineBridge("liggghts", {"aor": np.array([1.0])}, {"aor": np.array([0.4])},
        ...                  6, {}, "emulator", probe_magnitudes={"capillary_bridges": 0.8},
        ...                  effect_shift={"capillary_bridges": {"aor": np.array([-2.0])}},
        ...                  effect_shift_sd={"capillary_bridges": {"aor": np.array([0.5])}})
        >>> shift, sd = b.correction({"capillary_bridges": 0.4})
        >>> float(shift["aor"][0]), float(sd["aor"][0])
        (-1.0, 0.25)
        """
        shift, var = {}, {}
        for e, a in effects.items():
            if e not in self.effect_shift or float(a) == 0.0:
                continue
            for w, sh, sd in self._weights(e, float(a)):
                for name, d in sh.items():
                    shift[name] = shift.get(name, 0.0) + w * np.asarray(d, float)
                    var[name] = var.get(name, 0.0) + (w * np.asarray(sd[name], float)) ** 2
        return shift, {k: np.sqrt(v) for k, v in var.items()}

    def simulator(self, simulator):
        """``simulator`` corrected by the probed effects' responses (:class:`BridgedSimulator`);
        ``simulator`` itself when the bridge has no probes."""
        if not self.effect_shift:
            return simulator
        return BridgedSimulator(simulator, self)

    def apply(self, measurements: MeasurementSet) -> MeasurementSet:
        """The measurement set in the diagnosing simulator's frame: ``y - offset``,
        uncertainty ``sqrt(u**2 + offset_sd**2)``.

        Observables the engine's runs could not observe (:attr:`left_out`) are left out
        (see :meth:`note`); candidate observables (no values) and those read in no trial
        pass unchanged.

        Raises
        ------
        ConfigError
            A measured observable the bridge was not made for (its runs did not observe
            it), or one with another number of components.

        Examples
        --------
        >>> import numpy as np
        >>> from bedstruct.diagnose import MeasurementSet, measurement_from_dict
        >>> from bedstruct.diagnose.bridge import EngineBridge
        >>> m = measurement_from_dict({"name": "aor", "kind": "static_angle", "value": 33.0,
        ...                            "uncertainty": 0.3, "unit": "deg"})
        >>> b = EngineBridge("liggghts", {"aor": np.array([1.0])}, {"aor": np.array([0.4])},
        ...                  6, {}, "emulator")
        >>> out = b.apply(MeasurementSet((m,)))
        >>> float(out["aor"].values[0]), round(float(out["aor"].uncertainty[0]), 3)
        (32.0, 0.5)
        """
        keep = []
        for m in measurements.measurements:
            if m.name in self.left_out:
                continue
            if m.name not in self.offset:
                if m.role == "candidate":
                    keep.append(m)
                    continue
                raise ConfigError(f"bridge: observable {m.name!r} was not run on the "
                                  f"{self.engine} engine (the bridge holds "
                                  f"{', '.join(self.offset)}); make the bridge from this "
                                  f"measurement file")
            d = np.asarray(self.offset[m.name], float)
            s = np.asarray(self.offset_sd[m.name], float)
            if d.shape != m.values.shape:
                raise ConfigError(f"bridge: observable {m.name!r} has {m.values.shape[0]} "
                                  f"components; the {self.engine} runs gave {d.shape[0]}")
            reps = None if m.replicates is None else np.asarray(m.replicates, float) - d
            keep.append(replace(m, values=m.values - d, uncertainty=np.hypot(m.uncertainty, s),
                                replicates=reps))
        return replace(measurements, measurements=tuple(keep))

    def note(self) -> str:
        """One sentence for the diagnosis' data notes."""
        out = (f"measurements compared with the {self.engine} baseline: the offset of "
               f"{self.n_runs} {self.engine} runs at the base point from the "
               f"{self.reference} is subtracted (the measured values shown are the "
               f"measurements less that offset) and its uncertainty added")
        if self.left_out:
            out += (f"; {', '.join(self.left_out)} left out (the {self.engine} runs did not "
                    f"observe them)")
        if self.effect_shift:
            probes = ", ".join(
                f"{e} at {' and '.join(f'{m:g}' for m, _, _ in self.inner_probes.get(e, ()))}"
                f"{' and ' if self.inner_probes.get(e) else ''}{a:g}"
                for e, a in self.probe_magnitudes.items())
            out += (f"; the effects' responses are the {self.engine} engine's, from "
                    f"{self.probe_runs} runs at each probe ({probes})")
            if self.unprobed:
                out += (f"; {', '.join(self.unprobed)} keep the diagnosing simulator's response "
                        f"(the {self.engine} engine does not realise them)")
        return out

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready summary (offsets and their standard deviations per observable)."""
        return {"engine": self.engine, "n_runs": int(self.n_runs), "reference": self.reference,
                "base": dict(self.base), "seeds": [int(s) for s in self.seeds],
                "offset": {k: np.asarray(v, float).tolist() for k, v in self.offset.items()},
                "offset_sd": {k: np.asarray(v, float).tolist() for k, v in self.offset_sd.items()},
                "left_out": list(self.left_out),
                **({"probe_runs": int(self.probe_runs),
                    "probe_magnitudes": {e: float(a) for e, a in self.probe_magnitudes.items()},
                    "effect_shift": {e: {k: np.asarray(v, float).tolist() for k, v in d.items()}
                                     for e, d in self.effect_shift.items()},
                    "effect_shift_sd": {e: {k: np.asarray(v, float).tolist() for k, v in d.items()}
                                        for e, d in self.effect_shift_sd.items()},
                    "unprobed": list(self.unprobed)} if self.effect_shift else {}),
                **({"inner_probes": {
                    e: [{"magnitude": float(m),
                         "shift": {k: np.asarray(v, float).tolist() for k, v in sh.items()},
                         "shift_sd": {k: np.asarray(v, float).tolist() for k, v in sd.items()}}
                        for m, sh, sd in probes]
                    for e, probes in self.inner_probes.items()}} if self.inner_probes else {})}


class BridgedSimulator:
    """A diagnosing simulator whose runs carry the user's engine's response to each probed
    effect (:meth:`EngineBridge.simulator`).

    A call at effect magnitudes :math:`a_e` returns the simulator's run plus
    :math:`\\sum_e (a_e/a_{p,e})\\,\\Delta_e` (interpolated between the probes where there are
    inner ones) and a seeded draw of the correction's
    uncertainty (:meth:`EngineBridge.correction`); other attributes (``names``,
    ``parameter_box``, ``emulator``...) are the wrapped simulator's.

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct.diagnose import Observations
    >>> from bedstruct.diagnose.bridge import BridgedSimulator, EngineBridge
    >>> b = EngineBridge("liggghts", {"aor": np.array([0.0])}, {"aor": np.array([0.0])},
    ...                  6, {}, "emulator", probe_magnitudes={"capillary_bridges": 0.8},
    ...                  effect_shift={"capillary_bridges": {"aor": np.array([-2.0])}},
    ...                  effect_shift_sd={"capillary_bridges": {"aor": np.array([0.0])}})
    >>> sim = BridgedSimulator(lambda base, effects, seed: Observations({"aor": [33.0]}), b)
    >>> float(sim({}, {"capillary_bridges": 0.8}, 1)["aor"][0]), float(sim({}, {}, 1)["aor"][0])
    (31.0, 33.0)
    """

    def __init__(self, simulator, bridge: EngineBridge):
        self.simulator = simulator
        self.bridge = bridge
        self.name = f"{getattr(simulator, 'name', type(simulator).__name__)}+{bridge.engine} effects"

    def __getattr__(self, attr):
        if attr in ("simulator", "bridge"):
            raise AttributeError(attr)
        return getattr(self.simulator, attr)

    def __call__(self, base, effects, seed):
        obs = self.simulator(base, effects, seed)
        on = {e: float(a) for e, a in effects.items() if float(a) != 0.0}
        shift, sd = self.bridge.correction(on)
        if not shift:
            return obs
        tag = zlib.crc32(json.dumps(sorted(on.items())).encode())
        rng = np.random.default_rng([int(seed), tag, 23])
        vals = {}
        for name in obs.names:
            v = np.asarray(obs[name], float)
            if name in shift:
                draw = rng.standard_normal(v.shape[0])
                v = v + shift[name] + sd[name] * draw
            vals[name] = v
        return Observations(vals, source=obs.source)


def bridge_offset(engine_runs: Sequence[Observations], reference_mean: Mapping[str, Any],
                  reference_sd: Mapping[str, Any], reference_noise_sd: Mapping[str, Any], *,
                  engine: str, base: Mapping[str, float] | None = None,
                  reference: str = "emulator", seeds: Sequence[int] = ()) -> EngineBridge:
    """The bridge from ``engine_runs`` (runs of the user's engine at the base point).

    Parameters
    ----------
    engine_runs : sequence of Observations
        At least two runs of the user's engine at the base point.
    reference_mean, reference_sd, reference_noise_sd : mapping of str to (k,) array_like
        The diagnosing simulator at the same point: its predicted mean, that mean's own
        standard deviation (an emulator's :attr:`~bedstruct.diagnose.emulator.Prediction.sd`;
        see the notes for a mean of runs) and its run-to-run standard deviation.
    engine : str
        Name of the user's engine.

    Returns
    -------
    EngineBridge

    Notes
    -----
    For a reference that is itself a mean of ``m`` runs, pass ``reference_sd`` =
    ``s / sqrt(m)``. A component that an engine run did not observe (NaN) is averaged
    over the runs that did; an observable with a component no run observed, or observed
    by one run only, gets no offset and is listed in :attr:`EngineBridge.left_out`.

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct.diagnose import Observations
    >>> from bedstruct.diagnose.bridge import bridge_offset
    >>> runs = [Observations({"aor": [33.0]}), Observations({"aor": [35.0]})]
    >>> b = bridge_offset(runs, {"aor": [32.0]}, {"aor": [0.0]}, {"aor": [1.0]},
    ...                   engine="liggghts")
    >>> float(b.offset["aor"][0]), round(float(b.offset_sd["aor"][0]), 3)
    (2.0, 1.0)
    """
    runs = list(engine_runs)
    if len(runs) < 2:
        raise ConfigError(f"bridge: need at least 2 runs of the {engine} engine; got {len(runs)}")
    offset, sd, left = {}, {}, []
    for name in reference_mean:
        mu = np.atleast_1d(np.asarray(reference_mean[name], float))
        if any(name not in r for r in runs):
            left.append(name)
            continue
        y = np.array([np.atleast_1d(np.asarray(r[name], float)) for r in runs])
        if y.shape[1] != mu.shape[0]:
            raise ConfigError(f"bridge: observable {name!r}: the {engine} runs give "
                              f"{y.shape[1]} components, the diagnosing simulator {mu.shape[0]}")
        n = np.isfinite(y).sum(axis=0)
        if np.any(n < 2) or not np.all(np.isfinite(mu)):
            left.append(name)
            continue
        ybar = np.nanmean(y, axis=0)
        s_eng = np.nanstd(y, axis=0, ddof=1)
        s_ref = np.atleast_1d(np.asarray(reference_noise_sd[name], float))
        s_mu = np.atleast_1d(np.asarray(reference_sd[name], float))
        offset[name] = ybar - mu
        sd[name] = np.sqrt(np.maximum(s_eng, s_ref) ** 2 / n + s_mu ** 2)
    if not offset:
        raise ConfigError(f"bridge: the {engine} runs observed none of "
                          f"{', '.join(reference_mean)} in two or more runs")
    return EngineBridge(str(engine), offset, sd, len(runs), dict(base or {}), reference,
                        tuple(left), tuple(int(s) for s in seeds),
                        {k: np.array([np.asarray(r[k], float) for r in runs])
                         for k in offset})


def bridge_table(doc: Mapping[str, Any], where: str, folder: Path | None = None) -> dict:
    """The checked ``[bridge]`` table of a simulation configuration (see the module
    docstring); ``cache`` made absolute against ``folder``."""
    tab = dict(doc)
    for key, v in tab.items():
        if key not in BRIDGE_KEYS:
            raise ConfigError(f"{where} [bridge]: key {key!r}: unknown (expected "
                              f"{', '.join(BRIDGE_KEYS)})")
        typ = BRIDGE_KEYS[key]
        if not isinstance(v, typ) or isinstance(v, bool):
            raise ConfigError(f"{where} [bridge]: key {key!r}: expected {typ.__name__}; got {v!r}")
    if "engine" not in tab:
        raise ConfigError(f"{where} [bridge]: key 'engine' is required (the engine whose "
                          f"baseline the measurements are compared with)")
    engines = ("embedded", "liggghts", "lammps")
    if tab["engine"] not in engines:
        raise ConfigError(f"{where} [bridge]: key 'engine': expected one of "
                          f"{', '.join(engines)}; got {tab['engine']!r}")
    tab.setdefault("runs", 6)
    if tab["runs"] < 2:
        raise ConfigError(f"{where} [bridge]: key 'runs': need >= 2 runs to know the offset's "
                          f"uncertainty; got {tab['runs']}")
    tab.setdefault("seed", 0)
    if tab.get("probe_runs", 0) == 1 or not 0 <= tab.get("probe_runs", 0) <= tab["runs"]:
        raise ConfigError(f"{where} [bridge]: key 'probe_runs': expected 0 (no probes) or 2 to "
                          f"'runs' ({tab['runs']}: each probe run is paired with the base run "
                          f"of its seed); got {tab['probe_runs']}")
    if tab.get("probes", "top") not in PROBE_SETS:
        raise ConfigError(f"{where} [bridge]: key 'probes': expected one of "
                          f"{', '.join(map(repr, PROBE_SETS))} (the reference magnitudes "
                          f"probed); got {tab['probes']!r}")
    if "probes" in tab and not tab.get("probe_runs", 0):
        raise ConfigError(f"{where} [bridge]: key 'probes' needs 'probe_runs' (2 to "
                          f"{tab['runs']}): without probe runs nothing is probed")
    if "cache" in tab:
        c = Path(tab["cache"]).expanduser()
        tab["cache"] = str(c if c.is_absolute() or folder is None else folder / c)
    return tab


def engine_bridge(measurements: MeasurementSet, simulator, *, base: Mapping[str, float],
                  bridge: Mapping[str, Any], engine: Mapping[str, Any] | None = None,
                  cache=None, engine_simulator=None, effects: Sequence | None = None,
                  workers: int = 1, progress: bool = False, replay: bool = False) -> EngineBridge:
    """Run the user's engine at the base point (and each effect's probe) and bridge it to
    ``simulator``.

    Parameters
    ----------
    measurements : MeasurementSet
        The measurement file: its measured observables are the ones run and bridged.
    simulator : callable
        The diagnosing simulator. An
        :class:`~bedstruct.diagnose.emulator.EmulatedSimulator` answers with its
        emulator's prediction at ``base``; any other is run ``runs`` times there.
    base : mapping
        The base point (SI).
    bridge : mapping
        The ``[bridge]`` table (:func:`bridge_table`): ``engine``, ``runs``, ``seed``,
        ``probe_runs``, ``cache``.
    engine : mapping, optional
        The ``[engine]`` table of the diagnosing configuration (preset or workflow
        ``config``, ``overrides``, ``np``); the bridge runs use it with ``engine``
        replaced by the bridged one.
    cache : path, optional
        Folder keeping the bridge runs (overrides the table's ``cache``): a second
        diagnosis with the same configuration and code reads them back.
    engine_simulator : callable, optional
        The user's engine as a simulator, ``sim(base, effects, seed) -> Observations``
        (default: the ``[engine]`` table on the bridge's ``engine``, :func:`bridge_runs`).
    effects : sequence of Effect, optional
        The diagnosis' catalogue (default: all of it): with ``probe_runs`` in the table,
        each of them that the bridged engine realises is probed (:func:`effect_probes`).
    workers : int
        Local processes running the engine's runs (default 1).
    replay : bool
        Read the engine's runs from ``cache`` whatever code made them and run none (a run
        not kept there is an error): the bridge of a validation record, as recorded.

    Returns
    -------
    EngineBridge
    """
    measured = measurements.select(("calibrate", "validate"))
    seeds = bridge_seeds(bridge)
    if engine_simulator is None:
        engine_simulator = _engine_simulator(measured, bridge=bridge, engine=engine, cache=cache,
                                             workers=workers)
        engine_simulator.replay = bool(replay)
    elif replay:
        raise ConfigError("engine_bridge: `replay` reads the bridge's own cache; it cannot be "
                          "combined with an `engine_simulator`")
    runs = _run_all(engine_simulator, [(dict(base), {}, s) for s in seeds], progress,
                    f"bridge ({bridge['engine']})")
    names = measured.names
    emu = getattr(simulator, "emulator", None)
    if emu is not None:
        p = emu.predict(dict(base), {})
        mean, sd, noise = (emu.by_observable(p.mean), emu.by_observable(p.sd),
                           emu.by_observable(p.noise_sd))
        reference = "emulator"
    else:
        ref = _run_all(simulator, [(dict(base), {}, s) for s in seeds], progress,
                       "bridge (diagnosing simulator)")
        mean, sd, noise = {}, {}, {}
        for n in names:
            y = np.array([np.asarray(r[n], float) for r in ref])
            k = np.isfinite(y).sum(axis=0)
            mean[n] = np.nanmean(y, axis=0) if np.all(k > 0) else np.full(y.shape[1], np.nan)
            noise[n] = np.nanstd(y, axis=0, ddof=1) if np.all(k > 1) else np.full(y.shape[1], np.nan)
            sd[n] = noise[n] / np.sqrt(np.maximum(k, 1))
        reference = f"{getattr(simulator, 'name', 'diagnosing simulator')}, {len(seeds)} runs"
    want = {n: mean[n] for n in names if n in mean}
    out = bridge_offset(runs, want, sd, noise, engine=str(bridge["engine"]), base=base,
                        reference=reference, seeds=seeds)
    n_probe = int(bridge.get("probe_runs", 0))
    if n_probe:
        out = effect_probes(out, engine_simulator, simulator, effects=effects,
                            n_runs=n_probe, probes=str(bridge.get("probes", "top")),
                            progress=progress)
    return out


def _engine_simulator(design, *, bridge, engine, cache, workers: int = 1):
    """The ``[engine]`` table on the bridge's engine as a simulator (runs kept in ``cache``,
    batches run in ``workers`` processes)."""
    from .engine_simulator import diagnosis_simulator
    table = {k: v for k, v in dict(engine or {}).items() if k not in ("cache", "jobs")}
    table["engine"] = bridge["engine"]
    table["jobs"] = max(int(workers), 1)
    folder = cache if cache is not None else bridge.get("cache")
    if folder is not None:
        table["cache"] = str(folder)
    return diagnosis_simulator(design, table)


def _run_all(simulator, calls, progress, desc) -> list:
    """Every call of ``simulator``, in order; an engine simulator runs them ahead in its
    worker processes (``prefetch``)."""
    if hasattr(simulator, "prefetch"):
        simulator.prefetch(calls, progress=bool(progress))
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=len(calls), desc=desc, unit="run")
    out = []
    for base, effects, seed in calls:
        out.append(simulator(base, effects, int(seed)))
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    return out


def effect_probes(bridge: EngineBridge, engine_simulator, simulator, *,
                  effects: Sequence | None = None, n_runs: int = 4, probes: str = "top",
                  progress: bool = False) -> EngineBridge:
    """The bridge with each realisable effect's response difference :math:`\\Delta_e`.

    The user's engine is run at each effect's probe magnitude (its larger reference
    magnitude; with ``probes="reference"`` at its smaller one too) on the first ``n_runs``
    seeds of the bridge's base runs; each probe run is paired with the base run of its
    seed. The diagnosing simulator's response is the emulator's predicted difference (with
    its uncertainty at both points), or the mean paired difference of as many of its own
    runs.

    Parameters
    ----------
    bridge : EngineBridge
        From :func:`bridge_offset` (its :attr:`~EngineBridge.runs` and seeds are the
        engine's base runs).
    engine_simulator : callable
        The user's engine, ``sim(base, effects, seed) -> Observations``.
    simulator : callable
        The diagnosing simulator.
    effects : sequence of Effect, optional
        Catalogue (default: all); those the engine does not realise are not probed.
    n_runs : int
        Probe runs per effect and magnitude (2 to the bridge's base runs).
    probes : {"top", "reference"}
        The reference magnitudes probed: the larger, or both.
    progress : bool
        Progress bar over the probe runs.

    Returns
    -------
    EngineBridge
        With :attr:`~EngineBridge.effect_shift`, its standard deviation, the probes and,
        with ``probes="reference"``, :attr:`~EngineBridge.inner_probes`.

    Raises
    ------
    ConfigError
        Fewer than 2 probe runs, or more than the base runs they pair with; an unknown
        ``probes``.
    """
    from .catalogue import CATALOGUE
    from .engine_simulator import engine_realises
    n_runs = int(n_runs)
    if not 2 <= n_runs <= bridge.n_runs:
        raise ConfigError(f"bridge: probe_runs must lie in 2..{bridge.n_runs} (the base runs "
                          f"they pair with); got {n_runs}")
    if probes not in PROBE_SETS:
        raise ConfigError(f"bridge: probes must be one of {', '.join(map(repr, PROBE_SETS))}; "
                          f"got {probes!r}")
    effects = tuple(CATALOGUE if effects is None else effects)
    probed = [e for e in effects if engine_realises(e, bridge.engine)]
    unprobed = tuple(e.name for e in effects if e not in probed)
    seeds = list(bridge.seeds[:n_runs])
    base = dict(bridge.base)
    mags = {e.name: float(max(e.reference_magnitudes, key=abs)) for e in probed}
    inner = {e.name: tuple(sorted(float(a) for a in e.reference_magnitudes
                                  if abs(float(a)) < abs(mags[e.name]) and float(a) != 0.0))
             for e in probed} if probes == "reference" else {}
    points = [(e, a) for e in mags for a in inner.get(e, ()) + (mags[e],)]
    calls = [(base, {e: a}, s) for e, a in points for s in seeds]
    runs = _run_all(engine_simulator, calls, progress, f"bridge probes ({bridge.engine})")
    emu = getattr(simulator, "emulator", None)
    p0 = emu.predict(base, {}) if emu is not None else None
    ref0 = None if emu is not None else _run_all(simulator, [(base, {}, s) for s in seeds],
                                                 False, "")
    found = {}
    for k, (e, a) in enumerate(points):
        eng = runs[k * n_runs:(k + 1) * n_runs]
        if emu is not None:
            p = emu.predict(base, {e: a})
            d_ref = emu.by_observable(p.mean - p0.mean)
            v_ref = emu.by_observable(p.sd ** 2 + p0.sd ** 2)
        else:
            ref = _run_all(simulator, [(base, {e: a}, s) for s in seeds], False, "")
        shift, shift_sd = {}, {}
        for n in bridge.offset:
            y0 = np.asarray(bridge.runs[n], float)[:n_runs]
            dd = np.array([np.asarray(r[n], float) for r in eng]) - y0
            if emu is None:   # both codes' paired differences on the same seeds
                dd = dd - np.array([np.asarray(r[n], float) - np.asarray(r0[n], float)
                                    for r, r0 in zip(ref, ref0)])
                ref_mean, ref_var = 0.0, 0.0
            else:
                ref_mean, ref_var = np.asarray(d_ref[n], float), np.asarray(v_ref[n], float)
            m = np.isfinite(dd).sum(axis=0)
            # a component that fewer than two probe runs observed keeps the diagnosing response
            ok = m >= 2
            z = np.where(np.isfinite(dd), dd, 0.0)
            mean = z.sum(axis=0) / np.maximum(m, 1)
            var = ((z - mean) ** 2 * np.isfinite(dd)).sum(axis=0) / np.maximum(m - 1, 1)
            delta = mean - ref_mean
            sd = np.sqrt(var / np.maximum(m, 1) + ref_var)
            ok &= np.isfinite(delta) & np.isfinite(sd)
            shift[n] = np.where(ok, delta, 0.0)
            shift_sd[n] = np.where(ok, sd, 0.0)
        found[(e, a)] = (shift, shift_sd)
    return replace(bridge, probe_magnitudes=mags,
                   effect_shift={e: found[(e, a)][0] for e, a in mags.items()},
                   effect_shift_sd={e: found[(e, a)][1] for e, a in mags.items()},
                   probe_runs=n_runs, unprobed=unprobed,
                   inner_probes={e: tuple((a, *found[(e, a)]) for a in inner[e])
                                 for e in inner if inner[e]})


def bridge_seeds(bridge: Mapping[str, Any]) -> list[int]:
    """The seeds of a ``[bridge]`` table's runs (``runs`` of them, from its ``seed``).

    Examples
    --------
    >>> from bedstruct.diagnose.bridge import bridge_seeds
    >>> bridge_seeds({"engine": "liggghts", "runs": 3, "seed": 10})
    [500010, 500011, 500012]
    """
    return [BRIDGE_SEED_STRIDE + int(bridge.get("seed", 0)) + i
            for i in range(int(bridge.get("runs", 6)))]


def bridge_runs(design: MeasurementSet, *, base: Mapping[str, float], bridge: Mapping[str, Any],
                engine: Mapping[str, Any] | None = None, cache=None, seeds=None,
                progress: bool = False) -> tuple[list[Observations], list[int]]:
    """Runs of the bridged engine at the base point: ``(observations, seeds)``.

    The ``[engine]`` table with ``engine`` replaced by the bridge's; the runs observe
    ``design``'s observables and are kept in ``cache`` (else the table's ``cache``), so
    that processes running some of ``seeds`` each fill the same folder.
    """
    sim = _engine_simulator(design, bridge=bridge, engine=engine, cache=cache)
    if seeds is None:
        seeds = bridge_seeds(bridge)
    runs = _run_all(sim, [(dict(base), {}, s) for s in seeds], progress,
                    f"bridge ({bridge['engine']})")
    return runs, [int(s) for s in seeds]
