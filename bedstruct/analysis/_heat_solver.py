"""Transient conduction on a thermal network: implicit, adaptive, energy-accounted."""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import BedstructWarning
from . import _heat_kernels as _k
from ._heat_network import ThermalNetwork

__all__ = ["HemisphereSource", "EnergyRecord", "HeatResult", "conduct_heat", "source_nodes"]

log = logging.getLogger(__name__)

_N_CHUNKS = 64          # fixed reduction chunks: results independent of thread count
_DIRECT_MAX = 2_000     # "auto" uses a sparse LU up to this many free nodes (CG is faster above)


@dataclass(frozen=True)
class HemisphereSource:
    """A heat source: a hemisphere on the bed surface, held hot or heating.

    Parameters
    ----------
    center : (2,) or (3,) array_like of float, m
        Centre of the hemisphere. With two values ``(x, y)`` the centre is
        put on the bed surface there: at the highest sphere top among the
        particles whose centres lie within the source radius horizontally.
    diameter : float, m
        Diameter of the hemisphere (default 500 um, as in the seed report).
    temperature : float, K
        Temperature the particles inside are held at (default 1573.15 K =
        1300 C, the seed's value). Ignored when ``power`` is given.
    duration : float or None, s
        How long the source acts. ``None``: a pulse for a temperature source
        (the particles start at ``temperature`` and are released at once, as
        in the seed) and the whole run for a power source.
    power : float, optional, W
        Constant heating power spread over the particles inside in
        proportion to their heat capacity (a constant-flux source) instead of
        a held temperature.

    Notes
    -----
    A particle is inside when its centre lies in the half ball of radius
    ``diameter / 2`` below the centre (periodic images are not considered).

    .. versionadded:: 0.1

    Examples
    --------
    >>> HemisphereSource((1e-3, 1e-3)).diameter
    0.0005
    """

    center: tuple
    diameter: float = 500e-6
    temperature: float = 1573.15
    duration: float | None = None
    power: float | None = None

    def __post_init__(self):
        c = tuple(float(v) for v in np.asarray(self.center, dtype=np.float64).reshape(-1))
        if len(c) not in (2, 3) or not all(math.isfinite(v) for v in c):
            raise ValueError(f"`center` must be (x, y) or (x, y, z) in metres; got {self.center!r}")
        object.__setattr__(self, "center", c)
        if not (self.diameter > 0 and math.isfinite(self.diameter)):
            raise ValueError(f"`diameter` must be positive (m); got {self.diameter!r}")
        if self.power is None and not (self.temperature > 0 and math.isfinite(self.temperature)):
            raise ValueError(f"`temperature` must be positive (K); got {self.temperature!r}")
        if self.duration is not None and not (self.duration >= 0):
            raise ValueError(f"`duration` must be >= 0 (s) or None; got {self.duration!r}")
        if self.power is not None and not math.isfinite(self.power):
            raise ValueError(f"`power` must be finite (W); got {self.power!r}")


def source_nodes(network: ThermalNetwork, source: HemisphereSource) -> tuple[np.ndarray, np.ndarray]:
    """Particles inside a hemisphere source and the resolved 3-D centre.

    Returns
    -------
    nodes : ndarray of int
        Row indices of the particles inside.
    center : (3,) ndarray, m

    .. versionadded:: 0.1

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct.core import Frame, Contacts, Units
    >>> from bedstruct.analysis.heat import thermal_network
    >>> f = Frame([[0, 0, 0.5], [3, 0, 0.5]], [0.5, 0.5], box=[10, 10, 10])
    >>> net = thermal_network(f, Contacts([], [], np.zeros((0, 3)), [], [], n_particles=2))
    >>> nodes, c = source_nodes(net, HemisphereSource((0.0, 0.0), diameter=2.0))
    >>> nodes.tolist(), c.tolist()
    ([0], [0.0, 0.0, 1.0])
    """
    R = 0.5 * source.diameter
    pos = network.positions
    if len(source.center) == 2:
        horiz = np.hypot(pos[:, 0] - source.center[0], pos[:, 1] - source.center[1])
        under = horiz <= R
        if not np.any(under):
            raise ValueError(f"no particle lies under the source at {source.center} m "
                             f"(radius {R:g} m)")
        cz = float(np.max(pos[under, 2] + network.radii[under]))
        center = np.array([source.center[0], source.center[1], cz])
    else:
        center = np.array(source.center)
    d = np.linalg.norm(pos - center, axis=1)
    nodes = np.flatnonzero((d <= R) & (pos[:, 2] <= center[2]))
    if nodes.size == 0:
        raise ValueError(f"the source at {center.tolist()} m (radius {R:g} m) contains no particle "
                         f"centre")
    return nodes, center


