"""Simulation configuration of a diagnosis (``bedstruct diagnose --sim CONFIG``).

A small TOML file names the simulator, the calibrated base parameters, the
parameters recalibration may change, the catalogue and the statistical levels::

    [simulator]
    kind = "surrogate"        # "engine" once bedstruct.workflows provides the hook
    replicates = 4
    top_up = 4                # more seeds where identifiability is marginal (default 0)
    seed = 0

    [base]
    cohesion_energy_density = 3.6e7
    friction = 0.4
    rolling_friction = 0.05
    restitution = 0.1

    [recalibrate]
    parameters = ["cohesion_energy_density"]
    bounds = { cohesion_energy_density = [0.0, 1e9] }   # optional: narrower than physical

    [catalogue]
    exclude = []

    [bridge]                  # optional: measurements compared with another engine's baseline
    engine = "liggghts"       # (bedstruct.diagnose.bridge)
    runs = 6

    [diagnosis]
    alpha = 0.05              # level of the 'is there a gap' tests
    select_alpha = 0.01       # family-wise level of the effect selection
    gof_alpha = 0.01          # goodness of fit below which the answer is 'unexplained'
    heldout_alpha = 0.1       # level of the rerun's check on the held-out observables
    max_effects = 2
    refine = 2                # Gauss-Newton rounds simulating the leading effects at their fits
    confirm_rounds = 2        # refits after a rerun that contradicts the fit
    partial_shrink = 0.5      # held-out shrink (lower 90 % bound) above which an effect whose
                              # rerun misses only held-out data is named as partial (1: never)

``kind = "engine"`` calls
``bedstruct.diagnose.engine_simulator.diagnosis_simulator(design, config) -> simulator``
(the ``[engine]`` table is passed through as ``config``).

.. versionadded:: 0.1
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from .bridge import bridge_table
from .catalogue import Effect, catalogue
from .measurements import MeasurementSet
from .parameters import parameter_bounds, parameter_value_error
from .surrogate import BASE_PARAMETERS, SurrogateSimulator

__all__ = ["SimConfig", "load_sim_config", "make_simulator"]



@dataclass(frozen=True)
class SimConfig:
    """Parsed simulation configuration (see the module docstring for the file)."""

    kind: str = "surrogate"
    base: dict = field(default_factory=lambda: dict(BASE_PARAMETERS))
    nuisance: tuple[str, ...] = ("cohesion_energy_density",)
    bounds: dict = field(default_factory=dict)
    effects: tuple[Effect, ...] = field(default_factory=catalogue)
    replicates: int = 4
    top_up: int = 0
    seed: int = 0
    alpha: float = 0.05
    select_alpha: float = 0.01
    gof_alpha: float = 0.01
    heldout_alpha: float = 0.1
    max_effects: int = 2
    refine: int = 2
    confirm_rounds: int = 2
    partial_shrink: float = 0.5
    noise: float = 1.0
    engine: dict = field(default_factory=dict)
    library: dict = field(default_factory=dict)
    bridge: dict = field(default_factory=dict)
    path: str | None = None

    def diagnose_settings(self, seed: int | None = None) -> dict[str, Any]:
        """Keyword arguments of :func:`~bedstruct.diagnose.diagnose` this configuration sets
        (``seed`` replaces the configured replicate seed)."""
        if seed is not None and (isinstance(seed, bool) or int(seed) != seed or seed < 0):
            raise ConfigError(f"seed (the replicate seed, --seed): expected an integer >= 0; "
                              f"got {seed!r}")
        return dict(replicates=self.replicates, top_up=self.top_up,
                    seed=self.seed if seed is None else int(seed), alpha=self.alpha,
                    select_alpha=self.select_alpha, gof_alpha=self.gof_alpha,
                    heldout_alpha=self.heldout_alpha,
                    max_effects=self.max_effects, refine=self.refine,
                    confirm_rounds=self.confirm_rounds, partial_shrink=self.partial_shrink,
                    bounds=self.bounds)

    def library_settings(self) -> dict[str, Any]:
        """Keyword arguments of the run library's design
        (:func:`~bedstruct.diagnose.amortised.library_emulator`) from ``[library]``: each
        recalibrated parameter varied by ``vary`` (relative half-width, default 0.25)."""
        lib = dict(self.library)
        vary = float(lib.pop("vary", 0.25))
        if "replicates" in lib:
            lib["library_replicates"] = lib.pop("replicates")
        return dict(lib, effects=self.effects, nuisance=self.nuisance,
                    vary={n: vary for n in self.nuisance})

    def as_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "base": dict(self.base), "recalibrate": list(self.nuisance),
                "bounds": parameter_bounds(self.nuisance, self.bounds),
                "effects": [e.name for e in self.effects], "replicates": self.replicates,
                "top_up": self.top_up, "seed": self.seed, "alpha": self.alpha, "select_alpha": self.select_alpha,
                "gof_alpha": self.gof_alpha, "heldout_alpha": self.heldout_alpha,
                "max_effects": self.max_effects, "refine": self.refine,
                "confirm_rounds": self.confirm_rounds, "partial_shrink": self.partial_shrink,
                "library": dict(self.library),
                "bridge": dict(self.bridge), "path": self.path}


#: Keys of the ``[library]`` table: the size of a run library's design
#: (:func:`bedstruct.diagnose.run_design.design_spec`) and the varied base parameters'
#: relative half-width.
LIBRARY_KEYS = {"n_base": int, "n_per_effect": int, "replicates": int, "vary": float}


def _engine_table(doc, p) -> dict:
    eng = doc.get("engine", {})
    if not isinstance(eng, dict):
        raise ConfigError(f"{p}: key 'engine': expected a table; got {eng!r}")
    eng = dict(eng)
    if "config" in eng:   # the user's workflow configuration, relative to this file
        if not isinstance(eng["config"], str) or not eng["config"]:
            raise ConfigError(f"{p} [engine]: key 'config': expected the path of a workflow "
                              f"configuration (TOML); got {eng['config']!r}")
        cfg_path = Path(eng["config"]).expanduser()
        if not cfg_path.is_absolute():
            cfg_path = p.parent / cfg_path
        if not cfg_path.is_file():
            raise ConfigError(f"{p} [engine]: key 'config': workflow configuration not found: "
                              f"{cfg_path}")
        eng["config"] = str(cfg_path)
    return eng


def _model_base(engine: dict, p) -> dict:
    """The base point of the user's own workflow configuration (its contact model)."""
    from ..workflows.config import load_config
    try:
        c = load_config(engine["config"], preset=engine.get("preset"),
                        overrides=[str(s) for s in engine.get("overrides", [])])["contact"]
    except ConfigError as exc:
        raise ConfigError(f"{p} [engine]: key 'config': {exc}") from None
    return {"cohesion_energy_density": float(c["cohesion"]), "friction": float(c["friction"]),
            "rolling_friction": float(c["rolling_friction"]),
            "restitution": float(c["restitution"])}


