"""The observable kinds of the diagnosis: one function and one registry entry per kind.

Every kind a measurement file may name is an :class:`ObservableKind`: its name, its
canonical unit, what it needs from a run, the :mod:`bedstruct.analysis` function
that computes it (the definition the report uses too) and the function that turns
a run's data into the kind's component values. :func:`observe` applies it;
:func:`observable_kinds` lists them; :func:`register_observable` adds a kind of
your own, a Python callable on a run's frames.

The built-in kinds and their definitions:

==========================  ====  ==================================================
kind                        unit  computed by
==========================  ====  ==================================================
``static_angle``            deg   :func:`bedstruct.analysis.pile_angle` (a camera
                                  image: :func:`~bedstruct.diagnose.angle_from_image`)
``dynamic_angle_series``    deg   :func:`bedstruct.analysis.dynamic_angle_of_repose`
                                  per frame, window means by
                                  :func:`~bedstruct.diagnose.windowed_mean`
``bed_height``              m     :func:`bedstruct.analysis.bed_height`
``packing_fraction``        1     :func:`bedstruct.analysis.packing_fractions`
``psd``                     m     :func:`bedstruct.analysis.percentile_diameter`
                                  (volume-weighted)
``roughness``               m     :func:`bedstruct.analysis.surface_roughness` (Sa)
``coordination``            1     :func:`bedstruct.analysis.coordination` (mean)
``segregation_index``       1     :func:`bedstruct.analysis.segregation_index`
``tool_force_ratio``        1     :func:`~bedstruct.diagnose.observables.tool_force_ratio`
==========================  ====  ==================================================

.. versionadded:: 0.1
"""

from __future__ import annotations

import hashlib
import importlib
import inspect
from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np

from ..errors import ConfigError
from .measurements import _UNIT, KINDS, PLAUSIBLE
from .observables import psd_percentiles, psd_percentiles_from_cumulative, tool_force_ratio, \
    windowed_mean

__all__ = ["ObservableKind", "observable_kinds", "observable_kind", "register_observable",
           "unregister_observable", "load_callable", "canonical_unit", "observe"]


@dataclass(frozen=True)
class ObservableKind:
    """One observable kind: how a run's data become its component values.

    Attributes
    ----------
    name : str
        The ``kind`` of a measurement file.
    unit : str
        Canonical unit of its values (``"deg"``, ``"m"`` or ``"1"``).
    needs : str
        What it needs from a run (``"repose"``: the settled pile of the repose test;
        ``"spread"``: the bed after a spread layer and the frames of its stroke;
        ``"powder"``: the powder before spreading; ``"tool"``: the load on the
        recoater; ``"frames"``: the beds after each spread layer, for a user kind).
    inputs : str
        The keys of :func:`observe`'s ``data`` it reads.
    analysis : str
        The function that defines it (``""`` when no :mod:`bedstruct.analysis`
        function does).
    compute : callable
        ``compute(data, windows=..., percentiles=...) -> (n,) ndarray``.
    description : str
    user : bool
        Registered by :func:`register_observable`.
    source : str
        For a user kind, ``"module:function"`` and a hash of the function's source
        (part of the engine simulator's cache key: an edited function is run again).
    """

    name: str
    unit: str
    needs: str
    inputs: str
    analysis: str
    compute: Callable[..., np.ndarray]
    description: str = ""
    user: bool = False
    source: str = ""


def _frame(data: Mapping[str, Any]):
    """The ``frame`` of ``data``, or a Frame of its ``positions`` and ``radii`` in a
    non-periodic box around them."""
    from ..core.box import Box
    from ..core.frame import Frame, _as_frame
    if "frame" in data:
        return _as_frame(data["frame"])
    if "positions" not in data or "radii" not in data:
        raise ValueError("needs `frame` (a Frame) or `positions` and `radii`")
    p = np.asarray(data["positions"], dtype=float).reshape(-1, 3)
    r = np.asarray(data["radii"], dtype=float).reshape(-1)
    pad = float(r.max()) if r.size else 1.0
    lo = p.min(axis=0) - 2 * pad if len(p) else np.zeros(3)
    hi = p.max(axis=0) + 2 * pad if len(p) else np.ones(3)
    return Frame(p, r, box=Box.from_box((lo, hi), boundary=("ff", "ff", "ff")))


def _map_options(data):
    """The height-map options in ``data`` (``bounds``, ``spacing``)."""
    return {k: data[k] for k in ("bounds", "spacing") if k in data}


def _region(data, frame):
    if "region_lo" in data or "region_hi" in data:
        return (np.asarray(data["region_lo"], float).reshape(1, 3),
                np.asarray(data["region_hi"], float).reshape(1, 3))
    from ..analysis import bed_bounds
    lo, hi = bed_bounds(frame)
    return np.asarray(lo, float)[None, :], np.asarray(hi, float)[None, :]