@dataclass(frozen=True)
class EnergyRecord:
    """Energy account at the recorded times (J).

    ``stored = sum C_i (T_i - T_i(initial))``; ``source`` and ``boundary``
    are the cumulative energies that entered through the source (including
    the initial heating of the source particles) and through fixed
    temperatures (the plate and fixed particles); ``imbalance = stored -
    source - boundary`` is zero up to round-off.
    """

    stored: np.ndarray
    source: np.ndarray
    boundary: np.ndarray
    imbalance: np.ndarray
    relative_error: float


@dataclass(frozen=True, eq=False)
class HeatResult:
    """Transient temperatures of a thermal network.

    Attributes
    ----------
    times : (n_times,) ndarray, s
        Recorded times.
    temperatures : (n_times, N) ndarray, K
        Particle temperatures at ``times``.
    final_temperature : (N,) ndarray, K
        Temperatures at ``t_end``.
    peak_temperature : (N,) ndarray, K
        Largest temperature each particle reached (over all accepted steps).
    energy : EnergyRecord
    source_nodes : ndarray of int
        Particles inside the source.
    source_center : (3,) ndarray or None, m
    t_end : float, s
    n_steps, n_rejected, n_solves, n_iterations : int
        Accepted and rejected steps, linear solves, and CG iterations (0
        with the direct solver).
    solver : str
        ``"direct"`` or ``"cg"``.
    network : ThermalNetwork
    """

    times: np.ndarray
    temperatures: np.ndarray
    final_temperature: np.ndarray
    peak_temperature: np.ndarray
    energy: EnergyRecord
    source_nodes: np.ndarray
    source_center: np.ndarray | None
    t_end: float
    n_steps: int
    n_rejected: int
    n_solves: int
    n_iterations: int
    solver: str
    network: ThermalNetwork

    @property
    def max_temperature(self) -> np.ndarray:
        """Hottest particle temperature at each recorded time (K)."""
        return self.temperatures.max(axis=1) if self.temperatures.shape[1] else np.zeros(0)

    @property
    def units(self) -> str:
        """The unit conversion applied when the network was built."""
        return self.network.units

    def __repr__(self) -> str:
        return (f"HeatResult(n_particles={self.final_temperature.shape[0]}, t_end={self.t_end:g} s, "
                f"n_steps={self.n_steps}, solver={self.solver!r})")


