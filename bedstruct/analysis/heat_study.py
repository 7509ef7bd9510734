"""The seed's heat-conduction study on a spread bed: start, centre and end regions.

Section 2.4.2 of the seed report places a 500 um hemispherical source, heated
to 1300 C and switched off, on the start, centre and end regions of a spread
bed, and compares the peak temperature "at the end of the simulation" and the
roundness of the heat-affected zone (HAZ) with the contact fabric.
:func:`heat_regions` runs that study with the model of
:mod:`bedstruct.analysis.heat`, with the settings the seed does not state
chosen by rule:

- **End time.** Every region runs from the same pulse until its hottest
  particle has cooled to ``stop_fraction`` of the pulse excess,
  ``T0 + f (T_s - T0)`` (default ``f = 0.25``: the seed's peaks, mean 343 C,
  are 0.25 of the way from 20 C to 1300 C). The study's end time is the
  median of these crossing times, and every region is reported at that one
  time, as in the seed (one simulated time, peaks that differ by region).
  Scaling every conductance by one factor (another modulus, hence other
  contact radii, or another conductivity) only rescales time, so this rule
  gives results that do not depend on it.
- **HAZ outline.** The connected zone of the top-view map at or above
  ``T0 + q (T_map,max - T0)`` (default ``q = 0.5``, the half-maximum
  contour) around the source.
- **Several sources per region** (``n_sources``), shifted across the bed,
  give the scatter due to the particles under the source.
- **Narrow periodic strips** are replicated (tiled) along their periodic
  horizontal axes until they are at least ``min_width`` wide (default six
  source diameters), so that the source does not meet its own periodic
  image. The replicas are the periodic images the simulation itself assumed.

The effective conductivity tensor of each region (imposed gradients, see
:func:`~bedstruct.analysis.heat.conductivity_tensor`) and the normal fabric of
the same contacts are returned beside the HAZ; the in-plane (x-y) block of the
tensor predicts the HAZ roundness of a continuum, ``sqrt(k_min / k_max)``.

Everything is SI (m, s, K) except ``lower``/``upper`` given back also in the
frame's length unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ._heat_maps import ConductivityTensor, HAZShape, TemperatureMap, conductivity_tensor, haz_shape, temperature_map
from ._heat_network import ThermalNetwork, thermal_network
from ._heat_solver import HemisphereSource, conduct_heat, source_nodes

__all__ = ["HeatRegionsResult", "heat_regions", "heat_regions_table", "tile_network", "planar_axes"]

_REGION_NAMES = {1: ("bed",), 2: ("start", "end"), 3: ("start", "centre", "end")}


@dataclass(frozen=True, eq=False)
class HeatRegionsResult:
    """Heat pulses on the regions of a bed (seed section 2.4.2).

    Attributes
    ----------
    names : tuple of str
        Region names (``start``, ``centre``, ``end`` for three regions).
    lower, upper : (K, 3) ndarray, m
        Region windows (the bed split along ``axis``).
    source_centers : (K, S, 3) ndarray, m
        Centres of the hemispherical sources (on the local bed surface), S
        per region (``n_sources``).
    source_nodes : tuple of tuple of ndarray of int
        Particles heated by each pulse (rows of ``network``).
    time : float, s
        The common end time (median of ``crossing_times``).
    crossing_times : (K, S) ndarray, s
        When the hottest particle of each run fell to the stop temperature.
    initial_temperature, source_temperature : float, K
    stop_fraction, threshold_fraction : float
    peak_temperature : (K, S) ndarray, K
        Hottest particle at ``time`` (the seed's "peak temperature at the end
        of the simulation").
    thresholds : (K, S) ndarray, K
        HAZ outline temperature of each run.
    haz : tuple of tuple of HAZShape
        ``haz[k][s]``: region ``k``, source ``s``.
    maps : tuple of tuple of TemperatureMap
        Top views at ``time`` around each source (one region long and wide).
    conductivity : tuple of ConductivityTensor
        Effective conductivity and fabric of each region (untiled bed).
    temperatures : (K, S, N) ndarray, K
        Particle temperatures of every run at ``time`` (rows of ``network``),
        to re-map or re-threshold without rerunning.
    history_times, history_peak : tuple of tuple of ndarray, s and K
        Hottest-particle temperature over time of each run.
    network : ThermalNetwork
        The (tiled) network the pulses ran on.
    tiles : (3,) tuple of int
        Replicas along x, y, z.
    """

    names: tuple
    lower: np.ndarray
    upper: np.ndarray
    source_centers: np.ndarray
    source_nodes: tuple
    time: float
    crossing_times: np.ndarray
    initial_temperature: float
    source_temperature: float
    stop_fraction: float
    threshold_fraction: float
    peak_temperature: np.ndarray
    thresholds: np.ndarray
    haz: tuple
    maps: tuple
    conductivity: tuple
    temperatures: np.ndarray
    history_times: tuple
    history_peak: tuple
    network: ThermalNetwork
    tiles: tuple

    @property
    def roundness(self) -> np.ndarray:
        """(K, S) HAZ roundness ``4 A / (pi L_major^2)`` of every run (dimensionless)."""
        return np.array([[h.roundness for h in row] for row in self.haz])

    @property
    def orientation_deg(self) -> np.ndarray:
        """(K, S) HAZ major-axis angle from +x towards +y of every run, degrees."""
        return np.array([[h.orientation_deg for h in row] for row in self.haz])

    @property
    def mean_orientation_deg(self) -> np.ndarray:
        """(K,) direction of the mean elongation of a region's zones, degrees in (-90, 90].

        The axial mean of ``2 theta`` weighted by the elongation ``1 - R``.
        """
        z = np.sum((1.0 - self.roundness) * np.exp(2j * np.radians(self.orientation_deg)), axis=1)
        a = 0.5 * np.degrees(np.angle(z))
        return np.where(a <= -90.0, a + 180.0, a)

    @property
    def conductivity_roundness(self) -> np.ndarray:
        """Continuum HAZ roundness ``sqrt(k_min / k_max)`` of the in-plane conductivity."""
        return np.array([planar_axes(k.tensor)[1] for k in self.conductivity])

    @property
    def conductivity_orientation_deg(self) -> np.ndarray:
        """In-plane direction of highest conductivity from +x, degrees in (-90, 90]."""
        return np.array([planar_axes(k.tensor)[0] for k in self.conductivity])

    @property
    def fabric_ratio(self) -> np.ndarray:
        """In-plane fabric eigenvalue ratio ``n_min / n_max`` (1: isotropic in x-y)."""
        return np.array([planar_axes(k.fabric)[1] ** 2 for k in self.conductivity])

    @property
    def fabric_orientation_deg(self) -> np.ndarray:
        """In-plane direction of most contacts from +x, degrees in (-90, 90]."""
        return np.array([planar_axes(k.fabric)[0] for k in self.conductivity])


def planar_axes(tensor) -> tuple[float, float]:
    """Principal direction and ``sqrt(min/max)`` of the x-y block of a 3x3 tensor.

    Parameters
    ----------
    tensor : (3, 3) array_like
        Symmetric tensor (e.g. conductivity, W/(m K), or fabric).

    Returns
    -------
    angle_deg : float
        Angle of the eigenvector of the larger in-plane eigenvalue from +x
        towards +y, in (-90, 90] degrees.
    ratio : float
        ``sqrt(lambda_min / lambda_max)`` of the x-y block: the roundness of
        the iso-contours of diffusion with that tensor (1 when isotropic).

    Examples
    --------
    >>> a, r = planar_axes(np.diag([4.0, 1.0, 9.0]))
    >>> float(a), float(r)
    (0.0, 0.5)
    """
    t = np.asarray(tensor, dtype=np.float64)
    if t.shape != (3, 3):
        raise ValueError(f"`tensor` must have shape (3, 3); got {t.shape}")
    w, v = np.linalg.eigh(0.5 * (t[:2, :2] + t[:2, :2].T))
    ang = math.degrees(math.atan2(v[1, 1], v[0, 1]))
    ang = (ang + 90.0) % 180.0 - 90.0
    if ang <= -90.0:
        ang += 180.0
    ratio = math.sqrt(max(w[0], 0.0) / w[1]) if w[1] > 0 else float("nan")
    return float(ang) + 0.0, float(ratio)


def tile_network(network: ThermalNetwork, reps) -> ThermalNetwork:
    """Replicate a network along its periodic axes (the periodic images made explicit).

    Parameters
    ----------
    network : ThermalNetwork
    reps : (3,) sequence of int
        Copies along x, y, z; an axis with more than one copy must be periodic.

    Returns
    -------
    ThermalNetwork
        ``prod(reps)`` copies; copy ``(a, b, c)`` holds rows
        ``((a * reps[1] + b) * reps[2] + c) * N + row``. Contacts across a
        periodic face join neighbouring copies, and the box grows accordingly.

    Examples
    --------
    >>> from bedstruct.core import Box, Contacts, Frame, Units
    >>> f = Frame([[5.0, 5, 5], [5, 15, 5]], [5.1, 5.1], units=Units("micro"),
    ...           box=Box([0, 0, 0], [10, 20, 10], boundary="ff pp ff"))
    >>> c = Contacts([0, 1], [1, 0], [[0, 10, 0], [0, 10, 0]], [5.1, 5.1], [5.1, 5.1])
    >>> big = tile_network(thermal_network(f, c), (1, 3, 1))
    >>> big.n_particles, big.n_contacts, round(float(big.box_hi[1]) * 1e6, 6)
    (6, 6, 60.0)
    """
    net = network
    reps = tuple(int(r) for r in reps)
    if len(reps) != 3 or min(reps) < 1:
        raise ValueError(f"`reps` must be three positive integers; got {reps!r}")
    for ax in range(3):
        if reps[ax] > 1 and not net.periodic[ax]:
            raise ValueError(f"axis {ax} is not periodic; it cannot be tiled")
    if reps == (1, 1, 1):
        return net
    n = net.n_particles
    L = net.box_hi - net.box_lo
    pos, i, j, br = net.positions, net.i, net.j, net.branch
    # image shift of j relative to the copy of i, per axis
    shift = np.rint((pos[i] + br - pos[j]) / np.where(L > 0, L, 1.0)).astype(np.int64)
    copies = np.stack(np.meshgrid(*[np.arange(r) for r in reps], indexing="ij"), -1).reshape(-1, 3)
    rep = np.array(reps)

    def flat(c):
        return (c[..., 0] * reps[1] + c[..., 1]) * reps[2] + c[..., 2]

    P, I, J = [], [], []
    for cp in copies:
        P.append(pos + cp * L)
        I.append(flat(cp) * n + i)
        J.append(flat((cp + shift) % rep) * n + j)
    k = len(copies)
    return replace(
        net, capacity=np.tile(net.capacity, k), i=np.concatenate(I), j=np.concatenate(J),
        conductance=np.tile(net.conductance, k), gas_conductance=np.tile(net.gas_conductance, k),
        branch=np.tile(br, (k, 1)), positions=np.concatenate(P), radii=np.tile(net.radii, k),
        plate_conductance=np.tile(net.plate_conductance, k), box_hi=net.box_lo + rep * L,
        types=None if net.types is None else np.tile(net.types, k),
        units=net.units + f"; tiled {reps[0]}x{reps[1]}x{reps[2]}")


def _cool_until(net, T, target, t_chunk, kw, max_chunks=40):
    """Run from state ``T`` until max T <= target; return times, max T, snapshots (t, T)."""
    t0 = 0.0
    ts, peaks, snaps = [0.0], [float(T.max())], [(0.0, T)]
    for _ in range(max_chunks):
        rec = np.linspace(0.0, t_chunk, 17)
        res = conduct_heat(net, t_end=t_chunk, initial_temperature=T, times=rec, **kw)
        for t, Tk in zip(res.times[1:], res.temperatures[1:]):
            ts.append(t0 + float(t))
            peaks.append(float(Tk.max()))
            snaps.append((t0 + float(t), Tk))
        T = res.final_temperature
        t0 += t_chunk
        if peaks[-1] <= target:
            return np.array(ts), np.array(peaks), snaps
        t_chunk *= 2.0
    raise RuntimeError(f"the hottest particle did not cool to {target:.1f} K within {t0:g} s; "
                       "is the bed held at a higher temperature?")


def heat_regions(frame, contacts=None, *, n_regions: int = 3, axis: int = 0, bounds=None,
                 names=None, n_sources: int = 1, source_diameter: float = 500e-6, source_temperature: float = 1573.15,
                 initial_temperature: float = 293.15, stop_fraction: float = 0.25,
                 threshold_fraction: float = 0.5, tiles=None, min_width: float | None = None,
                 materials=None, length_unit=None, gas=None, contact_area: str = "auto",
                 cell: float | None = None, map_method: str = "top", atol: float | None = None
                 ) -> HeatRegionsResult:
    """Seed section 2.4.2: a heat pulse on each region of a bed, HAZ and conductivity.

    For each of ``n_regions`` equal windows along ``axis``
    (:func:`bedstruct.analysis.bed_windows`) the particles inside a
    hemisphere of ``source_diameter`` centred on the bed surface above the
    window centre start at ``source_temperature``, the rest at
    ``initial_temperature``, and heat conducts through the contacts (plate
    insulated). Each run continues until its hottest particle has cooled to
    ``T0 + stop_fraction (T_s - T0)``; the median of these crossing times is
    the common end time at which every region is mapped from above and its
    heat-affected zone measured at ``T0 + threshold_fraction (T_max - T0)``,
    ``T_max`` the hottest cell of its map.

    Parameters
    ----------
    frame : Frame
        The bed (frame length unit; its unit system must be known, or give
        ``length_unit``).
    contacts : Contacts, optional
        Contacts of ``frame``; found geometrically when omitted. Dumped
        contact areas are used when present (``contact_area="auto"``).
    n_regions : int
        Number of regions (3: start, centre, end).
    axis : int
        Spreading direction (0: x, 1: y).
    bounds : pair of (3,) array_like, optional, frame length unit
        Bed region to split; default :func:`bedstruct.analysis.bed_bounds`.
    names : sequence of str, optional
        Region names; default ``start, centre, end`` for three.
    n_sources : int
        Pulses per region, one at a time, at the window centre shifted
        across the bed (the other horizontal axis) by equal steps over one
        period of a periodic strip (half the bed width otherwise). Several
        give the scatter of the results due to the particle arrangement
        under the source.
    source_diameter : float, m
        Diameter of the hemispherical source (seed: 500e-6).
    source_temperature : float, K
        Pulse temperature (seed: 1300 C = 1573.15 K).
    initial_temperature : float, K
        Bed temperature before the pulse (default 20 C; the seed does not say).
    stop_fraction : float
        Fraction of the pulse excess at which a run counts as cooled
        (0 < f < 1).
    threshold_fraction : float
        Outline of the HAZ between ambient (0) and the map's hottest cell (1).
    tiles : (3,) sequence of int, optional
        Replicas along x, y, z (periodic axes only); default enough copies
        of each periodic horizontal axis other than ``axis`` to make it at
        least ``min_width`` wide.
    min_width : float, optional, m
        Default ``6 * source_diameter``.
    materials, length_unit, gas, contact_area
        Passed to :func:`bedstruct.analysis.heat.thermal_network`.
    cell : float, optional, m
        Map cell; default a quarter of the median radius.
    map_method : {"top", "max", "linear"}
        See :func:`bedstruct.analysis.heat.temperature_map`.
    atol : float, optional, K
        Solver tolerance (default 1e-3 of the temperature span).

    Returns
    -------
    HeatRegionsResult

    Raises
    ------
    ValueError
        For fractions outside (0, 1), a source hotter than nothing, or a
        source that covers no particle.

    Notes
    -----
    Every conductance scaled by one factor ``s`` (a softer or stiffer
    contact, another solid conductivity) scales time by ``1/s`` and leaves
    the temperatures at the crossing times, hence the peaks and the HAZ,
    unchanged: the end-time rule makes the comparison independent of the
    contact stiffness of a softened DEM model. The continuum HAZ of a
    point source in a medium of conductivity ``K`` has iso-contours that are
    ellipses with axes proportional to ``sqrt(k_i)``, hence roundness
    ``sqrt(k_min / k_max)`` of the in-plane block
    (:attr:`HeatRegionsResult.conductivity_roundness`).

    .. versionadded:: 0.1

    Examples
    --------
    A cubic lattice heated at the centre gives a round zone:

    >>> import numpy as np
    >>> from bedstruct.core import Box, Contacts, Frame, Units
    >>> g = np.stack(np.meshgrid(np.arange(15), np.arange(15), np.arange(3), indexing="ij"), -1).reshape(-1, 3)
    >>> f = Frame((g + 0.5) * 20.0, np.full(len(g), 10.5), box=Box([0, 0, 0], [300, 300, 60]),
    ...           units=Units("micro"))
    >>> res = heat_regions(f, n_regions=1, source_diameter=45e-6, cell=2.5e-6)
    >>> res.names, bool(res.roundness[0, 0] > 0.9)
    (('bed',), True)
    >>> round(float(res.conductivity_roundness[0]), 6)
    1.0
    """
    from .packing import bed_windows

    n_regions, n_sources = int(n_regions), int(n_sources)
    if n_sources < 1:
        raise ValueError(f"`n_sources` must be >= 1; got {n_sources}")
    if n_regions < 1:
        raise ValueError(f"`n_regions` must be >= 1; got {n_regions}")
    if axis not in (0, 1):
        raise ValueError(f"`axis` must be 0 (x) or 1 (y), a horizontal axis; got {axis!r}")
    for name, v in (("stop_fraction", stop_fraction), ("threshold_fraction", threshold_fraction)):
        if not 0.0 < float(v) < 1.0:
            raise ValueError(f"`{name}` must lie in (0, 1); got {v!r}")
    T0, Ts = float(initial_temperature), float(source_temperature)
    if not (T0 > 0 and Ts > T0):
        raise ValueError(f"need 0 < `initial_temperature` < `source_temperature` (K); got {T0}, {Ts}")
    if names is None:
        names = _REGION_NAMES.get(n_regions, tuple(f"region{k}" for k in range(n_regions)))
    names = tuple(str(s) for s in names)
    if len(names) != n_regions:
        raise ValueError(f"`names` must have {n_regions} entries; got {len(names)}")

    base = thermal_network(frame, contacts, materials=materials, length_unit=length_unit, gas=gas,
                           contact_area=contact_area)
    s = base.length_scale
    lo_f, hi_f = bed_windows(frame, n_regions, axis=axis, bounds=bounds)
    lower, upper = lo_f * s, hi_f * s
    kt = tuple(conductivity_tensor(base, region=(lo, hi)) for lo, hi in zip(lower, upper))

    L = base.box_hi - base.box_lo
    if tiles is None:
        width = 6.0 * source_diameter if min_width is None else float(min_width)
        tiles = [1, 1, 1]
        for ax in (0, 1):
            if ax != axis and base.periodic[ax] and L[ax] < width:
                tiles[ax] = int(math.ceil(width / L[ax]))
    tiles = tuple(int(t) for t in tiles)
    net = tile_network(base, tiles)
    # tiled region windows: periodic transverse axes span all copies
    lower_t, upper_t = lower.copy(), upper.copy()
    for ax in range(3):
        if tiles[ax] > 1:
            lower_t[:, ax] = net.box_lo[ax]
            upper_t[:, ax] = net.box_hi[ax]
    target = T0 + float(stop_fraction) * (Ts - T0)
    kw = {"atol": atol}
    # natural time of one particle: C / sum G; a source of radius R needs ~ (R / r)^2 of them
    gs = net.weight_sums
    tau = float(np.median(net.capacity[gs > 0] / gs[gs > 0])) if np.any(gs > 0) else 1.0
    t_chunk = tau * max(1.0, (0.5 * source_diameter / float(np.median(net.radii))) ** 2)

    # source positions: region centre, shifted across the bed for n_sources > 1
    trans = 1 - axis
    if base.periodic[trans]:
        span = float(L[trans])                         # one period of the original strip
    else:
        span = 0.5 * float(upper[0, trans] - lower[0, trans])
    offsets = (np.arange(n_sources) / n_sources - (n_sources - 1) / (2.0 * n_sources)) * span

    runs = []          # per (region, source): centre, nodes, times, peaks, snapshots, crossing
    for lo, hi in zip(lower_t, upper_t):
        row = []
        for off in offsets:
            c2 = 0.5 * (lo + hi)
            c2[trans] += off
            nodes, centre = source_nodes(net, HemisphereSource((float(c2[0]), float(c2[1])),
                                                               diameter=source_diameter, temperature=Ts))
            T = np.full(net.n_particles, T0)
            T[nodes] = Ts
            ts, peaks, snaps = _cool_until(net, T, target, t_chunk, kw)
            k = int(np.argmax(peaks <= target))
            # crossing time: linear in the log of the excess between the bracketing records
            e0, e1 = math.log(peaks[k - 1] - T0), math.log(max(peaks[k] - T0, 1e-300))
            et = math.log(target - T0)
            frac = (e0 - et) / (e0 - e1) if e0 != e1 else 1.0
            tc = ts[k - 1] + frac * (ts[k] - ts[k - 1])
            # keep the start and the snapshots near the crossing (the common end time is usually near)
            snaps = [snaps[0]] + [sn for sn in snaps[1:] if sn[0] >= 0.25 * tc]
            row.append([centre, nodes, ts, peaks, snaps, tc])
        runs.append(row)
    cross = np.array([[r[5] for r in row] for row in runs])
    t_end = float(np.median(cross))

    peak = np.empty(cross.shape)
    thr = np.empty(cross.shape)
    hazs, maps = [], []
    finals = np.empty(cross.shape + (net.n_particles,))
    for k in range(n_regions):
        hz, mp = [], []
        for q, run in enumerate(runs[k]):
            c, snaps = run[0], run[4]
            # last snapshot at or before t_end, then the rest of the way
            idx = max(m for m, (t, _) in enumerate(snaps) if t <= t_end * (1 + 1e-12))
            t_a, T = snaps[idx]
            if t_end - t_a > 1e-9 * t_end:
                res = conduct_heat(net, t_end=t_end - t_a, initial_temperature=T,
                                   times=[0.0, t_end - t_a], **kw)
                T = res.final_temperature
            if t_end > run[2][-1]:
                run[2] = np.append(run[2], t_end)
                run[3] = np.append(run[3], float(T.max()))
            # a square map one region wide, centred on the source (symmetric cell grid)
            h_cell = 0.25 * float(np.median(net.radii)) if cell is None else float(cell)
            half = 0.5 * h_cell * math.ceil(float(upper[k, axis] - lower[k, axis]) / h_cell)
            ext = (c[0] - half, c[0] + half, c[1] - half, c[1] + half)
            m = temperature_map(net, temperature=T, cell=h_cell, extent=ext, method=map_method)
            m = replace(m, source_center=np.array(c[:2]), time=t_end)
            top = float(np.nanmax(m.values))
            thr[k, q] = T0 + float(threshold_fraction) * (top - T0)
            peak[k, q] = float(T.max())
            finals[k, q] = T
            hz.append(haz_shape(m, thr[k, q]))
            mp.append(m)
            run[4] = None                                 # free the snapshots
        hazs.append(tuple(hz))
        maps.append(tuple(mp))
    return HeatRegionsResult(
        names=names, lower=lower, upper=upper,
        source_centers=np.array([[r[0] for r in row] for row in runs]),
        source_nodes=tuple(tuple(r[1] for r in row) for row in runs), time=t_end,
        crossing_times=cross, initial_temperature=T0, source_temperature=Ts,
        stop_fraction=float(stop_fraction), threshold_fraction=float(threshold_fraction),
        peak_temperature=peak, thresholds=thr, haz=tuple(hazs), maps=tuple(maps), conductivity=kt,
        temperatures=finals, history_times=tuple(tuple(r[2] for r in row) for row in runs),
        history_peak=tuple(tuple(r[3] for r in row) for row in runs), network=net, tiles=tiles)


def heat_regions_table(result: HeatRegionsResult) -> dict:
    """Per-region numbers of a :class:`HeatRegionsResult` as equal-length columns.

    Returns
    -------
    dict of str to ndarray
        One row per region, means over its sources with ``*_std`` their
        standard deviation (0 for one source): ``region``;
        ``peak_temperature_C``, ``peak_temperature_std`` (C);
        ``crossing_time`` (s); ``threshold_C`` (C); ``roundness``,
        ``roundness_std``; ``orientation_deg`` (mean elongation);
        ``major_axis``, ``minor_axis`` (m); ``k_max``, ``k_min`` (in-plane
        principal conductivities, W/(m K)); ``k_orientation_deg``;
        ``k_roundness`` (``sqrt(k_min / k_max)``); ``fabric_orientation_deg``;
        ``fabric_ratio``; ``n_source`` (heated particles, mean);
        ``n_runs`` (sources per region).

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct.core import Box, Frame, Units
    >>> g = np.stack(np.meshgrid(np.arange(30), np.arange(12), np.arange(3), indexing="ij"), -1).reshape(-1, 3)
    >>> f = Frame((g + 0.5) * 20.0, np.full(len(g), 10.5), box=Box([0, 0, 0], [600, 240, 60]),
    ...           units=Units("micro"))
    >>> t = heat_regions_table(heat_regions(f, n_regions=2, source_diameter=45e-6))
    >>> t["region"].tolist(), np.round(t["k_roundness"], 6).tolist()
    (['start', 'end'], [1.0, 1.0])
    """
    ks = [np.linalg.eigvalsh(k.tensor[:2, :2]) for k in result.conductivity]
    f = lambda name: np.array([[getattr(h, name) for h in row] for row in result.haz],  # noqa: E731
                              dtype=np.float64).reshape(len(result.names), -1)
    peak = np.asarray(result.peak_temperature, dtype=np.float64).reshape(len(result.names), -1) - 273.15
    rnd = f("roundness")
    return {
        "region": np.array(result.names, dtype=str),
        "peak_temperature_C": peak.mean(axis=1),
        "peak_temperature_std": peak.std(axis=1),
        "crossing_time": np.asarray(result.crossing_times, dtype=np.float64).reshape(peak.shape).mean(axis=1),
        "threshold_C": np.asarray(result.thresholds).reshape(peak.shape).mean(axis=1) - 273.15,
        "roundness": rnd.mean(axis=1),
        "roundness_std": rnd.std(axis=1),
        "orientation_deg": np.asarray(result.mean_orientation_deg, dtype=np.float64).reshape(-1),
        "major_axis": f("major_axis").mean(axis=1),
        "minor_axis": f("minor_axis").mean(axis=1),
        "k_max": np.array([w[1] for w in ks], dtype=np.float64),
        "k_min": np.array([w[0] for w in ks], dtype=np.float64),
        "k_orientation_deg": result.conductivity_orientation_deg,
        "k_roundness": result.conductivity_roundness,
        "fabric_orientation_deg": result.fabric_orientation_deg,
        "fabric_ratio": result.fabric_ratio,
        "n_source": np.array([np.mean([len(n) for n in row]) for row in result.source_nodes],
                             dtype=np.float64).reshape(-1),
        "n_runs": np.full(len(result.names), peak.shape[1], dtype=np.int64),
    }