def _library_table(doc, p) -> dict:
    lib = doc.get("library", {})
    if not isinstance(lib, dict):
        raise ConfigError(f"{p}: key 'library': expected a table; got {lib!r}")
    out = {}
    for key, v in lib.items():
        if key not in LIBRARY_KEYS:
            raise ConfigError(f"{p} [library]: key {key!r}: unknown (expected "
                              f"{', '.join(LIBRARY_KEYS)})")
        out[key] = _get(lib, key, LIBRARY_KEYS[key], f"{p} [library]", None)
        if not out[key] > 0:
            raise ConfigError(f"{p} [library]: key {key!r}: expected a positive number; "
                              f"got {out[key]!r}")
    return out


def _bridge(doc, p, kind) -> dict:
    tab = doc.get("bridge")
    if tab is None:
        return {}
    if not isinstance(tab, dict):
        raise ConfigError(f"{p}: key 'bridge': expected a table; got {tab!r}")
    if kind != "engine":
        raise ConfigError(f"{p} [bridge]: needs [simulator] kind = \"engine\" (the bridge runs "
                          f"the engine's workflow on another engine)")
    return bridge_table(tab, str(p), p.parent)


def _get(table, key, typ, where, default):
    if key not in table:
        return default
    v = table[key]
    if typ is float and isinstance(v, int) and not isinstance(v, bool):
        v = float(v)
    if not isinstance(v, typ) or isinstance(v, bool) and typ is not bool:
        raise ConfigError(f"{where}: key {key!r}: expected {typ.__name__}; got {v!r}")
    return v