class _Phase:
    """The linear system of one interval with a fixed set of held nodes."""

    def __init__(self, net: ThermalNetwork, held: np.ndarray, held_src: np.ndarray, T_held: np.ndarray,
                 q: np.ndarray, plate_g: np.ndarray, T_plate: float, solver: str):
        n = net.n_particles
        self.free = np.flatnonzero(~held)
        w = net.weights
        nf = self.free.shape[0]
        if nf == n:            # nothing held: no slicing of the (possibly huge) matrix
            self.W = w
            self.b_src = self.g_src = self.b_bnd = np.zeros(n)
            self.g_bnd = plate_g.copy()
            self.b_bnd = plate_g * T_plate
        else:
            wf = w[self.free]
            self.W = wf[:, self.free].tocsr()
            self.W.sort_indices()
            cols_src = np.flatnonzero(held & held_src)
            cols_bnd = np.flatnonzero(held & ~held_src)
            ws = wf[:, cols_src]
            wb = wf[:, cols_bnd]
            self.b_src = ws @ T_held[cols_src]
            self.g_src = np.asarray(ws.sum(axis=1)).ravel()
            self.b_bnd = wb @ T_held[cols_bnd] + plate_g[self.free] * T_plate
            self.g_bnd = np.asarray(wb.sum(axis=1)).ravel() + plate_g[self.free]
        self.d = net.weight_sums[self.free] + plate_g[self.free]
        self.C = net.capacity[self.free]
        self.q = q[self.free]
        self.rhs_const = self.b_src + self.b_bnd + self.q
        # scalar parts of the energy account, summed once
        self.sum_C = float(self.C.sum())
        self.sum_a1 = float((self.g_src + self.g_bnd).sum())   # A @ 1 = C/h + g_src + g_bnd
        self.sum_b_src = float(self.b_src.sum()) + float(self.q.sum())
        self.sum_b_bnd = float(self.b_bnd.sum())
        self.has_src = bool(np.any(self.g_src))
        self.has_bnd = bool(np.any(self.g_bnd))
        self.solver = solver if solver != "auto" else ("direct" if nf <= _DIRECT_MAX else "cg")
        self._lu: dict = {}
        self.bounds = _k.chunk_bounds(nf, _N_CHUNKS)
        self.diag = np.empty(nf)
        self.rhs = np.empty(nf)
        if self.solver == "cg":
            self.indptr = np.ascontiguousarray(self.W.indptr, dtype=np.int64)
            self.indices = np.ascontiguousarray(self.W.indices, dtype=np.int32 if nf < 2**31 else np.int64)
            self.wrow = np.ascontiguousarray(np.asarray(self.W.sum(axis=1)).ravel())
            self.out = np.zeros(1)
            self.data = np.ascontiguousarray(self.W.data, dtype=np.float64)
            self.work = [np.empty(nf) for _ in range(4)]
            self.partial = np.empty(_N_CHUNKS)
            self.partial_max = np.empty(_N_CHUNKS)

    def solve(self, x_old, h, guess, cg_tol, maxiter):
        """One backward-Euler step of length h; returns (x_new, e_src, e_bnd, iterations)."""
        it = 0
        if self.solver == "direct":
            ch = self.C / h
            diag = ch + self.d
            rhs = ch * x_old + self.rhs_const
            lu = self._lu.get(h)
            if lu is None:
                import scipy.sparse as sp
                from scipy.sparse.linalg import splu
                A = (sp.diags(diag) - self.W).tocsc()
                if len(self._lu) >= 4:
                    self._lu.clear()
                lu = self._lu[h] = (splu(A), A)
            x = lu[0].solve(rhs)
            r_sum = float((rhs - lu[1] @ x).sum())
        else:
            diag, rhs = self.diag, self.rhs
            _k.be_system(self.C, self.d, x_old, 1.0 / h, self.rhs_const, self.bounds, diag, rhs)
            x = np.array(guess, dtype=np.float64, copy=True)
            r, z, p, qv = self.work
            it = _k.pcg_solve(self.indptr, self.indices, self.data, diag, self.wrow, rhs, x, cg_tol,
                              maxiter, self.bounds, r, z, p, qv, self.partial, self.partial_max,
                              self.out)
            r_sum = float(self.out[0])
            if it > maxiter:
                raise RuntimeError(f"conjugate gradients did not converge in {maxiter} iterations "
                                   f"(step {h:g} s); raise cg_maxiter or loosen cg_tol")
        # make the step conserve energy exactly: remove the summed residual with a uniform shift
        a1 = self.sum_C / h + self.sum_a1
        if a1 > 0:
            x += r_sum / a1
        e_src = h * (self.sum_b_src - (float(np.dot(self.g_src, x)) if self.has_src else 0.0))
        e_bnd = h * (self.sum_b_bnd - (float(np.dot(self.g_bnd, x)) if self.has_bnd else 0.0))
        return x, e_src, e_bnd, it