# ------------------------------------------------------------------ built-in kinds

def _static_angle(data, **_):
    if "image" in data:
        from .observables_image import angle_from_image
        return np.array([angle_from_image(data["image"], pixel_size=data.get("pixel_size", 1.0))])
    from ..analysis import pile_angle
    frame = _frame(data)
    return np.array([float(pile_angle(frame, axis=0, base=data.get("plate_z")).repose.angle_deg)])


def _dynamic_angle_series(data, *, windows=None, **_):
    if windows is None:
        raise ValueError("dynamic_angle_series needs `windows`")
    if "images" in data:
        from .observables_image import angle_from_image
        angles = [angle_from_image(im, pixel_size=data.get("pixel_size", 1.0)) for im in data["images"]]
    elif "frames" in data and "platform_end" in data:
        # the spreading workflow's heap checks: NaN where a frame shows no heap with a free toe
        from ..analysis import heap_front_angle
        angles = [heap_front_angle(f, b, platform_end=data["platform_end"],
                                   platform_z=data["platform_z"],
                                   tool_bottom=data.get("tool_bottom", 0.0))
                  for f, b in zip(data["frames"], data["blade_positions"])]
    elif "frames" in data:
        from ..analysis import dynamic_repose_series
        angles = dynamic_repose_series(data["frames"], data["blade_positions"]).angle_deg
    else:
        angles = data["angles"]
    return windowed_mean(data["times"], angles, windows)[0]


def _bed_height(data, **_):
    if "surface_heights" in data:
        return np.array([float(np.nanmean(data["surface_heights"]))])
    from ..analysis import bed_height
    frame = _frame(data)
    plate = data.get("plate_z")
    plate = float(np.min(frame.positions[:, 2] - frame.radii)) if plate is None else float(plate)
    return np.array([bed_height(frame, plate, **_map_options(data))])


def _packing_fraction(data, **_):
    from ..analysis import packing_fractions
    frame = _frame(data)
    lo, hi = _region(data, frame)
    return np.array([float(packing_fractions(frame, lo, hi).fractions[0])])


def _psd(data, *, percentiles=None, **_):
    if percentiles is None:
        raise ValueError("psd needs `percentiles`")
    if "diameters" in data:
        return psd_percentiles(data["diameters"], percentiles)
    if "sizes" in data:
        return psd_percentiles_from_cumulative(data["sizes"], data["cumulative"], percentiles)
    return psd_percentiles(2.0 * np.asarray(_frame(data).radii), percentiles)


def _roughness(data, **_):
    from ..analysis import surface_height_map, surface_roughness
    if "surface_heights" in data:
        return np.array([surface_roughness(data["surface_heights"]).sa])
    kw = _map_options(data)
    if data.get("plate_z") is not None:   # bare platform counts as height zero, as in bed_height
        kw["base"] = float(data["plate_z"])
    return np.array([surface_height_map(_frame(data), **kw).sa])


def _coordination(data, **_):
    if "coordination" in data:
        return np.array([float(np.mean(data["coordination"]))])
    from ..analysis import coordination
    return np.array([coordination(_frame(data), data.get("contacts")).mean])


def _segregation_index(data, **_):
    from ..analysis import segregation_index
    frame = _frame(data)
    if "windows_lo" in data:
        return np.array([segregation_index(frame, data["windows_lo"], data["windows_hi"])])
    return np.array([segregation_index(frame)])


def _tool_force_ratio(data, **_):
    return np.array([tool_force_ratio(data["force_x"], data["force_z"])[0]])