def load_sim_config(path) -> SimConfig:
    """Read a simulation configuration; ``"surrogate"`` gives the default surrogate config.

    Raises
    ------
    ConfigError
        Naming the key when the file is invalid.

    Examples
    --------
    >>> cfg = load_sim_config("surrogate")
    >>> cfg.kind, cfg.nuisance, len(cfg.effects)
    ('surrogate', ('cohesion_energy_density',), 6)
    """
    if str(path) == "surrogate":
        return SimConfig(path="surrogate")
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"simulation config not found: {p}")
    try:
        doc = tomllib.loads(p.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: not valid TOML ({exc})") from None
    unknown = set(doc) - {"simulator", "base", "recalibrate", "catalogue", "diagnosis", "engine",
                          "library", "bridge"}
    if unknown:
        raise ConfigError(f"{p}: key {sorted(unknown)[0]!r}: unknown table")
    sim = doc.get("simulator", {})
    kind = _get(sim, "kind", str, f"{p} [simulator]", "surrogate")
    if kind not in ("surrogate", "engine"):
        raise ConfigError(f"{p} [simulator]: key 'kind': expected 'surrogate' or 'engine'; got {kind!r}")
    engine = _engine_table(doc, p)
    base = dict(BASE_PARAMETERS) if "config" not in engine else _model_base(engine, p)
    given = doc.get("base", {})
    if not isinstance(given, dict):
        raise ConfigError(f"{p}: key 'base': expected a table of parameter = value; got {given!r}")
    for k, v in given.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ConfigError(f"{p} [base]: key {k!r}: expected a number; got {v!r}")
        base[k] = float(v)
    for k, v in base.items():   # every base value physical, recalibrated or not
        why = parameter_value_error(k, v)
        if why and k in given:
            raise ConfigError(f"{p} [base]: key {k!r}: {v:g} is outside its bounds: {why}")
        if why:
            raise ConfigError(f"{p} [engine]: key 'config': its contact model gives {k} = {v:g}, "
                              f"outside its bounds: {why}")
    if kind == "surrogate":
        unknown = set(base) - set(BASE_PARAMETERS)
        if unknown:
            raise ConfigError(f"{p} [base]: key {sorted(unknown)[0]!r}: unknown to the surrogate "
                              f"(knows {sorted(BASE_PARAMETERS)})")
    rec = doc.get("recalibrate", {})
    nuisance = tuple(_get(rec, "parameters", list, f"{p} [recalibrate]", ["cohesion_energy_density"]))
    for n in nuisance:
        if n not in base:
            raise ConfigError(f"{p} [recalibrate]: key 'parameters': {n!r} is not a base parameter")
    bounds = rec.get("bounds", {})
    if not isinstance(bounds, dict):
        raise ConfigError(f"{p} [recalibrate]: key 'bounds': expected a table of "
                          f"parameter = [lower, upper]; got {bounds!r}")
    unknown = set(rec) - {"parameters", "bounds"}
    if unknown:
        raise ConfigError(f"{p} [recalibrate]: key {sorted(unknown)[0]!r}: unknown")
    try:
        limits = parameter_bounds(nuisance, bounds)
    except ConfigError as exc:
        raise ConfigError(f"{p} {exc}") from None
    for n, (lo, hi) in limits.items():
        if not lo <= base[n] <= hi:
            raise ConfigError(f"{p} [base]: key {n!r}: {base[n]:g} is outside its bounds "
                              f"[{lo:g}, {hi:g}]")
    cat = doc.get("catalogue", {})
    try:
        names = cat.get("effects")
        effects = catalogue(names, exclude=cat.get("exclude", []))
    except ConfigError as exc:
        raise ConfigError(f"{p} [catalogue]: {exc}") from None
    if not effects:
        raise ConfigError(f"{p} [catalogue]: no effect is left to diagnose with (effects = "
                          f"{list(names) if names is not None else 'all'}, exclude = "
                          f"{list(cat.get('exclude', []))}); expected at least one effect")
    dg = doc.get("diagnosis", {})
    cfg = SimConfig(kind=kind, base=base, nuisance=nuisance, bounds=dict(bounds), effects=effects,
                    replicates=_get(sim, "replicates", int, f"{p} [simulator]", 4),
                    top_up=_get(sim, "top_up", int, f"{p} [simulator]", 0),
                    seed=_get(sim, "seed", int, f"{p} [simulator]", 0),
                    noise=_get(sim, "noise", float, f"{p} [simulator]", 1.0),
                    alpha=_get(dg, "alpha", float, f"{p} [diagnosis]", 0.05),
                    select_alpha=_get(dg, "select_alpha", float, f"{p} [diagnosis]", 0.01),
                    gof_alpha=_get(dg, "gof_alpha", float, f"{p} [diagnosis]", 0.01),
                    heldout_alpha=_get(dg, "heldout_alpha", float, f"{p} [diagnosis]", 0.1),
                    max_effects=_get(dg, "max_effects", int, f"{p} [diagnosis]", 2),
                    refine=_get(dg, "refine", int, f"{p} [diagnosis]", 2),
                    confirm_rounds=_get(dg, "confirm_rounds", int, f"{p} [diagnosis]", 2),
                    partial_shrink=_get(dg, "partial_shrink", float, f"{p} [diagnosis]", 0.5),
                    engine=engine, library=_library_table(doc, p),
                    bridge=_bridge(doc, p, kind), path=str(p))
    if cfg.replicates < 2:
        raise ConfigError(f"{p} [simulator]: key 'replicates': need >= 2; got {cfg.replicates}")
    if cfg.seed < 0:
        raise ConfigError(f"{p} [simulator]: key 'seed': expected an integer >= 0; got {cfg.seed}")
    if cfg.top_up < 0:
        raise ConfigError(f"{p} [simulator]: key 'top_up': expected an integer >= 0; "
                          f"got {cfg.top_up}")
    for key in ("alpha", "select_alpha", "gof_alpha", "heldout_alpha"):
        if not 0 < getattr(cfg, key) < 1:
            raise ConfigError(f"{p} [diagnosis]: key {key!r} must lie in (0, 1); got {getattr(cfg, key)}")
    for key in ("refine", "confirm_rounds"):
        if getattr(cfg, key) < 0:
            raise ConfigError(f"{p} [diagnosis]: key {key!r}: expected an integer >= 0; "
                              f"got {getattr(cfg, key)}")
    if not 0 <= cfg.partial_shrink <= 1:
        raise ConfigError(f"{p} [diagnosis]: key 'partial_shrink' must lie in [0, 1]; "
                          f"got {cfg.partial_shrink}")
    unknown = set(dg) - {"alpha", "select_alpha", "gof_alpha", "heldout_alpha", "max_effects",
                         "refine", "confirm_rounds", "partial_shrink"}
    if unknown:
        raise ConfigError(f"{p} [diagnosis]: key {sorted(unknown)[0]!r}: unknown")
    unknown = set(sim) - {"kind", "replicates", "top_up", "seed", "noise"}
    if unknown:
        raise ConfigError(f"{p} [simulator]: key {sorted(unknown)[0]!r}: unknown")
    if cfg.max_effects not in (1, 2):
        raise ConfigError(f"{p} [diagnosis]: key 'max_effects': expected 1 or 2; got {cfg.max_effects}")
    return cfg


def make_simulator(config: SimConfig, design: MeasurementSet):
    """The simulator callable for a configuration and a design.

    ``kind = "surrogate"`` gives :class:`SurrogateSimulator`; ``kind = "engine"``
    calls :func:`bedstruct.diagnose.engine_simulator.diagnosis_simulator` with the
    ``[engine]`` table.
    """
    if config.kind == "surrogate":
        return SurrogateSimulator(design, noise=config.noise)
    # the engine simulator loads the DEM engine (numba): only when asked for
    from .engine_simulator import diagnosis_simulator
    sim = diagnosis_simulator(design, dict(config.engine))
    refused = [(e.name, why) for e in config.effects
               if (why := _refusal(sim, e, config.base))]
    if refused:
        where = f"{config.path} [catalogue]" if config.path else "[catalogue]"
        names = ", ".join(repr(n) for n, _ in refused)
        why = "; ".join(f"{n}: {r}" for n, r in refused)
        raise ConfigError(f"{where}: the {sim.engine} engine cannot realise {names} ({why}). "
                          f"Leave them out (exclude = [{names}]) or diagnose on the embedded "
                          f"engine")
    return sim


def _refusal(sim, effect, base) -> str:
    """Why the engine of ``sim`` cannot realise ``effect`` at the top of its prior in the
    run configuration of ``sim`` (empty when it can)."""
    from .engine_simulator import engine_refusal
    if sim.engine == "embedded" or not effect.realisations[sim.engine].realised:
        return engine_refusal(effect, sim.engine)   # no run configuration needed
    return engine_refusal(effect, sim.engine,
                          sim.run_config(base, {effect.name: effect.prior[1]}, 0))
