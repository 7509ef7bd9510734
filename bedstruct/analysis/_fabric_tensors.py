"""Fabric tensors of a set of directions (:class:`FabricTensors`,
:func:`fabric_tensors`), the direction density they approximate on the sphere
and in a plane, and sampling directions from such a density.

Implementation module of :mod:`bedstruct.analysis.fabric` (import from there).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from . import _fabric_kernels as _k
from ._fabric_algebra import _DELTA, _readonly, _second_kind, _third_kind
from ._fabric_algebra import isotropic_rank4  # noqa: F401  (used by the doctests)

__all__ = ["FabricTensors", "fabric_tensors", "fabric_density", "projected_density",
           "sample_directions"]

log = logging.getLogger("bedstruct.analysis.fabric")  # the public module's logger, as before


# --------------------------------------------------------------------------- result
@dataclass(frozen=True)
class FabricTensors:
    """Fabric tensors of ranks 2 and 4 and kinds 1-3 of one set of directions.

    All tensors are dimensionless and fully symmetric. Build with
    :func:`fabric_tensors` (from directions) or :meth:`from_moments`.

    Attributes
    ----------
    N2, N4 : (3, 3), (3, 3, 3, 3) ndarray
        Moment tensors (first kind), weighted means of ``n n`` and ``n n n n``.
    F2, F4 : (3, 3), (3, 3, 3, 3) ndarray
        Fabric tensors of the second kind; ``F4 :: nnnn / (4 pi)`` is the
        rank-4 approximation of the density, ``F2 : nn / (4 pi)`` the rank-2 one.
    D2, D4 : (3, 3), (3, 3, 3, 3) ndarray
        Deviatoric tensors (third kind), traceless.
    n_contacts : int
        Number of directions used (rows of zero length excluded).
    total_weight : float
        Sum of the weights (``n_contacts`` when unweighted).
    eigenvalues : (3,) ndarray
        Eigenvalues of ``N2`` in descending order (they sum to 1).
    eigenvectors : (3, 3) ndarray
        Matching unit eigenvectors as columns.
    anisotropy : float
        :math:`a = \\sqrt{\\tfrac32 D_{ij} D_{ij}}`, the rank-2 anisotropy of
        Rothenburg & Bathurst / Ouadfel & Rothenburg (0 for isotropic; for
        ``f = (1 + a (3 (e.n)^2 - 1)/3 ... )`` style axisymmetric deviators
        ``D = a (3 e e - I) / 3`` it returns ``a``).
    anisotropy_rank4 : float
        :math:`\\sqrt{D_{ijkl} D_{ijkl}}`, the Frobenius norm of the rank-4
        deviator.

    Notes
    -----
    A finite set of directions is anisotropic by sampling alone: ``M``
    independent isotropic directions give :math:`E[a^2] = 225 / (4 M)` and
    :math:`E[a_4^2] = 2835 / (8 M)` (:attr:`anisotropy_noise`,
    :attr:`anisotropy_rank4_noise`), since :math:`a^2 = \\tfrac{45}{4} P_2/P_0`
    and :math:`a_4^2 = \\tfrac{315}{8} P_4/P_0` with :math:`E[P_l/P_0] = (2l+1)/M`
    (:func:`~bedstruct.analysis.harmonic_expansion`). An anisotropy within about
    twice its noise says nothing about the fabric.

    .. versionadded:: 0.1
    """

    N2: np.ndarray
    N4: np.ndarray
    F2: np.ndarray
    F4: np.ndarray
    D2: np.ndarray
    D4: np.ndarray
    n_contacts: int
    total_weight: float
    eigenvalues: np.ndarray = field(repr=False)
    eigenvectors: np.ndarray = field(repr=False)
    anisotropy: float
    anisotropy_rank4: float

    @classmethod
    def from_moments(cls, N2, N4, *, n_contacts: int = 0, total_weight: float | None = None
                     ) -> "FabricTensors":
        """Build every kind from the moment tensors ``N2`` (3, 3) and ``N4`` (3, 3, 3, 3).

        Examples
        --------
        >>> t = FabricTensors.from_moments(np.eye(3) / 3, isotropic_rank4() / 5)
        >>> np.allclose(t.F2, np.eye(3)), np.allclose(t.D2, 0), np.allclose(t.D4, 0)
        (True, True, True)
        """
        n2 = np.asarray(N2, dtype=np.float64)
        n4 = np.asarray(N4, dtype=np.float64)
        if n2.shape != (3, 3) or n4.shape != (3, 3, 3, 3):
            raise ValueError(f"`N2` must have shape (3, 3) and `N4` (3, 3, 3, 3); "
                             f"got {n2.shape} and {n4.shape}")
        f2, f4 = _second_kind(n2, n4)
        d2, d4 = _third_kind(n2, n4)
        w, v = np.linalg.eigh(0.5 * (n2 + n2.T))
        order = np.argsort(w)[::-1]
        w, v = w[order], v[:, order]
        # a deterministic sign: largest-magnitude component of each eigenvector positive
        idx = np.argmax(np.abs(v), axis=0)
        v = v * np.sign(v[idx, np.arange(3)])
        return cls(N2=_readonly(n2), N4=_readonly(n4), F2=_readonly(f2), F4=_readonly(f4),
                   D2=_readonly(d2), D4=_readonly(d4), n_contacts=int(n_contacts),
                   total_weight=float(n_contacts if total_weight is None else total_weight),
                   eigenvalues=_readonly(w), eigenvectors=_readonly(v),
                   anisotropy=float(math.sqrt(1.5 * float(np.sum(d2 * d2)))),
                   anisotropy_rank4=float(math.sqrt(float(np.sum(d4 * d4)))))

    @property
    def anisotropy_noise(self) -> float:
        """RMS :attr:`anisotropy` of ``n_contacts`` isotropic random directions,
        :math:`7.5/\\sqrt{M}` (NaN without contacts). For weighted directions the noise is
        larger: they count as :math:`(\\sum w)^2 / \\sum w^2 \\le M` directions.

        Examples
        --------
        >>> round(fabric_tensors(np.eye(3)).anisotropy_noise, 3)
        4.33
        """
        return 7.5 / math.sqrt(self.n_contacts) if self.n_contacts > 0 else math.nan

    @property
    def anisotropy_rank4_noise(self) -> float:
        """RMS :attr:`anisotropy_rank4` of ``n_contacts`` isotropic random directions,
        :math:`\\sqrt{2835/(8 M)}` (NaN without contacts)."""
        return math.sqrt(2835.0 / (8.0 * self.n_contacts)) if self.n_contacts > 0 else math.nan

    def density(self, directions, *, rank: int = 4) -> np.ndarray:
        """Shortcut for :func:`fabric_density` ``(self, directions, rank=rank)``."""
        return fabric_density(self, directions, rank=rank)

    def rotated(self, rotation) -> "FabricTensors":
        """The tensors of the directions rotated by the (3, 3) orthogonal matrix ``rotation``.

        Examples
        --------
        >>> t = fabric_tensors([[1.0, 0.0, 0.0]])
        >>> r = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
        >>> t.rotated(r).N2.round(12).tolist()
        [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]]
        """
        r = np.asarray(rotation, dtype=np.float64)
        if r.shape != (3, 3) or not np.allclose(r @ r.T, _DELTA, atol=1e-10):
            raise ValueError(f"`rotation` must be an orthogonal (3, 3) matrix; got shape {r.shape}")
        n2 = np.einsum("ia,jb,ab->ij", r, r, self.N2)
        n4 = np.einsum("ia,jb,kc,ld,abcd->ijkl", r, r, r, r, self.N4, optimize=True)
        return FabricTensors.from_moments(n2, n4, n_contacts=self.n_contacts,
                                          total_weight=self.total_weight)


# --------------------------------------------------------------------------- validation
def _as_directions(normals, name="normals") -> np.ndarray:
    if hasattr(normals, "normals") and hasattr(normals, "branch"):
        normals = normals.normals
    arr = np.asarray(normals, dtype=np.float64)
    if arr.ndim == 1 and arr.size == 3:
        arr = arr.reshape(1, 3)
    if arr.ndim == 1 and arr.size == 0:
        arr = arr.reshape(0, 3)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"`{name}` must have shape (M, 3); got {arr.shape}")
    return np.ascontiguousarray(arr)


def _resolve_weights(source, weights, m):
    """Weights array (M,) or None; strings look up per-contact fields of a Contacts object."""
    if weights is None:
        return None
    if isinstance(weights, str):
        if not (hasattr(source, "branch") and hasattr(source, "normals")):
            raise TypeError(f"`weights={weights!r}` needs a Contacts object as first argument; "
                            f"got {type(source).__name__}")
        key = weights.lower()
        if key in ("force_normal", "normal_force", "force"):
            fn = source.force_normal
            if fn is None:
                raise ValueError("`weights='force_normal'` needs Contacts.force_normal; "
                                 "these contacts have no forces (read a dump local file)")
            weights = np.sqrt(np.einsum("ij,ij->i", fn, fn))
        elif key in ("contact_area", "area"):
            weights = source.contact_area
        elif key in ("branch_length", "branch", "distance"):
            weights = source.distance
        else:
            raise ValueError(f"unknown `weights` {weights!r}; expected an array or one of "
                             f"'force_normal', 'contact_area', 'branch_length'")
    w = np.ascontiguousarray(weights, dtype=np.float64)
    if w.ndim == 0:
        w = np.full(m, float(w))
    if w.shape != (m,):
        raise ValueError(f"`weights` must have shape (M,) matching the directions (M={m}); "
                         f"got {w.shape}")
    if m and not np.all(np.isfinite(w)):
        raise ValueError("`weights` must be finite")
    if m and w.min() < 0:
        raise ValueError(f"`weights` must be non-negative; got minimum {w.min()}")
    return w


def _n_chunks(m: int) -> int:
    from .._numba import get_num_threads
    return int(max(1, min(4 * get_num_threads(), m // 4096 + 1)))


# --------------------------------------------------------------------------- main entry
def fabric_tensors(normals, weights=None) -> FabricTensors:
    """Fabric tensors of ranks 2 and 4 (kinds 1, 2, 3) of a set of directions.

    Parameters
    ----------
    normals : (M, 3) array_like of float, or Contacts
        Contact normals (any length; each row is normalised), or a
        :class:`~bedstruct.Contacts` whose ``normals`` are used. ``n`` and
        ``-n`` are equivalent. Rows of zero length (coincident centres) are
        skipped and logged.
    weights : (M,) array_like of float or str, optional
        Non-negative per-contact weights (e.g. normal-force magnitude or
        contact area). With a Contacts object the strings
        ``"force_normal"`` (``|force_normal|``), ``"contact_area"`` and
        ``"branch_length"`` (``|branch|``) select its fields. Default: all 1.

    Returns
    -------
    FabricTensors
        ``N2, N4, F2, F4, D2, D4`` (dimensionless), eigen-decomposition of
        ``N2`` and scalar anisotropies.

    Raises
    ------
    ValueError
        Bad shapes, negative or non-finite weights, no usable direction,
        or all weights zero.

    Notes
    -----
    With :math:`W = \\sum_a w_a`,
    :math:`N_{ij} = W^{-1}\\sum_a w_a n_i^a n_j^a` and likewise for
    :math:`N_{ijkl}`; the other kinds follow from the module formulas.
    Uniform weights give exactly the unweighted tensors. For spheres the
    branch vector is parallel to the normal, so the *branch* fabric is the
    ``weights="branch_length"`` tensor and the force fabric the
    ``weights="force_normal"`` tensor (Ouadfel & Rothenburg 2001).

    Examples
    --------
    The six contacts of a simple cubic lattice (each once, ``n`` or ``-n``):

    >>> t = fabric_tensors([[1, 0, 0], [0, -1, 0], [0, 0, 2]])
    >>> t.N2.round(6).tolist()
    [[0.333333, 0.0, 0.0], [0.0, 0.333333, 0.0], [0.0, 0.0, 0.333333]]
    >>> bool(np.allclose(t.D2, 0)), bool(np.allclose(t.F2, np.eye(3)))
    (True, True)
    >>> float(t.D4[0, 0, 0, 0])      # cubic symmetry shows at rank 4
    5.25
    """
    arr = _as_directions(normals)
    m = arr.shape[0]
    w = _resolve_weights(normals, weights, m)
    n_chunks = _n_chunks(m)
    out = np.zeros((n_chunks, _k.N_MOMENT_COLUMNS))
    _k.moment_sums(arr, w if w is not None else np.empty(0), w is not None, n_chunks, out)
    sums = out.sum(axis=0)
    n_bad = int(sums[1])
    n_used = m - n_bad
    if n_bad:
        log.info("fabric_tensors: skipped %d directions of zero length or non-finite", n_bad)
    if n_used == 0:
        raise ValueError(f"`normals` has no usable direction (M={m}, {n_bad} of zero length "
                         f"or non-finite)")
    total = float(sums[0])
    if not total > 0:
        raise ValueError("`weights` sum to zero over the usable directions")
    n2 = _assemble_n2(sums[2:8] / total)
    n4 = _assemble_n4(sums[8:23] / total)
    return FabricTensors.from_moments(n2, n4, n_contacts=n_used, total_weight=total)


def _assemble_n2(v6):
    n2 = np.empty((3, 3))
    for k, (i, j) in enumerate(_k.MONO2):
        n2[i, j] = n2[j, i] = v6[k]
    return n2


def _mono4_index():
    lookup = {tuple(e): k for k, e in enumerate(_k.MONO4.tolist())}
    idx = np.empty((3, 3, 3, 3), dtype=np.int64)
    for i, j, k, l in np.ndindex(3, 3, 3, 3):
        e = [0, 0, 0]
        for a in (i, j, k, l):
            e[a] += 1
        idx[i, j, k, l] = lookup[tuple(e)]
    return idx


_MONO4_INDEX = _mono4_index()


def _assemble_n4(v15):
    return np.asarray(v15, dtype=np.float64)[_MONO4_INDEX]


# --------------------------------------------------------------------------- density
def _unit_rows(directions):
    d = np.asarray(directions, dtype=np.float64)
    shape = d.shape[:-1]
    if d.shape[-1:] != (3,):
        raise ValueError(f"`directions` must have shape (..., 3); got {d.shape}")
    d = d.reshape(-1, 3)
    norm = np.sqrt(np.einsum("ij,ij->i", d, d))
    if np.any(norm == 0):
        raise ValueError("`directions` contains a zero vector")
    return d / norm[:, None], shape


def fabric_density(tensors: FabricTensors, directions, *, rank=4) -> np.ndarray:
    """The direction density approximated by the fabric tensors, per steradian.

    Parameters
    ----------
    tensors : FabricTensors
    directions : (..., 3) array_like of float
        Directions (normalised here).
    rank : {2, 4, "difference"}
        ``2``: :math:`f_2 = (1 + D_{ij}n_in_j)/(4\\pi)`; ``4``:
        :math:`f_4 = (1 + D_{ij}n_in_j + D_{ijkl}n_in_jn_kn_l)/(4\\pi)`;
        ``"difference"``: :math:`f_4 - f_2 = D_{ijkl}n_in_jn_kn_l/(4\\pi)`.

    Returns
    -------
    ndarray of float, shape (...), 1/steradian
        Integrates to 1 over the sphere for ranks 2 and 4 (0 for the
        difference). May be negative where a strongly anisotropic sample is
        poorly described by a low-rank truncation.

    Examples
    --------
    >>> t = fabric_tensors([[1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> round(float(fabric_density(t, [0, 0, 1], rank=2)) * 4 * np.pi, 12)
    1.0
    """
    d, shape = _unit_rows(directions)
    q2 = np.einsum("ni,nj,ij->n", d, d, tensors.D2)
    q4 = np.einsum("ni,nj,nk,nl,ijkl->n", d, d, d, d, tensors.D4, optimize=True)
    if rank == 2:
        f = 1.0 + q2
    elif rank == 4:
        f = 1.0 + q2 + q4
    elif rank == "difference":
        f = q4
    else:
        raise ValueError(f"`rank` must be 2, 4 or 'difference'; got {rank!r}")
    return (f / (4.0 * math.pi)).reshape(shape)


_PLANES = {"xy": (0, 1, 2), "xz": (0, 2, 1), "yz": (1, 2, 0)}


def projected_density(tensors: FabricTensors, angles, *, plane="xy", rank=4, n_quad=24):
    """Density of the in-plane angle of directions projected on a coordinate plane.

    For ``plane="xy"`` a direction :math:`n = (\\cos\\beta\\cos\\alpha,
    \\cos\\beta\\sin\\alpha, \\sin\\beta)` projects on the angle
    :math:`\\alpha`; the density of :math:`\\alpha` implied by the tensor
    approximation :math:`f` is

    .. math:: p(\\alpha) = \\int_{-\\pi/2}^{\\pi/2} f(n(\\alpha, \\beta)) \\cos\\beta \\, d\\beta ,

    integrated here by Gauss-Legendre quadrature (exact for these
    polynomials), so :math:`\\int_0^{2\\pi} p\\,d\\alpha = 1` (ranks 2 and 4).
    Planes ``"xz"`` and ``"yz"`` measure :math:`\\alpha` from the first
    named axis towards the second.

    Parameters
    ----------
    tensors : FabricTensors
    angles : array_like of float, radian
        In-plane angles :math:`\\alpha`.
    plane : {"xy", "xz", "yz"}
    rank : {2, 4, "difference"}
    n_quad : int
        Quadrature nodes in :math:`\\sin\\beta`.

    Returns
    -------
    ndarray of float, 1/radian, shape of ``angles``

    Examples
    --------
    >>> t = fabric_tensors([[1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> bool(np.allclose(projected_density(t, [0.0, 1.0], plane="xz", rank=2), 1 / (2 * np.pi)))
    True
    """
    if plane not in _PLANES:
        raise ValueError(f"`plane` must be one of {sorted(_PLANES)}; got {plane!r}")
    a = np.asarray(angles, dtype=np.float64)
    u, v, w = _PLANES[plane]
    s, ws = np.polynomial.legendre.leggauss(int(n_quad))   # s = sin(beta), ds = cos(beta) dbeta
    c = np.sqrt(1.0 - s * s)
    dirs = np.zeros(a.shape + s.shape + (3,))
    dirs[..., u] = np.cos(a)[..., None] * c
    dirs[..., v] = np.sin(a)[..., None] * c
    dirs[..., w] = s
    f = fabric_density(tensors, dirs, rank=rank)
    return np.einsum("...q,q->...", f, ws)


# --------------------------------------------------------------------------- sampling
def sample_directions(n: int, *, D2=None, D4=None, rng=None) -> np.ndarray:
    """Draw unit directions from :math:`f(n) = (1 + D_{ij}n_in_j + D_{ijkl}n_in_jn_kn_l)/(4\\pi)`.

    Rejection sampling from the uniform distribution on the sphere. Useful
    as a null model or to test estimators.

    Parameters
    ----------
    n : int
        Number of directions.
    D2 : (3, 3) array_like, optional
        Symmetric traceless rank-2 deviator (default 0).
    D4 : (3, 3, 3, 3) array_like, optional
        Fully symmetric traceless rank-4 deviator (default 0).
    rng : numpy.random.Generator or int, optional
        Random generator or seed.

    Returns
    -------
    (n, 3) ndarray of float
        Unit vectors.

    Raises
    ------
    ValueError
        If the density is negative somewhere (not a distribution).

    Examples
    --------
    >>> d = sample_directions(5, D2=np.diag([1.0, -0.5, -0.5]), rng=1)
    >>> d.shape, bool(np.allclose(np.linalg.norm(d, axis=1), 1))
    ((5, 3), True)
    """
    rng = np.random.default_rng(rng)
    d2 = np.zeros((3, 3)) if D2 is None else np.asarray(D2, dtype=np.float64)
    d4 = np.zeros((3, 3, 3, 3)) if D4 is None else np.asarray(D4, dtype=np.float64)
    if d2.shape != (3, 3) or d4.shape != (3, 3, 3, 3):
        raise ValueError(f"`D2` must have shape (3, 3) and `D4` (3, 3, 3, 3); got {d2.shape}, {d4.shape}")
    if abs(np.trace(d2)) > 1e-9 or np.abs(np.einsum("iikl->kl", d4)).max() > 1e-9:
        raise ValueError("`D2` and `D4` must be traceless (deviatoric)")

    def g(x):
        return (1.0 + np.einsum("ni,nj,ij->n", x, x, d2)
                + np.einsum("ni,nj,nk,nl,ijkl->n", x, x, x, x, d4, optimize=True))

    probe = rng.normal(size=(20000, 3))
    probe /= np.linalg.norm(probe, axis=1)[:, None]
    gp = g(probe)
    if gp.min() < 0:
        raise ValueError(f"the density is negative in some directions (min 4 pi f = {gp.min():.3g}); "
                         "D2/D4 do not describe a distribution")
    bound = 1.1 * gp.max() + 1e-12
    out = np.empty((0, 3))
    while out.shape[0] < n:
        k = max(1024, int(1.3 * (n - out.shape[0]) * bound))
        x = rng.normal(size=(k, 3))
        x /= np.linalg.norm(x, axis=1)[:, None]
        keep = rng.random(k) * bound < g(x)
        out = np.concatenate([out, x[keep]])
    return np.ascontiguousarray(out[:n])