_BUILTIN = (
    ObservableKind("static_angle", "deg", "repose", "image (+ pixel_size), or frame / positions + "
                   "radii (+ plate_z)", "bedstruct.analysis.pile_angle", _static_angle,
                   "static angle of repose of a settled pile (both flanks fitted, averaged)"),
    ObservableKind("dynamic_angle_series", "deg", "spread",
                   "times (stroke fractions) and angles (deg), images (+ pixel_size) or frames + "
                   "blade_positions (+ platform_end, platform_z, tool_bottom: the heap checks "
                   "of heap_front_angle); windows", "bedstruct.analysis.dynamic_angle_of_repose",
                   _dynamic_angle_series, "mean dynamic angle of the heap ahead of the tool in "
                   "each time window of the stroke"),
    ObservableKind("bed_height", "m", "spread", "frame / positions + radii (+ plate_z, bounds, "
                   "spacing), or surface_heights", "bedstruct.analysis.bed_height", _bed_height,
                   "mean top-surface height of the bed above the platform after a layer"),
    ObservableKind("packing_fraction", "1", "spread", "frame / positions + radii (+ region_lo, "
                   "region_hi)", "bedstruct.analysis.packing_fractions", _packing_fraction,
                   "solid fraction of a region of the bed (exact sphere-box volumes)"),
    ObservableKind("psd", "m", "powder", "diameters, frame / positions + radii, or sizes + "
                   "cumulative; percentiles", "bedstruct.analysis.percentile_diameter", _psd,
                   "volume-weighted percentile diameters, before or after spreading"),
    ObservableKind("roughness", "m", "spread", "surface_heights, or frame / positions + radii "
                   "(+ plate_z, bounds, spacing)", "bedstruct.analysis.surface_roughness", _roughness,
                   "arithmetic mean height deviation Sa of the top surface"),
    ObservableKind("coordination", "1", "spread", "coordination (per-particle counts), or frame "
                   "(+ contacts)", "bedstruct.analysis.coordination", _coordination,
                   "mean number of particle-particle contacts per particle"),
    ObservableKind("segregation_index", "1", "spread", "frame / positions + radii (+ windows_lo, "
                   "windows_hi)", "bedstruct.analysis.segregation_index", _segregation_index,
                   "coefficient of variation of the windows' volume-weighted mean diameters"),
    ObservableKind("tool_force_ratio", "1", "tool", "force_x + force_z", "",
                   _tool_force_ratio, "vertical over horizontal load on the recoater over a stroke"),
)

_REGISTRY: dict[str, ObservableKind] = {k.name: k for k in _BUILTIN}
_CANONICAL = {"angle": "deg", "length": "m", "fraction": "1"}


def observable_kinds() -> tuple[ObservableKind, ...]:
    """Every observable kind, built-in ones first.

    Examples
    --------
    >>> [k.name for k in observable_kinds()][:3]
    ['static_angle', 'dynamic_angle_series', 'bed_height']
    """
    return tuple(_REGISTRY.values())


def observable_kind(name: str) -> ObservableKind:
    """The kind called ``name``.

    Raises
    ------
    ValueError
        If no kind has that name (the message lists them).

    Examples
    --------
    >>> observable_kind("bed_height").analysis
    'bedstruct.analysis.bed_height'
    """
    if name not in _REGISTRY:
        raise ValueError(f"unknown observable kind {name!r}; known: {sorted(_REGISTRY)} "
                         f"(register your own with register_observable)")
    return _REGISTRY[name]


def _source_hash(func) -> str:
    try:
        text = inspect.getsource(func)
    except (OSError, TypeError):
        text = repr(getattr(func, "__code__", func))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def register_observable(name: str, func: Callable, *, unit: str, description: str = "",
                        plausible: tuple[float, float] | None = None) -> ObservableKind:
    """Add an observable kind computed by your own function of a run's frames.

    Parameters
    ----------
    name : str
        The kind's name (what a measurement file's ``kind`` says). It must not be a
        built-in kind's; registering the same name again replaces the function.
    func : callable
        ``func(frames) -> float or (n,) array``: ``frames`` is a list of
        :class:`bedstruct.Frame` in SI units (the engine simulator passes the bed
        after each spread layer up to the observable's ``conditions.layer``, the last
        one that layer's), and the result is in the canonical unit.
    unit : str
        Canonical unit of the result: ``"deg"``, ``"m"`` or ``"1"`` (a file may state
        its values in any unit of the same dimension, e.g. ``"um"``).
    description : str
    plausible : (lo, hi), optional
        Range measured values must lie in (canonical unit), as for the built-in kinds.

    Returns
    -------
    ObservableKind

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> def top_z(frames):
    ...     f = frames[-1]
    ...     return float(np.max(f.positions[:, 2] + f.radii))
    >>> k = register_observable("top_z", top_z, unit="m")
    >>> f = Frame([[0.5, 0.5, 0.5]], [0.5], box=[1, 1, 2])
    >>> observe("top_z", {"frames": [f]})
    array([1.])
    >>> unregister_observable("top_z")
    """
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"observable name must be an identifier (letters, digits, _); got {name!r}")
    if name in _REGISTRY and not _REGISTRY[name].user:
        raise ValueError(f"{name!r} is a built-in observable kind; choose another name")
    if not callable(func):
        raise TypeError(f"`func` must be callable; got {type(func).__name__}")
    if unit not in ("deg", "m", "1"):
        raise ValueError(f"`unit` must be the canonical unit 'deg', 'm' or '1'; got {unit!r}")

    def compute(data, **_):
        frames = data.get("frames")
        if frames is None and "frame" in data:
            frames = [data["frame"]]
        if frames is None:
            raise ValueError(f"observable {name!r} needs `frames` (a list of Frame)")
        out = np.atleast_1d(np.asarray(func(list(frames)), dtype=float)).ravel()
        if out.size == 0:
            raise ValueError(f"observable {name!r}: {getattr(func, '__name__', func)} returned "
                             f"no value")
        return out

    where = f"{getattr(func, '__module__', '?')}:{getattr(func, '__qualname__', repr(func))}"
    kind = ObservableKind(name, unit, "frames", "frames (a list of Frame)", "", compute,
                          description or (inspect.getdoc(func) or "").split("\n")[0], user=True,
                          source=f"{where}#{_source_hash(func)}")
    _REGISTRY[name] = kind
    KINDS[name] = unit
    if plausible is not None:
        PLAUSIBLE[name] = (float(plausible[0]), float(plausible[1]))
    else:
        PLAUSIBLE.pop(name, None)
    return kind


