"""Measurements and the observation containers (the files are read in :mod:`.measurement_io`).

A measurement file lists *observables*: each has a kind, a value (scalar or one
value per component), an uncertainty (or replicates), the conditions it was taken
at (speed, layer, region, time window, ...) and a role (``calibrate`` or
``validate``). The same structure, without values, is the *design* a simulator is
asked to reproduce. The format is documented in ``docs/diagnose.md``.

Canonical units inside: angles in degrees, lengths in metres, speeds in m/s,
times in seconds, fractions dimensionless. Every conversion made at load time is
recorded in :attr:`Measurement.conversions`.

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Iterable, Mapping

import numpy as np

from ..errors import ConfigError

__all__ = ["KINDS", "ROLES", "PLAUSIBLE", "PLAUSIBLE_CONDITIONS", "PLAUSIBLE_SETUP", "KIND_CONDITIONS",
           "normalise_region", "Conditions", "Setup",
           "Measurement", "MeasurementSet", "Observations"]

#: Observable kinds and their canonical unit (the built-in ones, and those added by
#: :func:`bedstruct.diagnose.register_observable`; how each is computed:
#: :func:`bedstruct.diagnose.observable_kinds`).
KINDS: dict[str, str] = {
    "static_angle": "deg", "dynamic_angle_series": "deg", "bed_height": "m",
    "packing_fraction": "1", "psd": "m", "roughness": "m", "coordination": "1",
    "segregation_index": "1", "tool_force_ratio": "1",
}
#: Roles of an observable; ``candidate`` marks a design-only (not yet measured) one.
ROLES = ("calibrate", "validate", "candidate")

_UNIT = {  # unit -> (dimension, factor to canonical)
    "deg": ("angle", 1.0), "degree": ("angle", 1.0), "degrees": ("angle", 1.0),
    "rad": ("angle", 180.0 / math.pi),
    "m": ("length", 1.0), "mm": ("length", 1e-3), "um": ("length", 1e-6),
    "µm": ("length", 1e-6), "μm": ("length", 1e-6), "micron": ("length", 1e-6),
    "nm": ("length", 1e-9),
    "1": ("fraction", 1.0), "": ("fraction", 1.0), "%": ("fraction", 0.01),
}
_DIM = {"deg": "angle", "m": "length", "1": "fraction"}
_KNOWN_CONDITIONS = {"speed", "layer", "region", "time_window", "stage", "relative_humidity",
                     "rest_time", "box_width"}

_SPREAD = ("speed", "layer", "relative_humidity")
#: The conditions each built-in kind may be taken at (what the simulators vary it with): a
#: repose test's pile has no speed, layer or region; a spread layer no box or rest time.
#: A kind of your own (:func:`~bedstruct.diagnose.register_observable`) may take any.
KIND_CONDITIONS: dict[str, tuple[str, ...]] = {
    "static_angle": ("box_width", "rest_time", "relative_humidity"),
    "dynamic_angle_series": _SPREAD + ("time_window", "rest_time"),
    "bed_height": _SPREAD,
    "roughness": _SPREAD,
    "tool_force_ratio": _SPREAD,
    "packing_fraction": _SPREAD + ("region",),
    "coordination": _SPREAD + ("region",),
    "segregation_index": _SPREAD + ("region",),
    "psd": ("stage",) + _SPREAD + ("region",),
}

#: Plausible values per kind, canonical units: ``lo < value < hi`` (checked when a
#: measurement file is read; a value outside is almost always a unit mistake, e.g. sizes
#: in mm labelled ``um``). ``tool_force_ratio`` (a signed ratio) is not range-checked;
#: ``segregation_index``, a coefficient of variation, is 0 for a mixed bed and never negative.
PLAUSIBLE: dict[str, tuple[float, float]] = {
    "static_angle": (5.0, 90.0), "dynamic_angle_series": (5.0, 90.0),   # deg
    "packing_fraction": (0.05, 0.9), "coordination": (0.1, 20.0),
    "segregation_index": (-1e-12, 2.0),
    "bed_height": (1e-6, 0.1), "psd": (1e-6, 1e-2), "roughness": (1e-7, 1e-3),   # m
}

#: Kinds whose values are counts, not fractions: the unit ``%`` is refused.
NOT_PERCENT = ("coordination",)

#: Plausible observable conditions, SI: ``lo <= value <= hi`` (a value outside is almost
#: always a unit mistake: a speed in cm/s, a box width in mm written as metres).
PLAUSIBLE_CONDITIONS: dict[str, tuple[float, float]] = {
    "speed": (1e-4, 2.0),          # m/s: 0.1 mm/s to 2 m/s
    "box_width": (1e-4, 1.0),      # m: 0.1 mm to 1 m
    "rest_time": (0.0, 1e7),       # s: up to about four months
}

#: Plausible lengths of a measurement set-up (``[conditions]``), SI, as
#: :data:`PLAUSIBLE_CONDITIONS`: powder layers of 1 um to 10 mm, platforms of 1 mm to 10 m.
PLAUSIBLE_SETUP: dict[str, tuple[float, float]] = {
    "layer_thickness": (1e-6, 1e-2),
    "platform_length": (1e-3, 10.0),
    "platform_width": (1e-4, 10.0),
    "wall_distance": (1e-4, 10.0),
}

#: Bed regions (``conditions.region``): accepted spellings (case-insensitive) -> the one kept.
_REGION_SPELLINGS = {"start": "start", "center": "center", "centre": "center", "end": "end"}


def normalise_region(region) -> str:
    """The canonical spelling of a bed region: ``"start"``, ``"center"`` or ``"end"``.

    Case-insensitive; ``"centre"`` is read as ``"center"``. The measurement file
    reader, the surrogate and the engine's observation all use it, so an unknown
    region is an error everywhere instead of silently the centre.

    Raises
    ------
    ConfigError
        If ``region`` is not one of those.

    Examples
    --------
    >>> normalise_region("Centre")
    'center'
    """
    key = region.strip().lower() if isinstance(region, str) else None
    if key not in _REGION_SPELLINGS:
        raise ConfigError(f"region {region!r}: expected one of 'start', 'center' (or 'centre'), "
                          f"'end'")
    return _REGION_SPELLINGS[key]


@dataclass(frozen=True)
class Conditions:
    """Conditions an observable was taken at (all optional).

    Parameters
    ----------
    speed : float or None
        Rake/stage speed, m/s.
    layer : int or None
        Layer number (1-based).
    region : str or None
        Region of the bed: ``"start"``, ``"center"`` or ``"end"`` (see
        :func:`normalise_region`; the file reader normalises the spelling).
    time_window : tuple of float or None
        ``(t0, t1)`` as fractions of the stroke (0 = blade starts, 1 = ends).
    extra : tuple of (str, value)
        Further named conditions: ``stage`` (``"before"``/``"after"`` spreading),
        ``relative_humidity`` (dimensionless), ``rest_time`` (s), ``box_width`` (m).

    Examples
    --------
    >>> Conditions(speed=0.0254, layer=3, time_window=(0.0, 0.1)).label()
    'v=2.54 cm/s, layer 3, t=0-10% of stroke'
    """

    speed: float | None = None
    layer: int | None = None
    region: str | None = None
    time_window: tuple[float, float] | None = None
    extra: tuple[tuple[str, Any], ...] = ()

    def get(self, key: str, default=None):
        """Value of a condition by name (``extra`` included)."""
        if key in ("speed", "layer", "region", "time_window"):
            v = getattr(self, key)
            return default if v is None else v
        return dict(self.extra).get(key, default)

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for k in ("speed", "layer", "region"):
            if getattr(self, k) is not None:
                out[k] = getattr(self, k)
        if self.time_window is not None:
            out["time_window"] = list(self.time_window)
        out.update(dict(self.extra))
        return out

    def label(self) -> str:
        parts = []
        if self.speed is not None:
            parts.append(f"v={self.speed * 100:.3g} cm/s")
        if self.layer is not None:
            parts.append(f"layer {self.layer}")
        if self.region is not None:
            parts.append(f"{self.region} region")
        if self.time_window is not None:
            t0, t1 = self.time_window
            parts.append(f"t={t0 * 100:.3g}-{t1 * 100:.3g}% of stroke")
        for k, v in self.extra:
            parts.append(f"{k}={v}")
        return ", ".join(parts) if parts else "-"


@dataclass(frozen=True)
class Setup:
    """The experiment's set-up that a simulator must reproduce (a file's ``[conditions]``).

    Every field is optional (``None``: the simulator's own choice); values are SI,
    converted from the file's units once, when it is read.

    Parameters
    ----------
    psd : (5,) tuple of float or None, m
        ``(d10, d50, d90, d_min, d_max)``: volume-weighted percentiles of the powder
        and the smallest and largest diameter.
    psd_source : str
        Where ``psd`` came from (``"percentiles"`` or the size-distribution file).
    psd_table : (diameters, fractions) tuple of tuples of float or None
        From a size-distribution file, the whole distribution: the cumulative volume
        fraction undersize (0 to 1) at the size classes' edges (m), midway between the
        file's diameters and half a class beyond the first and last.
    layer_thickness : tuple of float or None, m
        Platform lowering before each layer, one per layer.
    blade_speed : float or None, m/s
        Speed of the recoater (observables without their own ``speed``).
    platform_length, platform_width : float or None, m
        Build platform along and across the stroke.
    side_walls : bool or None
        Whether side walls bound the powder across the stroke.
    wall_distance : float or None, m
        Distance between the side walls.
    path : str or None
        The file the set-up was read from (named in a simulator's refusal).
    conversions : tuple of str
        Unit conversions made when the file was read.

    Examples
    --------
    >>> s = Setup(layer_thickness=(100e-6,) * 3, blade_speed=0.05)
    >>> s.n_layers, s.is_empty
    (3, False)
    """

    psd: tuple[float, float, float, float, float] | None = None
    psd_source: str = ""
    psd_table: tuple[tuple[float, ...], tuple[float, ...]] | None = None
    layer_thickness: tuple[float, ...] | None = None
    blade_speed: float | None = None
    platform_length: float | None = None
    platform_width: float | None = None
    side_walls: bool | None = None
    wall_distance: float | None = None
    path: str | None = None
    conversions: tuple[str, ...] = ()

    #: The set-up's keys (as in a file's ``[conditions]``), in order.
    KEYS = ("psd", "layers", "layer_thickness", "blade_speed", "platform_length",
            "platform_width", "side_walls", "wall_distance")

    @property
    def n_layers(self) -> int | None:
        """Number of layers (``len(layer_thickness)``)."""
        return None if self.layer_thickness is None else len(self.layer_thickness)

    @property
    def is_empty(self) -> bool:
        """No condition given."""
        return all(v is None for v in (self.psd, self.layer_thickness, self.blade_speed,
                                       self.platform_length, self.platform_width,
                                       self.side_walls, self.wall_distance))

    def given(self) -> tuple[str, ...]:
        """The file keys of the conditions given."""
        out = []
        for k in self.KEYS:
            v = self.n_layers if k == "layers" else getattr(self, k)
            if v is not None:
                out.append(k)
        return tuple(out)

    def where(self, key: str) -> str:
        """``"<file>: key 'conditions.<key>'"``, for messages."""
        return f"{self.path or 'measurement set'}: key 'conditions.{key}'"


@dataclass(frozen=True)
class Measurement:
    """One observable: values per component, uncertainties, conditions and role.

    Parameters
    ----------
    name : str
        Unique name in its set.
    kind : str
        One of :data:`KINDS`.
    values : (n,) ndarray of float
        Values in the kind's canonical unit (NaN for a design-only observable).
    uncertainty : (n,) ndarray of float
        One standard deviation per component, same unit; positive.
    labels : tuple of str
        Component labels (``"value"``, ``"t=0-0.1"``, ``"d10"``, ``"layer 2"``...).
    conditions : Conditions
        Common conditions of all components.
    role : str
        ``"calibrate"``, ``"validate"`` or ``"candidate"``.
    windows : (n, 2) ndarray or None
        Time windows (stroke fractions) of a ``dynamic_angle_series``.
    percentiles : (n,) ndarray or None
        Volume percentiles of a ``psd`` (e.g. 10, 50, 90).
    replicates : (r, n) ndarray or None
        Replicate readings when they were given.
    note, provenance : str
        Free text; ``provenance`` says how the value was obtained
        (``"measured"``, ``"read from a qualitative statement"`` ...).
    conversions : tuple of str
        What was done to the file's numbers at load time: unit conversions, and an
        uncertainty taken from replicates at its upper confidence bound.
    trials : int or None
        Repeated trials the values summarise, when the file states them.
    not_measured : (n,) ndarray of int or None
        Per component, the trials that could not give a reading (a heap that stood as a
        block after rest, no heap left to fit): a heap that does not flow is an outcome
        of the test, not a gap in the file. ``None`` when ``trials`` is not stated.
    """

    name: str
    kind: str
    values: np.ndarray
    uncertainty: np.ndarray
    labels: tuple[str, ...]
    conditions: Conditions = field(default_factory=Conditions)
    role: str = "calibrate"
    windows: np.ndarray | None = None
    percentiles: np.ndarray | None = None
    replicates: np.ndarray | None = None
    note: str = ""
    provenance: str = "measured"
    conversions: tuple[str, ...] = ()
    trials: int | None = None
    not_measured: np.ndarray | None = None

    @property
    def measured_in_no_trial(self) -> bool:
        """Whether every stated trial failed to give a reading (no value at all)."""
        return self.trials is not None and self.not_measured is not None and \
            bool(np.all(self.not_measured >= self.trials))

    @property
    def unit(self) -> str:
        """Canonical unit of the values."""
        return KINDS[self.kind]

    @property
    def n_components(self) -> int:
        return len(self.values)


@dataclass(frozen=True)
class Observations:
    """Values of named observables, as produced by an observation operator.

    Simulators return one :class:`Observations` per run; real data give one via
    :meth:`MeasurementSet.observations`. Both carry the same names and component
    order, so they can be compared component by component.

    Parameters
    ----------
    values : mapping of str to (n,) ndarray
        Observable name to component values (canonical units).
    source : str
        ``"surrogate"``, ``"engine"``, ``"measured"`` ...

    Examples
    --------
    >>> obs = Observations({"a": [1.0, 2.0], "b": [3.0]})
    >>> obs.vector(["b", "a"])
    array([3., 1., 2.])
    """

    values: Mapping[str, np.ndarray]
    source: str = ""

    def __post_init__(self):
        vals = {str(k): np.atleast_1d(np.asarray(v, dtype=float)).ravel() for k, v in self.values.items()}
        object.__setattr__(self, "values", vals)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.values[name]

    def __contains__(self, name) -> bool:
        return name in self.values

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.values)

    def vector(self, names: Iterable[str]) -> np.ndarray:
        """Concatenate the components of ``names`` in that order."""
        parts = []
        for n in names:
            if n not in self.values:
                raise KeyError(f"observable {n!r} missing from {self.source or 'observations'}; "
                               f"has {sorted(self.values)}")
            parts.append(self.values[n])
        return np.concatenate(parts) if parts else np.zeros(0)


@dataclass(frozen=True)
class MeasurementSet:
    """An ordered set of :class:`Measurement` with metadata (one measurement file).

    Examples
    --------
    >>> from bedstruct.diagnose import measurement_from_dict
    >>> m = measurement_from_dict({"name": "aor", "kind": "static_angle", "value": 33.0,
    ...                            "uncertainty": 1.0, "unit": "deg"})
    >>> ms = MeasurementSet((m,), title="demo")
    >>> ms.n_components, ms.roles().tolist()
    (1, ['calibrate'])

    ``setup`` holds the file's ``[conditions]``: the experiment's set-up (:class:`Setup`).
    ``unmeasured`` holds the observables that were tried but gave a reading in none of
    their trials (``trials`` and ``not_measured`` equal in the file); they have no values
    and take no part in the fit, and the diagnosis reports them as data.
    """

    measurements: tuple[Measurement, ...]
    title: str = ""
    source: str = ""
    path: str | None = None
    notes: str = ""
    unmeasured: tuple[Measurement, ...] = ()
    setup: Setup = field(default_factory=Setup)

    def __post_init__(self):
        seen = set()
        for m in self.measurements + tuple(self.unmeasured):
            if m.name in seen:
                raise ConfigError(f"observable name {m.name!r} is used twice")
            seen.add(m.name)

    def __len__(self) -> int:
        return len(self.measurements)

    def __iter__(self):
        return iter(self.measurements)

    def __getitem__(self, name: str) -> Measurement:
        for m in self.measurements:
            if m.name == name:
                return m
        raise KeyError(name)

    def __contains__(self, name) -> bool:
        return any(m.name == name for m in self.measurements)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.measurements)

    @property
    def n_components(self) -> int:
        return sum(m.n_components for m in self.measurements)

    def _per_component(self, f) -> np.ndarray:
        out = []
        for m in self.measurements:
            out.extend([f(m, i) for i in range(m.n_components)])
        return np.asarray(out, dtype=object) if out else np.zeros(0, dtype=object)

    def values(self) -> np.ndarray:
        """All component values, concatenated in file order."""
        return np.concatenate([m.values for m in self.measurements]) if self.measurements else np.zeros(0)

    def uncertainty(self) -> np.ndarray:
        """All component standard deviations, concatenated in file order."""
        return (np.concatenate([m.uncertainty for m in self.measurements])
                if self.measurements else np.zeros(0))

    def roles(self) -> np.ndarray:
        return self._per_component(lambda m, i: m.role).astype(str)

    def component_names(self) -> np.ndarray:
        return self._per_component(lambda m, i: m.name).astype(str)

    def component_labels(self) -> np.ndarray:
        return self._per_component(lambda m, i: m.labels[i]).astype(str)

    def kinds(self) -> np.ndarray:
        return self._per_component(lambda m, i: m.kind).astype(str)

    def observations(self) -> Observations:
        """The measured values as :class:`Observations` (source ``"measured"``)."""
        return Observations({m.name: m.values for m in self.measurements}, source="measured")

    def select(self, roles: Iterable[str]) -> "MeasurementSet":
        """The observables whose role is in ``roles``."""
        roles = set(roles)
        return replace(self, measurements=tuple(m for m in self.measurements if m.role in roles))

    def with_values(self, obs: Observations, *, uncertainty: Observations | None = None,
                    provenance: str | None = None) -> "MeasurementSet":
        """A copy with the values (and optionally uncertainties) taken from ``obs``."""
        ms = []
        for m in self.measurements:
            v = np.asarray(obs[m.name], dtype=float)
            if v.shape != m.values.shape:
                raise ValueError(f"observable {m.name!r}: expected {m.values.shape[0]} components, "
                                 f"got {v.shape}")
            u = m.uncertainty if uncertainty is None else np.asarray(uncertainty[m.name], float)
            ms.append(replace(m, values=v, uncertainty=u, replicates=None,
                              provenance=provenance or m.provenance))
        return replace(self, measurements=tuple(ms))

    def merged(self, other: "MeasurementSet") -> "MeasurementSet":
        """This set followed by the observables of ``other`` whose names are new."""
        extra = tuple(m for m in other.measurements if m.name not in self)
        return replace(self, measurements=self.measurements + extra)

