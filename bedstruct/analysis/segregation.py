"""Size segregation: the heap in front of the blade vs the deposited bed vs the
initial pile, PSD along the bed, and a segregation index.

Sizes are diameters in the frame's length unit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.frame import _as_frame
from .psd import PSDResult, particle_size_distribution

__all__ = ["PSDComparison", "compare_psd", "wasserstein_psd", "segregation_index",
           "SegregationResult", "segregation", "heap_mask"]


def wasserstein_psd(a: PSDResult, b: PSDResult) -> float:
    """Wasserstein-1 (earth mover's) distance between two PSDs (length).

    Uses the particles' diameters with each PSD's weighting, i.e. the area
    between the two weighted cumulative distributions.

    Examples
    --------
    >>> from bedstruct.analysis import particle_size_distribution as psd
    >>> wasserstein_psd(psd(np.array([1.0, 1.0]), weighting="number"),
    ...                 psd(np.array([1.5, 1.5]), weighting="number"))
    1.0
    """
    from scipy import stats
    if a.weighting != b.weighting:
        raise ValueError(f"PSDs must share a weighting; got {a.weighting!r} and {b.weighting!r}")
    if a.n_particles == 0 or b.n_particles == 0:
        return float("nan")
    return float(stats.wasserstein_distance(a.diameters, b.diameters, a.weights, b.weights))


@dataclass(frozen=True)
class PSDComparison:
    """How a PSD differs from a reference (``other - reference``, length).

    Attributes
    ----------
    d10_shift, d50_shift, d90_shift : float
    relative_d50_shift : float
        ``d50_shift / reference.d50``.
    wasserstein : float
        :func:`wasserstein_psd` between the two.
    """

    d10_shift: float
    d50_shift: float
    d90_shift: float
    relative_d50_shift: float
    wasserstein: float


def compare_psd(reference: PSDResult, other: PSDResult) -> PSDComparison:
    """Shifts of D10/D50/D90 and the Wasserstein distance of ``other`` from ``reference``.

    Examples
    --------
    >>> from bedstruct.analysis import particle_size_distribution as psd
    >>> c = compare_psd(psd(np.array([1.0, 2.0])), psd(np.array([1.5, 2.5])))
    >>> round(c.relative_d50_shift, 3) > 0
    True
    """
    return PSDComparison(other.d10 - reference.d10, other.d50 - reference.d50,
                         other.d90 - reference.d90, (other.d50 - reference.d50) / reference.d50,
                         wasserstein_psd(reference, other))


def segregation_index(frame, lower=None, upper=None, *, n_windows=(6, 1, 1),
                      weighting: str = "volume", bounds=None, min_particles: int = 10) -> float:
    """Spread of the local mean size: relative standard deviation over windows.

    Parameters
    ----------
    frame : Frame
    lower, upper : (K, 3) array_like of float, length, optional
        Explicit windows (e.g. from :func:`bedstruct.analysis.bed_windows`);
        particles count in a window by centre. Default: a regular grid of
        ``n_windows`` over ``bounds``.
    n_windows : int or tuple of 3 int, optional
        Grid windows along x, y, z of the bed region (an int splits x only).
        Default 6 along the spreading direction.
    weighting : {"volume", "number"}, optional
        Mean diameter per window: number mean or D[4,3] (default volume).
    bounds : pair of (3,) array_like, optional
        Region of the grid (default :func:`bedstruct.analysis.bed_bounds`).
    min_particles : int, optional
        Windows with fewer particles are ignored.

    Returns
    -------
    float
        :math:`S = \\sigma_w(\\bar d_k) / \\mu_w(\\bar d_k)`, the coefficient of
        variation of the windows' mean diameters :math:`\\bar d_k`, weighted by
        their particle counts (0 for a perfectly mixed bed; NaN with fewer
        than 2 usable windows).

    Examples
    --------
    >>> from bedstruct import Frame
    >>> x = np.linspace(0.5, 9.5, 200)
    >>> mixed = Frame(np.c_[x, np.full(200, 1.0), np.full(200, 1.0)],
    ...               np.tile([0.2, 0.4], 100), box=([0, 0, 0], [10, 2, 2]))
    >>> graded = Frame(mixed.positions, np.where(x < 5, 0.2, 0.4), box=mixed.box)
    >>> segregation_index(mixed, n_windows=2) < 0.01 < segregation_index(graded, n_windows=2)
    True
    >>> round(segregation_index(graded, [[0, 0, 0], [5, 0, 0]], [[5, 2, 2], [10, 2, 2]]), 3)
    0.333
    """
    from .packing import bed_bounds
    frame = _as_frame(frame)
    if weighting not in ("volume", "number"):
        raise ValueError(f"`weighting` must be 'number' or 'volume'; got {weighting!r}")
    pos = frame.box.wrap(frame.positions)
    d = 2.0 * frame.radii
    w = d ** 3 if weighting == "volume" else np.ones_like(d)
    if lower is not None or upper is not None:
        lo = np.atleast_2d(np.asarray(lower, dtype=np.float64))
        hi = np.atleast_2d(np.asarray(upper, dtype=np.float64))
        if lo.shape != hi.shape or lo.shape[1:] != (3,):
            raise ValueError(f"`lower` and `upper` must both have shape (K, 3); got {lo.shape}, {hi.shape}")
        cnt = np.zeros(lo.shape[0])
        sw = np.zeros(lo.shape[0])
        swd = np.zeros(lo.shape[0])
        for k in range(lo.shape[0]):
            inside = np.all((pos >= lo[k]) & (pos < hi[k]), axis=1)
            cnt[k] = inside.sum()
            sw[k] = w[inside].sum()
            swd[k] = (w * d)[inside].sum()
    else:
        shape = (int(n_windows), 1, 1) if np.ndim(n_windows) == 0 else tuple(int(v) for v in n_windows)
        blo, bhi = bed_bounds(frame) if bounds is None else (np.asarray(bounds[0], float),
                                                           np.asarray(bounds[1], float))
        idx = []
        for k in range(3):
            e = np.linspace(blo[k], bhi[k], shape[k] + 1)
            idx.append(np.clip(np.searchsorted(e, pos[:, k], side="right") - 1, 0, shape[k] - 1))
        inside = np.all((pos >= blo) & (pos <= bhi), axis=1)
        lin = np.ravel_multi_index(tuple(i[inside] for i in idx), shape)
        m = int(np.prod(shape))
        cnt = np.bincount(lin, minlength=m).astype(np.float64)
        sw = np.bincount(lin, weights=w[inside], minlength=m)
        swd = np.bincount(lin, weights=(w * d)[inside], minlength=m)
    ok = cnt >= min_particles
    if ok.sum() < 2:
        return float("nan")
    local = swd[ok] / sw[ok]
    mean = np.average(local, weights=cnt[ok])
    var = np.average((local - mean) ** 2, weights=cnt[ok])
    return float(np.sqrt(var) / mean)


def heap_mask(frame, blade_position: float, *, direction: int = 1, axis: int = 0,
              above: float | None = None, vertical: int = 2) -> np.ndarray:
    """Particles ahead of the blade (the heap being pushed), optionally above a height.

    Parameters
    ----------
    frame : Frame
    blade_position : float, length
        Coordinate of the blade's front face along ``axis``.
    direction : {1, -1}, optional
        Direction of travel of the blade.
    axis : int, optional
        Spreading direction (default 0).
    above : float, length, optional
        Only particles whose centres lie above this height (e.g. the top of
        the previous layer) count.
    vertical : int, optional
        Vertical axis (default 2).

    Returns
    -------
    (N,) ndarray of bool

    Examples
    --------
    >>> from bedstruct import Frame
    >>> f = Frame([[1, 0, 0], [3, 0, 0]], [0.5, 0.5], box=([0, -1, -1], [4, 1, 1]))
    >>> heap_mask(f, 2.0).tolist()
    [False, True]
    """
    frame = _as_frame(frame)
    if direction not in (1, -1):
        raise ValueError(f"`direction` must be 1 or -1; got {direction!r}")
    x = frame.positions[:, axis]
    mask = (x - float(blade_position)) * direction > 0
    if above is not None:
        mask &= frame.positions[:, vertical] > float(above)
    return mask


@dataclass(frozen=True)
class SegregationResult:
    """PSDs of heap, bed and initial pile, PSD along the bed, and indices.

    Attributes
    ----------
    heap, bed : PSDResult
        Particles ahead of / behind the blade.
    initial : PSDResult or None
        The initial pile, when given.
    heap_vs_bed : PSDComparison
        ``heap`` relative to ``bed``.
    bed_vs_initial, heap_vs_initial : PSDComparison or None
    along_bed : list of PSDResult
        PSD of each window along the deposited bed (start to end).
    along_edges : (K + 1,) ndarray of float, length
        Window edges along the spreading axis.
    along_d50 : (K,) ndarray of float, length
    index : float
        :func:`segregation_index` of the deposited bed over the same windows.
    """

    heap: PSDResult
    bed: PSDResult
    initial: PSDResult | None
    heap_vs_bed: PSDComparison
    bed_vs_initial: PSDComparison | None
    heap_vs_initial: PSDComparison | None
    along_bed: list
    along_edges: np.ndarray
    along_d50: np.ndarray
    index: float


def segregation(frame, blade_position: float, *, direction: int = 1, axis: int = 0,
                initial=None, n_windows: int = 3, weighting: str = "volume", bins=30,
                above: float | None = None) -> SegregationResult:
    """Compare the heap in front of the blade with the deposited bed (and the initial pile).

    Parameters
    ----------
    frame : Frame
        A frame during or after spreading.
    blade_position : float, length
        Blade front coordinate along ``axis`` (use ``+inf``/``-inf`` after the
        blade has left: everything is bed).
    direction : {1, -1}, optional
        Direction of travel of the blade.
    axis : int, optional
        Spreading direction (default 0).
    initial : Frame or (N,) array_like of radii, optional
        The pile before spreading.
    n_windows : int, optional
        Windows along the deposited bed (default 3: start, centre, end).
    weighting : {"volume", "number"}, optional
    bins : int or array_like, optional
        Bins of all PSDs (shared edges are derived from all diameters when
        an int is given, so PSDs are comparable).
    above : float, length, optional
        Passed to :func:`heap_mask`.

    Returns
    -------
    SegregationResult

    .. versionadded:: 0.1

    Examples
    --------
    >>> from bedstruct import Frame
    >>> rng = np.random.default_rng(0)
    >>> x = rng.uniform(0, 10, 400)
    >>> r = np.where(x > 8, 0.3, 0.2)                 # coarse particles in the heap
    >>> f = Frame(np.c_[x, rng.uniform(0, 2, 400), rng.uniform(0, 1, 400)], r,
    ...           box=([0, 0, 0], [10, 2, 1]))
    >>> s = segregation(f, 8.0)
    >>> round(s.heap_vs_bed.d50_shift, 3)
    0.2
    """
    from .packing import bed_bounds
    frame = _as_frame(frame)
    if weighting not in ("volume", "number"):
        raise ValueError(f"`weighting` must be 'number' or 'volume'; got {weighting!r}")
    heap = heap_mask(frame, blade_position, direction=direction, axis=axis, above=above)
    bed = ~heap
    init_r = None
    if initial is not None:
        init_r = np.asarray(initial.radii if hasattr(initial, "radii") else initial, dtype=np.float64)
    if np.ndim(bins) == 0:
        alld = 2.0 * np.concatenate([frame.radii] + ([init_r] if init_r is not None else []))
        edges = np.linspace(alld.min(), alld.max() * (1 + 1e-12), int(bins) + 1)
    else:
        edges = np.asarray(bins, dtype=np.float64)
    kw = dict(weighting=weighting, bins=edges)
    p_heap = particle_size_distribution(frame.radii[heap], **kw)
    p_bed = particle_size_distribution(frame.radii[bed], **kw)
    p_init = particle_size_distribution(init_r, **kw) if init_r is not None else None
    # windows along the deposited bed
    bedframe = frame.select(bed)
    if bedframe.n_particles:
        lo, hi = bed_bounds(bedframe)
    else:
        lo, hi = np.zeros(3), np.ones(3)
    e = np.linspace(lo[axis], hi[axis], int(n_windows) + 1)
    x = bedframe.box.wrap(bedframe.positions)[:, axis] if bedframe.n_particles else np.zeros(0)
    along = []
    for k in range(int(n_windows)):
        sel = (x >= e[k]) & ((x < e[k + 1]) if k < n_windows - 1 else (x <= e[k + 1]))
        along.append(particle_size_distribution(bedframe.radii[sel], **kw))
    shape = [1, 1, 1]
    shape[axis] = int(n_windows)
    index = (segregation_index(bedframe, n_windows=tuple(shape), weighting=weighting, min_particles=1)
             if bedframe.n_particles else float("nan"))
    return SegregationResult(
        heap=p_heap, bed=p_bed, initial=p_init, heap_vs_bed=compare_psd(p_bed, p_heap),
        bed_vs_initial=compare_psd(p_init, p_bed) if p_init is not None else None,
        heap_vs_initial=compare_psd(p_init, p_heap) if p_init is not None else None,
        along_bed=along, along_edges=e, along_d50=np.array([p.d50 for p in along]), index=index)