def unregister_observable(name: str) -> None:
    """Remove a kind added by :func:`register_observable` (built-in kinds stay)."""
    k = _REGISTRY.get(name)
    if k is None or not k.user:
        raise ValueError(f"{name!r} is not a registered user observable")
    del _REGISTRY[name]
    KINDS.pop(name, None)
    PLAUSIBLE.pop(name, None)


def load_callable(spec: str) -> Callable:
    """The function named by ``"module:function"`` (``"package.module:name"``).

    Raises
    ------
    ConfigError
        If the text is not of that form, the module cannot be imported or has no
        such callable.

    Examples
    --------
    >>> load_callable("math:hypot")(3, 4)
    5.0
    """
    if not isinstance(spec, str) or spec.count(":") != 1 or not all(spec.split(":")):
        raise ConfigError(f"expected 'module:function' (e.g. 'mypackage.observables:heap_width'); "
                          f"got {spec!r}")
    mod_name, attr = spec.split(":")
    try:
        mod = importlib.import_module(mod_name)
    except ImportError as exc:
        raise ConfigError(f"cannot import module {mod_name!r} of {spec!r} ({exc}); is it on "
                          f"the Python path?") from None
    obj = mod
    for part in attr.split("."):
        obj = getattr(obj, part, None)
    if not callable(obj):
        raise ConfigError(f"module {mod_name!r} has no callable {attr!r}")
    return obj


def canonical_unit(unit: str) -> str:
    """The canonical unit of the dimension of ``unit`` (``"um"`` -> ``"m"``)."""
    if unit not in _UNIT:
        raise ValueError(f"unknown unit {unit!r}; expected one of {sorted(_UNIT)}")
    return _CANONICAL[_UNIT[unit][0]]


def observe(kind: str, data, *, windows=None, percentiles=None) -> np.ndarray:
    """Apply the observation function of ``kind`` to a run's (or a measurement's) data.

    This is the contract between a simulation workflow (or a real-data reader)
    and the diagnosis: ``data`` is a dict of arrays whose keys each kind lists in
    :attr:`ObservableKind.inputs` (see :func:`observable_kinds`). A
    :class:`bedstruct.Frame` may be passed instead of a dict for the frame-based
    kinds (it becomes ``{"frame": frame}``), a list of frames for a user kind.

    Parameters
    ----------
    kind : str
        A name of :func:`observable_kinds`.
    data : mapping, Frame or list of Frame
    windows : (n, 2) array_like, optional
        Time windows of a ``dynamic_angle_series`` (stroke fractions).
    percentiles : (n,) array_like, optional
        Volume percentiles of a ``psd`` (e.g. 10, 50, 90).

    Returns
    -------
    (n,) ndarray
        Component values in the kind's canonical unit.

    Raises
    ------
    ValueError
        Unknown kind, or ``data`` lacks what the kind needs.

    Examples
    --------
    >>> observe("coordination", {"coordination": [3, 4, 5]})
    array([4.])
    """
    k = observable_kind(kind)
    if isinstance(data, (list, tuple)) and data and all(hasattr(f, "positions") for f in data):
        data = {"frames": list(data)}
    elif not isinstance(data, Mapping):
        if hasattr(data, "positions") and hasattr(data, "radii"):
            data = {"frame": data} if hasattr(data, "box") else \
                {"positions": np.asarray(data.positions), "radii": np.asarray(data.radii)}
        else:
            raise TypeError(f"`data` must be a dict of arrays or a Frame; got {type(data).__name__}")
    try:
        return np.atleast_1d(np.asarray(k.compute(data, windows=windows, percentiles=percentiles),
                                        dtype=float)).ravel()
    except KeyError as exc:
        raise ValueError(f"observable kind {kind!r} needs {k.inputs}; missing {exc}") from None
