"""What the spreading workflow measures, the same for every engine: the layer's results, the
dynamic angle and coordination of each recorded frame, the bed after each layer, and which
particles are in flight.

Used by :func:`bedstruct.workflows.run_spread` (embedded engine) and by the LIGGGHTS/LAMMPS
spreading runs (:mod:`bedstruct.workflows.external`), which read the same frames from dumps.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace

import numpy as np

from .._json import to_jsonable
from ._common import from_plain, typed

__all__ = ["LayerResult", "SpreadResult", "bed_mask", "frame_metrics", "measure_layer",
           "particles_in_flight", "mid_layer_segregation", "spread_result_from_dict"]

# the spreading workflow's logger: these messages belong to its run
log = logging.getLogger("bedstruct.workflows.spread")

_REGION_NAMES = {3: ("start", "centre", "end")}


@dataclass(frozen=True)
class LayerResult:
    """Measurements of one spread layer (lengths in m, angles in degrees).

    Attributes
    ----------
    index : int
        1-based layer number.
    gap : float, m
        Platform lowering before this layer.
    nominal_height : float, m
        Cumulative gap: the tool height above the platform.
    bed_height_m : float, m
        Mean top-surface height of the bed above the platform (over the
        platform, away from its ends; :func:`bedstruct.analysis.bed_height`).
    bed_top_m : float, m
        95th percentile of the top-surface height (the "top" of the bed).
    bed_height_regions_m : (R,) tuple of float, m
        Mean top-surface height in each region (start, centre, end).
    roughness_sa_m : float, m
        Arithmetic mean deviation Sa of the top surface (ISO 25178).
    packing_fraction : (R,) tuple of float
        Solid fraction of each region (start, centre, end) between the
        platform and the tool height.
    coordination : (R,) tuple of float
        Mean coordination number per region (particle-particle contacts).
    fabric_anisotropy : (R,) tuple of float
        Deviatoric anisotropy of the second-order fabric tensor per region.
    dynamic_angle_deg : tuple of float
        Dynamic angle of the heap in each recorded frame (NaN when it could
        not be fitted or the heap is less than two diameters high).
    mean_dynamic_angle_deg, dynamic_angle_std_deg : float
        Mean and standard deviation over the frames where it was fitted.
    mean_cn_series : tuple of float
        Mean coordination of all particles in each recorded frame.
    blade_positions : tuple of float, m
        Front of the tool in each recorded frame.
    heap_d50_shift : float, m
        Volume D50 of the heap minus that of the deposited bed at mid-layer
        (> 0: coarse particles enriched in the heap).
    segregation_index : float
    n_inserted, n_bed, n_heap, n_removed : int
        Particles inserted this layer; in the bed (on the platform, powder in the air
        left out: :func:`bed_mask`), the others still in the domain (the heap beyond the
        platform, powder in the air), and removed so far (cumulative).
    wall_time : float, s
    landing_wait : float, s
        Settling added before the pile was reinserted, while powder thrown up
        by the previous stroke landed (see :func:`particles_in_flight`; 0 when
        nothing was in flight). LIGGGHTS/LAMMPS decks wait by the same rule
        without its contact test (:func:`bedstruct.engines.spread_layers_deck`).
    tool_force : (3,) tuple of float, N
        Force of the powder on the tool averaged over every step of the stroke
        (:meth:`bedstruct.dem.Simulation.wall_load_average`; what a load cell on
        the recoater mount reports). ``-tool_force[0]`` is the drag, ``-tool_force[2]``
        the downward pull (negative: a push up); their ratio is :attr:`tool_force_ratio`.
        LIGGGHTS and LAMMPS runs record it too
        (:func:`bedstruct.engines.tool_loads`).
    """

    index: int
    gap: float
    nominal_height: float
    bed_height_m: float
    bed_top_m: float
    bed_height_regions_m: tuple
    roughness_sa_m: float
    packing_fraction: tuple
    coordination: tuple
    fabric_anisotropy: tuple
    dynamic_angle_deg: tuple
    mean_dynamic_angle_deg: float
    dynamic_angle_std_deg: float
    mean_cn_series: tuple
    blade_positions: tuple
    heap_d50_shift: float
    segregation_index: float
    n_inserted: int
    n_bed: int
    n_heap: int
    n_removed: int
    wall_time: float
    landing_wait: float = 0.0
    tool_force: tuple = (float("nan"),) * 3

    @property
    def tool_force_ratio(self) -> float:
        """Vertical over horizontal load on the tool over the stroke, ``F_z / F_x`` (NaN
        without a load): positive when the powder drags the tool down its face, negative
        when powder wedged under a bevel pushes it up."""
        fx, fz = float(self.tool_force[0]), float(self.tool_force[2])
        return fz / fx if fx != 0.0 else float("nan")


def particles_in_flight(fr, z_plat: float, x_range, *, gravity=(0.0, 0.0, -9.81)) -> np.ndarray:
    """Particles in free flight over ``x_range = (xa, xb)`` above the platform ``z_plat``.

    In flight: no contact force acts (the total force, gravity included, is within half
    the weight of ``m g``) and the particle does not rest on the platform through
    touching particles (:func:`bedstruct.analysis.grounded_particles`). Particles held
    by the tool (cohesion carries their weight) and grains on the bed are not.

    Parameters
    ----------
    fr : Frame
        SI frame with ``forces`` (total, gravity included) and a ``mass`` column, as
        :meth:`bedstruct.dem.Simulation.frame` gives.
    z_plat : float, m
    x_range : (float, float), m
    gravity : (3,) array_like, m/s^2
    """
    from ..analysis import grounded_particles
    if fr.n_particles == 0:
        return np.zeros(0, dtype=bool)
    if fr.forces is None or "mass" not in fr.columns:
        raise ValueError("particles_in_flight: the frame needs forces and a 'mass' column "
                         "(a Simulation.frame())")
    p = fr.positions
    over = (p[:, 0] >= float(x_range[0])) & (p[:, 0] <= float(x_range[1])) & (p[:, 2] > z_plat)
    mg = np.asarray(fr.columns["mass"], float)[:, None] * np.asarray(gravity, float)[None, :]
    free = over & (np.linalg.norm(np.asarray(fr.forces, float) - mg, axis=1)
                   < 0.5 * np.linalg.norm(mg, axis=1))
    if not free.any():   # the usual case: no contact search needed
        return free
    return free & ~grounded_particles(fr, z_plat)


def bed_mask(fr, plate_length: float, z_plat: float, r_max: float, *,
             tool_level: float = 0.0) -> np.ndarray:
    """The particles of the bed in a spreading frame (SI) after a layer.

    The bed is what lies over the platform (``x < plate_length``) above the platform less
    the largest radius (``z > z_plat - r_max``), except powder in the air: a particle
    whose lowest point is above the tool's lowest point (``z - r > tool_level``), after
    the tool has passed, and that does not rest on the platform through touching
    particles (:func:`bedstruct.analysis.grounded_particles`) was thrown up (squeezed
    under the tool) and is not part of the bed. A particle at that height resting on the
    bed is.

    Parameters
    ----------
    fr : Frame
    plate_length, z_plat, r_max : float, m
        Platform length, platform height and largest particle radius.
    tool_level : float, m, optional
        Height of the tool's lowest point (the workflows keep it at z = 0).

    Returns
    -------
    (N,) ndarray of bool

    Examples
    --------
    >>> from bedstruct import Frame
    >>> f = Frame([[1e-4, 1e-4, -3e-4], [2e-4, 1e-4, -2e-4], [3e-4, 1e-4, 2e-3]],
    ...           [5e-5, 5e-5, 5e-5], box=([0, 0, -1e-3], [1e-3, 1e-3, 3e-3]))
    >>> bed_mask(f, 1e-3, -3.5e-4, 5e-5).tolist()    # the third is in the air
    [True, True, False]
    """
    p, r = np.asarray(fr.positions, float), np.asarray(fr.radii, float)
    keep = (p[:, 0] < float(plate_length)) & (p[:, 2] > float(z_plat) - float(r_max))
    high = keep & (p[:, 2] - r > float(tool_level))
    if high.any():   # the usual case is none: no contact search needed
        from ..analysis import grounded_particles
        keep &= ~(high & ~grounded_particles(fr, float(z_plat)))
    return keep


def frame_metrics(fr, contacts, front: float, *, plate_length: float, z_plat: float, r_max: float):
    """Dynamic angle of the heap in front of the tool (degrees, NaN when not measurable) and mean
    coordination ``2 N_c / N`` of one spreading frame (SI).

    The heap is the powder ahead of the tool's front face on the platform. Its
    free surface (side silhouette) is fitted from the crest forwards between
    20 and 80 % of the heap height, measured from the **toe** (the lowest point
    of the surface ahead of the tool: the bed or bare platform the heap runs
    onto), as the seed measures the angle the heap makes with the existing bed.
    NaN when the heap is lower than two median diameters, when its front
    flank does not come down to the bed on the platform (the heap has reached
    the front wall or the end of the platform, or the pile is still the
    inserted block with a vertical front: no free toe above the bed, which
    lies below the tool's lowest point z = 0), or when the fitted line
    descends through less than half of the fitted band (the flat top of a
    block, not a flank).
    """
    return _dynamic_angle(fr, front, plate_length=plate_length, z_plat=z_plat, r_max=r_max), \
        float(2.0 * contacts.n_contacts / max(fr.n_particles, 1))


def _dynamic_angle(fr, front: float, *, plate_length: float, z_plat: float, r_max: float,
                   fit_range=(0.2, 0.8)) -> float:
    """Front-flank angle of the heap ahead of ``front`` (see :func:`frame_metrics`); NaN if none.
    The tool's lowest point is at z = 0."""
    from ..analysis import heap_front_angle
    return heap_front_angle(fr, front, platform_end=plate_length, platform_z=z_plat,
                            tool_bottom=0.0, r_max=r_max, fit_range=fit_range)


def mid_layer_segregation(mfr, mfront: float, plate_length: float, pile) -> tuple:
    """``(heap_d50_shift, segregation_index)`` of the frame ``mfr`` in the middle of a layer
    with the tool's front at ``mfront``, against the initial ``pile`` (NaN, with a logged
    warning, when it cannot be measured)."""
    from ..analysis import segregation
    try:
        sg = segregation(mfr.select(mfr.positions[:, 0] < plate_length), mfront, direction=1,
                         axis=0, initial=pile)
        return float(sg.heap_vs_bed.d50_shift), float(sg.index)
    except (ValueError, AttributeError) as exc:
        log.warning("spread: segregation failed: %s", exc)
        return float("nan"), float("nan")


def measure_layer(fr, contacts_all, cfg, *, index: int, z_plat: float, front0: float,
                  r_max: float, pile, dyn, cn_series, blade_pos, mid, n_inserted: int,
                  n_removed: int, wall_time: float, segregation_values=None, bed=None):
    """Measure the bed of spread layer ``index`` in frame ``fr`` (SI) with its contacts.

    The bed is :func:`bed_mask` of the frame (or ``bed``, that mask when the caller has
    it): powder thrown into the air is left out.

    The same measurement for every engine (see :func:`run_spread`). ``mid`` is a list
    holding the ``(frame, tool front)`` of the middle of the layer (or empty), or give
    ``segregation_values``, :func:`mid_layer_segregation` of it. Returns
    ``(LayerResult, packing_per_region, coordination_per_region)``.
    """
    from ..analysis import (coordination, coordination_by_window, packing_along, region_fabric,
                            surface_height_map)
    sc = typed(cfg).spread
    rmax = r_max
    Lplat, W = float(sc.plate_length), float(sc.width)
    gaps = [float(g) for g in sc.gaps]
    n_reg = int(sc.regions)
    k = index - 1
    gap = gaps[k]
    n_ins = n_inserted
    bed = fr.select(bed_mask(fr, Lplat, z_plat, rmax) if bed is None else bed)
    n_bed = bed.n_particles
    n_heap = fr.n_particles - n_bed
    H_k = sum(gaps[:k + 1])
    xa, xb = front0 + 2 * rmax, Lplat - 2 * rmax
    try:
        surf = surface_height_map(bed, base=z_plat, bounds=((xa, xb), (0.0, W)),
                                  spacing=0.5 * float(np.median(bed.radii)))
        hmap = np.asarray(surf.heights) - z_plat
        h = float(np.mean(hmap))
        h_top = float(np.percentile(hmap, 95))
        sa = float(surf.sa)
        xs = np.asarray(surf.x)
        e = np.linspace(xa, xb, n_reg + 1)
        h_reg = tuple(float(np.mean(hmap[(xs >= e[i]) & (xs <= e[i + 1])]))
                      for i in range(n_reg))
    except ValueError:
        h = h_top = sa = float("nan")
        h_reg = (float("nan"),) * n_reg
    lo = np.array([xa, 0.0, z_plat])
    hi = np.array([xb, W, z_plat + H_k])
    pack = packing_along(bed, n_reg, axis=0, bounds=(lo, hi)).fractions
    coord = coordination(fr, contacts_all)
    wlo, whi = _windows(lo, hi, n_reg)
    cnw = coordination_by_window(fr, wlo, whi, contacts=contacts_all, result=coord).mean
    try:
        rf = region_fabric(contacts_all, fr, axis=0, n_regions=n_reg, bounds=(xa, xb))
        aniso = tuple(float(rf[nm].anisotropy) if rf[nm] is not None else float("nan")
                      for nm in rf.names)
    except (ValueError, KeyError) as exc:
        log.warning("spread: fabric failed: %s", exc)
        aniso = (float("nan"),) * n_reg
    d50s = seg_i = float("nan")
    if segregation_values is not None:
        d50s, seg_i = (float(v) for v in segregation_values)
    elif mid:
        d50s, seg_i = mid_layer_segregation(mid[0][0], mid[0][1], Lplat, pile)
    dyn_a = np.array(dyn, dtype=float)
    ok = np.isfinite(dyn_a)
    layer = (LayerResult(
        index=k + 1, gap=gap, nominal_height=H_k, bed_height_m=float(h), bed_top_m=h_top,
        roughness_sa_m=sa,
        bed_height_regions_m=h_reg,
        packing_fraction=tuple(float(v) for v in pack),
        coordination=tuple(float(v) for v in cnw), fabric_anisotropy=aniso,
        dynamic_angle_deg=tuple(dyn),
        mean_dynamic_angle_deg=float(dyn_a[ok].mean()) if ok.any() else float("nan"),
        dynamic_angle_std_deg=float(dyn_a[ok].std()) if ok.sum() > 1 else float("nan"),
        mean_cn_series=tuple(cn_series), blade_positions=tuple(blade_pos), heap_d50_shift=d50s,
        segregation_index=seg_i, n_inserted=n_ins, n_bed=n_bed, n_heap=n_heap,
        n_removed=int(n_removed), wall_time=float(wall_time)))
    return layer, pack, cnw


def _subset_contacts(contacts, mask):
    """Contacts between particles of ``mask`` only, re-indexed to ``frame.select(mask)``."""
    keep = mask[contacts.i] & mask[contacts.j]
    c = contacts.select(keep)
    new = np.cumsum(mask) - 1
    return replace(c, i=new[c.i], j=new[c.j], n_particles=int(mask.sum()), walls=None)


def _windows(lo, hi, n):
    e = np.linspace(lo[0], hi[0], n + 1)
    lower = np.tile(lo, (n, 1))
    upper = np.tile(hi, (n, 1))
    lower[:, 0] = e[:-1]
    upper[:, 0] = e[1:]
    return lower, upper


@dataclass(frozen=True)
class SpreadResult:
    """Result of a multi-layer spreading run.

    Attributes
    ----------
    layers : tuple of LayerResult
    tool : str
    speed : float, m/s
    regions : tuple of str
    n_pile : int
        Particles in the generated pile (inserted before every layer).
    n_inserted_total : int
    german_a, german_b : float
        Fit of ``CN = 2a + 11 b f^2`` over all layers and regions (NaN with
        fewer than 3 points).
    german_r_squared : float
    german_determined : bool or None
        Whether the points determine ``a`` and ``b`` separately
        (:attr:`bedstruct.analysis.GermanFit.determined`); None without a fit.
    """

    layers: tuple
    tool: str
    speed: float
    regions: tuple
    n_pile: int
    n_inserted_total: int
    german_a: float = float("nan")
    german_b: float = float("nan")
    german_r_squared: float = float("nan")
    german_determined: bool | None = None
    extra: dict = field(default_factory=dict)

    @property
    def bed_height_m(self) -> tuple:
        """Bed height above the platform after each layer (m)."""
        return tuple(layer.bed_height_m for layer in self.layers)

    def to_dict(self) -> dict:
        """JSON-ready summary including ``bed_height_m``, ``packing_fraction`` per layer and region
        and ``mean_dynamic_angle_deg`` per layer."""
        d = to_jsonable(self)
        d["bed_height_m"] = list(self.bed_height_m)
        d["packing_fraction"] = [list(layer.packing_fraction) for layer in self.layers]
        d["mean_dynamic_angle_deg"] = [to_jsonable(layer.mean_dynamic_angle_deg)
                                       for layer in self.layers]
        return d


def spread_result_from_dict(d: dict) -> SpreadResult:
    """The :class:`SpreadResult` of ``SpreadResult.to_dict()`` (as read from results.json)."""
    layers = tuple(from_plain(LayerResult, la) for la in d["layers"])
    base = {k: v for k, v in d.items() if k != "layers"}
    res = from_plain(SpreadResult, {**base, "layers": []})
    extra = d.get("extra") or {}
    return replace(res, layers=layers, regions=tuple(d["regions"]), extra=dict(extra))


#: Settling intervals waited at most for powder in flight to land before a pile is reinserted.
_MAX_LANDING_WAIT = 20
