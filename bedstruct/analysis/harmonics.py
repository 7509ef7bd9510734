"""Real spherical-harmonic expansion of contact-normal distributions.

The density of directions on the unit sphere (per steradian, integrating to
1) is expanded as

.. math::

    f(n) = \\sum_{l=0}^{l_{max}} \\sum_{m=-l}^{l} c_{lm} Y_{lm}(n), \\qquad
    c_{lm} = \\int f\\,Y_{lm}\\,d\\Omega = \\langle Y_{lm}(n) \\rangle_w ,

the weighted sample mean of :math:`Y_{lm}` over the data. The real
harmonics are orthonormal on the unit sphere,
:math:`\\int Y_{lm} Y_{l'm'} d\\Omega = \\delta_{ll'}\\delta_{mm'}`, without the
Condon-Shortley phase:

.. math::

    Y_{lm} = \\sqrt{2} K_{l|m|} P_l^{|m|}(\\cos\\theta) \\cos(m\\phi)\\ (m > 0), \\quad
    Y_{l0} = K_{l0} P_l(\\cos\\theta), \\quad
    Y_{lm} = \\sqrt{2} K_{l|m|} P_l^{|m|}(\\cos\\theta) \\sin(|m|\\phi)\\ (m < 0),

with :math:`K_{lm} = \\sqrt{\\tfrac{2l+1}{4\\pi}\\tfrac{(l-m)!}{(l+m)!}}` and
:math:`P_l^m` without the :math:`(-1)^m` factor. So :math:`Y_{1,1}\\propto x`,
:math:`Y_{1,-1}\\propto y`, :math:`Y_{1,0}\\propto z`, :math:`Y_{2,-2}\\propto xy`,
:math:`Y_{2,2}\\propto x^2 - y^2`. In terms of SciPy's complex harmonics,
``Y_lm = sqrt(2) (-1)^m Re sph_harm_y(l, m, theta, phi)`` for ``m > 0`` and
``sqrt(2) (-1)^m Im sph_harm_y(l, |m|, theta, phi)`` for ``m < 0``.

Coefficients are stored flat, ``coefficients[l*l + l + m]``. For antipodal
data (contact normals: ``n`` and ``-n`` are the same contact) the odd
degrees vanish exactly and are not computed. The power per degree
:math:`P_l = \\sum_m c_{lm}^2` is invariant under rotations.

The link with fabric tensors is exact: the expansion truncated at
:math:`l = 2` equals :math:`(1 + D_{ij}n_in_j)/(4\\pi)` and at :math:`l = 4`
equals :math:`(1 + D_{ij}n_in_j + D_{ijkl}n_in_jn_kn_l)/(4\\pi)`, because both
are the :math:`L^2` projection of the sample's empirical measure onto the
same function space; :func:`harmonics_from_fabric` and
:func:`fabric_from_harmonics` convert in both directions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import _fabric_kernels as _k
from ._fabric_tensors import (FabricTensors, _as_directions, _n_chunks, _resolve_weights,
                              fabric_density, fabric_tensors)

__all__ = [
    "HarmonicExpansion", "harmonic_expansion", "real_spherical_harmonics", "harmonic_density",
    "sphere_grid", "harmonics_from_fabric", "fabric_from_harmonics",
]


def _check_lmax(l_max) -> int:
    if isinstance(l_max, bool) or not isinstance(l_max, (int, np.integer)) or l_max < 0:
        raise ValueError(f"`l_max` must be a non-negative integer; got {l_max!r}")
    if l_max > 150:
        raise ValueError(f"`l_max` must be <= 150; got {l_max}")
    return int(l_max)


def real_spherical_harmonics(directions, l_max: int) -> np.ndarray:
    """Real orthonormal spherical harmonics at each direction, all degrees up to ``l_max``.

    Parameters
    ----------
    directions : (M, 3) array_like of float
        Directions (normalised here; zero or non-finite rows raise).
    l_max : int
        Highest degree.

    Returns
    -------
    (M, (l_max + 1)**2) ndarray of float
        Column ``l*l + l + m`` holds :math:`Y_{lm}` (module docstring).

    Examples
    --------
    >>> y = real_spherical_harmonics([[0.0, 0.0, 1.0]], 1)
    >>> y.round(6).tolist()   # Y00, Y1-1 (y), Y10 (z), Y11 (x)
    [[0.282095, 0.0, 0.488603, 0.0]]
    """
    l_max = _check_lmax(l_max)
    d = _as_directions(directions, "directions")
    n2 = np.einsum("ij,ij->i", d, d)
    if d.shape[0] and not np.all(np.isfinite(n2) & (n2 > 0)):
        bad = int(np.flatnonzero(~(np.isfinite(n2) & (n2 > 0)))[0])
        raise ValueError(f"`directions` must be non-zero and finite; row {bad} is {d[bad].tolist()}")
    out = np.zeros((d.shape[0], (l_max + 1) ** 2))
    a, b, fmm = _k.recurrence_tables(l_max)
    _k.harmonic_matrix(d, l_max, a, b, fmm, out)
    return out


@dataclass(frozen=True)
class HarmonicExpansion:
    """Real spherical-harmonic coefficients of a direction density.

    Attributes
    ----------
    l_max : int
        Highest degree.
    coefficients : ((l_max + 1)**2,) ndarray of float
        :math:`c_{lm}` at index ``l*l + l + m`` (the sample mean of
        :math:`Y_{lm}`; dimensionless, :math:`c_{00} = 1/\\sqrt{4\\pi}`).
    power : (l_max + 1,) ndarray of float
        :math:`P_l = \\sum_m c_{lm}^2`; :math:`P_0 = 1/(4\\pi)`.
    antipodal : bool
        True when ``n`` and ``-n`` were counted alike (odd degrees zero).
    n_samples : int
        Number of directions used.
    total_weight : float
        Sum of weights.

    .. versionadded:: 0.1
    """

    l_max: int
    coefficients: np.ndarray = field(repr=False)
    power: np.ndarray
    antipodal: bool
    n_samples: int
    total_weight: float

    @classmethod
    def from_coefficients(cls, coefficients, *, antipodal: bool = True, n_samples: int = 0,
                          total_weight: float | None = None) -> "HarmonicExpansion":
        """Wrap a flat coefficient array of length ``(l_max + 1)**2``.

        Examples
        --------
        >>> e = HarmonicExpansion.from_coefficients([1 / np.sqrt(4 * np.pi), 0, 0, 0])
        >>> e.l_max, round(float(e.power[0]) * 4 * np.pi, 12)
        (1, 1.0)
        """
        c = np.array(coefficients, dtype=np.float64).reshape(-1)
        l_max = int(round(math.sqrt(c.size))) - 1
        if (l_max + 1) ** 2 != c.size or c.size == 0:
            raise ValueError(f"`coefficients` must have length (l_max + 1)**2; got {c.size}")
        power = np.array([np.sum(c[l * l:(l + 1) ** 2] ** 2) for l in range(l_max + 1)])
        c.setflags(write=False)
        power.setflags(write=False)
        return cls(l_max=l_max, coefficients=c, power=power, antipodal=bool(antipodal),
                   n_samples=int(n_samples),
                   total_weight=float(n_samples if total_weight is None else total_weight))

    def coefficient(self, l: int, m: int) -> float:
        """:math:`c_{lm}`.

        Examples
        --------
        >>> e = harmonic_expansion([[0, 0, 1]], 2)
        >>> round(e.coefficient(2, 0), 6)   # Y20 at the pole
        0.630783
        """
        if not (0 <= l <= self.l_max and -l <= m <= l):
            raise ValueError(f"need 0 <= l <= {self.l_max} and -l <= m <= l; got l={l}, m={m}")
        return float(self.coefficients[l * l + l + m])

    def degree(self, l: int) -> np.ndarray:
        """The ``2l + 1`` coefficients of degree ``l`` (m = -l ... l)."""
        return self.coefficients[l * l:(l + 1) ** 2]

    def truncated(self, l_max: int) -> "HarmonicExpansion":
        """The expansion cut at degree ``l_max`` (<= ``self.l_max``)."""
        l_max = _check_lmax(l_max)
        if l_max > self.l_max:
            raise ValueError(f"`l_max` must be <= {self.l_max}; got {l_max}")
        return HarmonicExpansion.from_coefficients(
            self.coefficients[:(l_max + 1) ** 2], antipodal=self.antipodal,
            n_samples=self.n_samples, total_weight=self.total_weight)

    def density(self, directions, *, l_max: int | None = None) -> np.ndarray:
        """Shortcut for :func:`harmonic_density`."""
        return harmonic_density(self, directions, l_max=l_max)


def harmonic_expansion(normals, l_max: int, weights=None, *, antipodal: bool = True
                       ) -> HarmonicExpansion:
    """Real spherical-harmonic coefficients of the (weighted) distribution of directions.

    Parameters
    ----------
    normals : (M, 3) array_like of float, or Contacts
        Directions (normalised here; zero rows skipped), or Contacts.
    l_max : int
        Highest degree (e.g. 4 to match the rank-4 fabric tensors, 8 for
        detail).
    weights : (M,) array_like of float or str, optional
        Non-negative weights, or with Contacts ``"force_normal"``,
        ``"contact_area"``, ``"branch_length"`` (see
        :func:`~bedstruct.analysis.fabric.fabric_tensors`).
    antipodal : bool
        True (default) for contact normals: ``n`` and ``-n`` count alike and
        odd degrees are exactly 0. False for directed vectors (odd degrees
        kept).

    Returns
    -------
    HarmonicExpansion
        ``coefficients`` (``c[l*l + l + m]``) and ``power`` per degree.

    Notes
    -----
    :math:`c_{lm} = \\sum_a w_a Y_{lm}(n^a) / \\sum_a w_a`; with
    ``antipodal=True`` each datum is replaced by the pair :math:`\\pm n^a`
    with half weight, which zeroes the odd degrees and leaves the even ones
    unchanged.

    Examples
    --------
    >>> e = harmonic_expansion([[1, 0, 0], [0, 1, 0], [0, 0, 1]], 4)
    >>> e.power.round(6).tolist()   # cubic: no l = 2 part, some l = 4
    [0.079577, 0.0, 0.0, 0.0, 0.417782]
    """
    l_max = _check_lmax(l_max)
    arr = _as_directions(normals)
    m = arr.shape[0]
    w = _resolve_weights(normals, weights, m)
    norm2 = np.einsum("ij,ij->i", arr, arr)
    good = np.isfinite(norm2) & (norm2 > 0)
    n_used = int(good.sum())
    if n_used == 0:
        raise ValueError(f"`normals` has no usable direction (M={m})")
    total = float(n_used if w is None else w[good].sum())
    if not total > 0:
        raise ValueError("`weights` sum to zero over the usable directions")
    n_chunks = _n_chunks(m)
    k = (l_max + 1) ** 2
    out = np.zeros((n_chunks, k))
    a, b, fmm = _k.recurrence_tables(l_max)
    _k.harmonic_sums(arr, w if w is not None else np.empty(0), w is not None, l_max,
                     bool(antipodal), a, b, fmm, n_chunks, out)
    return HarmonicExpansion.from_coefficients(out.sum(axis=0) / total, antipodal=antipodal,
                                               n_samples=n_used, total_weight=total)


def harmonic_density(expansion: HarmonicExpansion, directions, *, l_max: int | None = None
                     ) -> np.ndarray:
    """The expansion :math:`\\sum_{l \\le l_{max}} c_{lm} Y_{lm}(n)` evaluated at directions.

    Parameters
    ----------
    expansion : HarmonicExpansion
    directions : (..., 3) array_like of float
    l_max : int, optional
        Truncation degree (default all of ``expansion``).

    Returns
    -------
    ndarray of float, shape (...), 1/steradian

    Examples
    --------
    >>> e = harmonic_expansion([[0, 0, 1]], 0)
    >>> round(float(harmonic_density(e, [1, 0, 0])) * 4 * np.pi, 12)
    1.0
    """
    l_max = expansion.l_max if l_max is None else min(_check_lmax(l_max), expansion.l_max)
    d = np.asarray(directions, dtype=np.float64)
    if d.shape[-1:] != (3,):
        raise ValueError(f"`directions` must have shape (..., 3); got {d.shape}")
    shape = d.shape[:-1]
    y = real_spherical_harmonics(d.reshape(-1, 3), l_max)
    return (y @ expansion.coefficients[:(l_max + 1) ** 2]).reshape(shape)


def sphere_grid(n_theta: int = 61, n_phi: int = 121):
    """A closed latitude-longitude grid of unit directions (for surfaces and plots).

    Parameters
    ----------
    n_theta, n_phi : int
        Points in polar angle (0 to pi, both poles included) and azimuth
        (0 to 2 pi, the seam repeated so surfaces close).

    Returns
    -------
    theta : (n_theta, n_phi) ndarray, radian
    phi : (n_theta, n_phi) ndarray, radian
    directions : (n_theta, n_phi, 3) ndarray
        Unit vectors :math:`(\\sin\\theta\\cos\\phi, \\sin\\theta\\sin\\phi, \\cos\\theta)`.

    Examples
    --------
    >>> th, ph, d = sphere_grid(3, 5)
    >>> d.shape, d[0, 0].round(12).tolist()
    ((3, 5, 3), [0.0, 0.0, 1.0])
    """
    if n_theta < 2 or n_phi < 3:
        raise ValueError(f"need n_theta >= 2 and n_phi >= 3; got {n_theta}, {n_phi}")
    th, ph = np.meshgrid(np.linspace(0.0, math.pi, int(n_theta)),
                         np.linspace(0.0, 2.0 * math.pi, int(n_phi)), indexing="ij")
    d = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1)
    return th, ph, d


def _sphere_quadrature(degree: int):
    """Nodes and weights integrating polynomials of degree <= ``degree`` exactly on the sphere."""
    nz = degree // 2 + 1
    nphi = degree + 1
    z, wz = np.polynomial.legendre.leggauss(nz)
    phi = 2.0 * math.pi * np.arange(nphi) / nphi
    s = np.sqrt(1.0 - z * z)
    dirs = np.stack([np.outer(s, np.cos(phi)), np.outer(s, np.sin(phi)),
                     np.outer(z, np.ones(nphi))], axis=-1).reshape(-1, 3)
    w = np.outer(wz, np.full(nphi, 2.0 * math.pi / nphi)).reshape(-1)
    return dirs, w


def harmonics_from_fabric(tensors: FabricTensors, *, l_max: int = 4, rank: int = 4
                          ) -> HarmonicExpansion:
    """Harmonic coefficients of the tensor approximation :math:`f_2` or :math:`f_4`.

    Parameters
    ----------
    tensors : FabricTensors
    l_max : int
        Degree of the returned expansion (coefficients above ``rank`` are 0).
    rank : {2, 4}
        Which approximation (:func:`~bedstruct.analysis.fabric.fabric_density`).

    Returns
    -------
    HarmonicExpansion
        Equal, to rounding, to ``harmonic_expansion(normals, l_max=rank)``
        of the data the tensors came from.

    Notes
    -----
    :math:`c_{lm} = \\int f\\,Y_{lm}\\,d\\Omega` computed by a product
    Gauss-Legendre/trapezoid rule that is exact for the polynomial degree
    involved.

    Examples
    --------
    >>> t = fabric_tensors([[1, 0, 0], [0, 0, 1]])
    >>> e = harmonics_from_fabric(t)
    >>> bool(np.allclose(e.coefficients, harmonic_expansion([[1, 0, 0], [0, 0, 1]], 4).coefficients))
    True
    """
    l_max = _check_lmax(l_max)
    if rank not in (2, 4):
        raise ValueError(f"`rank` must be 2 or 4; got {rank!r}")
    dirs, w = _sphere_quadrature(rank + l_max)
    f = fabric_density(tensors, dirs, rank=rank)
    y = real_spherical_harmonics(dirs, l_max)
    c = (w * f) @ y
    for l in range(rank + 1, l_max + 1):
        c[l * l:(l + 1) ** 2] = 0.0   # exactly zero: clear quadrature rounding
    for l in range(1, l_max + 1, 2):
        c[l * l:(l + 1) ** 2] = 0.0
    return HarmonicExpansion.from_coefficients(c, antipodal=True, n_samples=tensors.n_contacts,
                                               total_weight=tensors.total_weight)


def fabric_from_harmonics(expansion: HarmonicExpansion) -> FabricTensors:
    """Fabric tensors of the density described by harmonic coefficients of degree <= 4.

    The moment tensors are :math:`N_{ij} = \\int f n_in_j\\,d\\Omega / \\int f\\,d\\Omega`
    and likewise :math:`N_{ijkl}`, where only degrees 0, 2 and 4 of ``f``
    contribute; so the tensors of a sample are recovered exactly from its
    expansion to ``l_max >= 4`` (with ``l_max = 2`` the rank-4 deviator is 0).

    Parameters
    ----------
    expansion : HarmonicExpansion
        Needs ``c_00 > 0``.

    Returns
    -------
    FabricTensors

    Examples
    --------
    >>> d = [[1, 0, 0], [0, 0.6, 0.8]]
    >>> t = fabric_from_harmonics(harmonic_expansion(d, 4))
    >>> bool(np.allclose(t.D4, fabric_tensors(d).D4))
    True
    """
    c = expansion.coefficients
    if not c[0] > 0:
        raise ValueError(f"the expansion must have c_00 > 0 (a distribution); got {c[0]}")
    l_use = min(expansion.l_max, 4)
    dirs, w = _sphere_quadrature(l_use + 4)
    y = real_spherical_harmonics(dirs, l_use)
    cc = np.array(c[:(l_use + 1) ** 2])
    for l in range(1, l_use + 1, 2):
        cc[l * l:(l + 1) ** 2] = 0.0   # odd degrees carry no even moments
    f = y @ cc
    total = float(np.sum(w * f))
    wf = w * f / total
    n2 = np.einsum("q,qi,qj->ij", wf, dirs, dirs)
    n4 = np.einsum("q,qi,qj,qk,ql->ijkl", wf, dirs, dirs, dirs, dirs, optimize=True)
    return FabricTensors.from_moments(n2, n4, n_contacts=expansion.n_samples,
                                      total_weight=expansion.total_weight)