def conduct_heat(network: ThermalNetwork, *, t_end: float, source: HemisphereSource | None = None,
                 initial_temperature=293.15, plate_temperature: float | None = None,
                 fixed_temperature=None, times=None, atol: float | None = None,
                 dt_initial: float | None = None, extrapolate: bool = True, solver: str = "auto",
                 cg_tol: float | None = None, cg_maxiter: int = 10_000, max_steps: int = 100_000,
                 progress: bool = False) -> HeatResult:
    """Transient heat conduction through the contact network.

    Solves ``C_i dT_i/dt = sum_j G_ij (T_j - T_i) + G_p,i (T_p - T_i) + q_i``
    with backward Euler steps, step doubling for the error estimate and
    adaptive step size (optionally with Richardson extrapolation of the two
    half steps, second order and still L-stable).

    Parameters
    ----------
    network : ThermalNetwork
        From :func:`thermal_network` (SI).
    t_end : float, s
        End time.
    source : HemisphereSource, optional
        Heat source (held temperature or constant power).
    initial_temperature : float or (N,) array_like, K
        Temperature at t = 0 before the source acts (default 293.15 K).
    plate_temperature : float, optional, K
        Temperature of the build plate; ``None`` (default) insulates it.
    fixed_temperature : (N,) array_like of float, optional, K
        Particles held at a temperature (NaN for free particles).
    times : array_like of float, optional, s
        Times to record temperatures at (within [0, t_end]); default 11
        evenly spaced times.
    atol : float, optional, K
        Largest accepted local error per step (max norm of the step-doubling
        estimate); default 1e-3 of the temperature span of the problem.
    dt_initial : float, optional, s
        First trial step; default a tenth of the median ``C_i / sum_j G_ij``.
    extrapolate : bool
        Keep ``2 T_half - T_full`` (second order) rather than ``T_half``
        (first order, monotone). Default True.
    solver : {"auto", "direct", "cg"}
        Sparse LU (reused for equal steps) or Jacobi-preconditioned
        conjugate gradients (numba, parallel); "auto" takes the LU up to
        2,000 free particles.
    cg_tol : float, optional, K
        CG stop when ``max |r_i / A_ii|`` falls below it; default
        ``1e-3 * atol``.
    cg_maxiter, max_steps : int
        Limits; exceeding them raises RuntimeError.
    progress : bool
        Show a tqdm progress bar over simulated time.

    Returns
    -------
    HeatResult

    Notes
    -----
    Each linear solve is followed by a uniform shift of the free
    temperatures that makes the summed residual exactly zero, so
    ``sum C_i dT_i`` equals the energy through the source and the
    boundaries to round-off whatever the CG tolerance (checked in the tests
    to 1e-10 relative with insulated boundaries).

    .. versionadded:: 0.1

    Examples
    --------
    Two equal spheres joined by G relax as ``exp(-2 G t / C)``:

    >>> import numpy as np
    >>> from bedstruct.core import Frame, Contacts, Units
    >>> from bedstruct.analysis.heat import thermal_network
    >>> f = Frame([[0, 0, 0], [19.6, 0, 0]], [10.0, 10.0], box=[50, 50, 50], units=Units("micro"))
    >>> c = Contacts(i=[0], j=[1], branch=[[19.6, 0, 0]], radii_i=[10.0], radii_j=[10.0])
    >>> net = thermal_network(f, c)
    >>> res = conduct_heat(net, t_end=1e-3, initial_temperature=[400.0, 300.0], atol=1e-4)
    >>> dT = res.final_temperature[0] - res.final_temperature[1]
    >>> expected = 100 * np.exp(-2 * net.conductance[0] * 1e-3 / net.capacity[0])
    >>> bool(abs(dT - expected) < 1e-3), res.energy.relative_error < 1e-10
    (True, True)
    """
    if not isinstance(network, ThermalNetwork):
        raise TypeError(f"`network` must be a ThermalNetwork (see thermal_network()); got "
                        f"{type(network).__name__}")
    t_end = float(t_end)
    if not (t_end > 0 and math.isfinite(t_end)):
        raise ValueError(f"`t_end` must be positive (s); got {t_end!r}")
    if solver not in ("auto", "direct", "cg"):
        raise ValueError(f"`solver` must be 'auto', 'direct' or 'cg'; got {solver!r}")
    net = network
    n = net.n_particles
    T_init = np.asarray(initial_temperature, dtype=np.float64)
    T_init = np.full(n, float(T_init)) if T_init.ndim == 0 else np.array(T_init, copy=True)
    if T_init.shape != (n,):
        raise ValueError(f"`initial_temperature` must be a scalar or shape (N,) (N={n}); got "
                         f"{T_init.shape}")
    if not np.all(np.isfinite(T_init)) or np.any(T_init <= 0):
        raise ValueError("`initial_temperature` must be finite and positive (K)")
    fixed = np.zeros(n, dtype=bool)
    T_fixed = np.full(n, np.nan)
    if fixed_temperature is not None:
        T_fixed = np.asarray(fixed_temperature, dtype=np.float64)
        if T_fixed.shape != (n,):
            raise ValueError(f"`fixed_temperature` must have shape (N,) (N={n}), NaN for free "
                             f"particles; got {T_fixed.shape}")
        fixed = np.isfinite(T_fixed)
    if plate_temperature is not None:
        plate_temperature = float(plate_temperature)
        if not plate_temperature > 0:
            raise ValueError(f"`plate_temperature` must be positive (K); got {plate_temperature!r}")
        plate_g = net.plate_conductance
        T_plate = plate_temperature
        if not np.any(plate_g > 0):
            warnings.warn(f"plate_temperature={plate_temperature:g} K is given but no particle "
                          f"touches the plate at z = {net.plate_z:g} m (no overlap), so the plate "
                          f"exchanges no heat", BedstructWarning, stacklevel=2)
    else:
        plate_g = np.zeros(n)
        T_plate = 0.0

    # ---- source
    src = np.zeros(0, dtype=np.int64)
    center = None
    q_on = np.zeros(n)
    src_hold = False
    t_on = 0.0
    if source is not None:
        if not isinstance(source, HemisphereSource):
            raise TypeError(f"`source` must be a HemisphereSource; got {type(source).__name__}")
        src, center = source_nodes(net, source)
        src = src[~fixed[src]]
        if source.power is not None:
            t_on = t_end if source.duration is None else min(float(source.duration), t_end)
            cap = net.capacity[src]
            q_on[src] = source.power * cap / cap.sum()
        else:
            t_on = 0.0 if source.duration is None else min(float(source.duration), t_end)
            src_hold = True

    # ---- initial state
    T = T_init.copy()
    e_source = 0.0
    e_bound = 0.0
    if src_hold:
        T[src] = source.temperature
        e_source += float(net.capacity[src] @ (T[src] - T_init[src]))
    T[fixed] = T_fixed[fixed]
    e_bound += float(net.capacity[fixed] @ (T[fixed] - T_init[fixed]))

    span_vals = [T.max(), T.min(), T_init.max(), T_init.min()]
    if plate_temperature is not None:
        span_vals.append(plate_temperature)
    if source is not None and source.power is None:
        span_vals.append(source.temperature)
    span = max(span_vals) - min(span_vals)
    if atol is None:
        atol = 1e-3 * span if span > 0 else 1e-3
        if source is not None and source.power is not None and span == 0:
            atol = 1e-2
    atol = float(atol)
    if not atol > 0:
        raise ValueError(f"`atol` must be positive (K); got {atol!r}")
    if cg_tol is None:
        cg_tol = 1e-3 * atol

    if times is None:
        times = np.linspace(0.0, t_end, 11)
    times = np.unique(np.asarray(times, dtype=np.float64).reshape(-1))
    if times.size and (times[0] < 0 or times[-1] > t_end * (1 + 1e-12)):
        raise ValueError(f"`times` must lie in [0, t_end={t_end:g}] s; got [{times[0]:g}, {times[-1]:g}]")

    # ---- phases: (t0, t1, held mask, held_src mask, q)
    phases = []
    if t_on > 0:
        held = fixed.copy()
        held_src = np.zeros(n, dtype=bool)
        if src_hold:
            held[src] = True
            held_src[src] = True
        phases.append((0.0, t_on, held, held_src, q_on))
    if t_on < t_end:
        phases.append((t_on, t_end, fixed.copy(), np.zeros(n, dtype=bool), np.zeros(n)))

    with np.errstate(divide="ignore", invalid="ignore"):
        tau = net.capacity / net.weight_sums
    tau = tau[np.isfinite(tau)]
    if dt_initial is None:
        dt = 0.1 * float(np.median(tau)) if tau.size else t_end / 10
    else:
        dt = float(dt_initial)
    dt = min(max(dt, 1e-12 * t_end), t_end)

    rec_T: list[np.ndarray] = []
    rec_t: list[float] = []
    rec_e: list[tuple[float, float, float]] = []
    peak = T.copy()
    stats = dict(steps=0, rejected=0, solves=0, iters=0)

    def stored():
        return float(net.capacity @ (T - T_init))

    def record(t):
        rec_t.append(t)
        rec_T.append(T.copy())
        rec_e.append((stored(), e_source, e_bound))

    k_rec = 0
    while k_rec < times.size and times[k_rec] <= 0.0:
        record(0.0)
        k_rec += 1

    bar = None
    if progress:
        from tqdm.auto import tqdm
        bar = tqdm(total=t_end, unit="s", desc="conduct_heat")
    t = 0.0
    used_solver = "direct"
    for (t0, t1, held, held_src, q) in phases:
        T_held = np.where(held, T, 0.0)
        ph = _Phase(net, held, held_src, T_held, q, plate_g, T_plate, solver)
        used_solver = ph.solver
        free = ph.free
        x = T[free].copy()
        peak_f = peak[free]
        scratch = np.empty_like(x)
        x_prev = None
        h_prev = None
        stops = [s for s in times[k_rec:] if t0 < s < t1] + [t1]
        while t < t1:
            next_stop = stops[0]
            h = min(dt, next_stop - t)
            if t + 1.05 * h >= next_stop:
                h = next_stop - t
            clipped = h < dt
            guess = x if (x_prev is None or h_prev is None) else x + (x - x_prev) * (h / h_prev)
            full, ef_s, ef_b, i1 = ph.solve(x, h, guess, cg_tol, cg_maxiter)
            half1, e1_s, e1_b, i2 = ph.solve(x, 0.5 * h, 0.5 * (x + full), cg_tol, cg_maxiter)
            half2, e2_s, e2_b, i3 = ph.solve(half1, 0.5 * h, full, cg_tol, cg_maxiter)
            stats["solves"] += 3
            stats["iters"] += i1 + i2 + i3
            err = float(np.max(np.abs(np.subtract(half2, full, out=scratch)))) if free.size else 0.0
            accept = err <= atol or h <= 1e-14 * max(t1, 1e-300)
            factor = 0.9 * math.sqrt(atol / err) if err > 0 else 4.0
            factor = min(4.0, max(0.2, factor))
            if accept:
                if extrapolate:
                    x_new = 2.0 * half2 - full
                    e_source += 2.0 * (e1_s + e2_s) - ef_s
                    e_bound += 2.0 * (e1_b + e2_b) - ef_b
                else:
                    x_new = half2
                    e_source += e1_s + e2_s
                    e_bound += e1_b + e2_b
                x_prev, h_prev = x, h
                x = x_new
                np.maximum(peak_f, x, out=peak_f)
                t_new = next_stop if h == next_stop - t else t + h
                if bar is not None:
                    bar.update(t_new - t)
                t = t_new
                stats["steps"] += 1
                if stats["steps"] > max_steps:
                    raise RuntimeError(f"more than max_steps={max_steps} steps before t_end; "
                                       f"raise max_steps or atol")
                if t >= next_stop:
                    stops.pop(0)
                    T[free] = x
                    while k_rec < times.size and times[k_rec] <= t * (1 + 1e-12):
                        record(float(times[k_rec]))
                        k_rec += 1
                dt = max(dt, h * factor) if clipped else h * factor
            else:
                stats["rejected"] += 1
                dt = h * min(factor, 0.5)
        T[free] = x
        peak[free] = peak_f
    if bar is not None:
        bar.close()

    rec_arr = np.array(rec_e, dtype=np.float64).reshape(-1, 3)
    final_e = (stored(), e_source, e_bound)
    all_e = np.vstack([rec_arr, np.array(final_e)[None]])
    imbalance = all_e[:, 0] - all_e[:, 1] - all_e[:, 2]
    scale = max(float(np.max(np.abs(all_e))) if all_e.size else 0.0,
                float(net.capacity @ np.abs(T_init - T_init.mean())) if n else 0.0)
    rel = float(np.max(np.abs(imbalance)) / scale) if scale > 0 else 0.0
    energy = EnergyRecord(stored=rec_arr[:, 0].copy(), source=rec_arr[:, 1].copy(),
                          boundary=rec_arr[:, 2].copy(), imbalance=imbalance[:-1].copy(),
                          relative_error=rel)
    log.debug("conduct_heat: %d steps (%d rejected), %d solves, %d CG iterations, energy error %.2e",
              stats["steps"], stats["rejected"], stats["solves"], stats["iters"], rel)
    temps = np.array(rec_T).reshape(len(rec_T), n)
    return HeatResult(times=np.array(rec_t), temperatures=temps, final_temperature=T,
                      peak_temperature=peak, energy=energy, source_nodes=src,
                      source_center=center, t_end=t_end, n_steps=stats["steps"],
                      n_rejected=stats["rejected"], n_solves=stats["solves"],
                      n_iterations=stats["iters"], solver=used_solver, network=net)
