"""Fabric tensors with the conventions of LAMMPS ``compute fabric``.

Implementation module of :mod:`bedstruct.analysis.fabric` (import from there).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._fabric_algebra import _DELTA
from ._fabric_tensors import _as_directions, _resolve_weights

__all__ = ["lammps_voigt", "LammpsFabric", "lammps_fabric"]


# --------------------------------------------------------------------------- LAMMPS
def lammps_voigt(tensor) -> np.ndarray:
    """Components of a symmetric (3, 3) tensor in LAMMPS order ``xx yy zz xy xz yz``.

    Examples
    --------
    >>> lammps_voigt([[1, 4, 5], [4, 2, 6], [5, 6, 3]]).tolist()
    [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    """
    t = np.asarray(tensor, dtype=np.float64)
    if t.shape != (3, 3):
        raise ValueError(f"`tensor` must have shape (3, 3); got {t.shape}")
    return np.array([t[0, 0], t[1, 1], t[2, 2], t[0, 1], t[0, 2], t[1, 2]])


@dataclass(frozen=True)
class LammpsFabric:
    """The vector of LAMMPS ``compute fabric`` for one set of contacts.

    Each field is a (6,) array in LAMMPS order ``xx yy zz xy xz yz``, or
    None when the input needed for it was not given.

    Attributes
    ----------
    contact : (6,) ndarray
        Contact tensor; equals :func:`lammps_voigt` of :attr:`FabricTensors.D2`.
    branch : (6,) ndarray or None
        Branch tensor (needs branch lengths).
    force_normal : (6,) ndarray or None
        Normal-force tensor (needs normal-force magnitudes).
    force_tangential : (6,) ndarray or None
        Tangential-force tensor (needs normal and tangential magnitudes).
    n_contacts : int
        The scalar output (number of pairs).
    """

    contact: np.ndarray
    branch: np.ndarray | None
    force_normal: np.ndarray | None
    force_tangential: np.ndarray | None
    n_contacts: int


def lammps_fabric(normals, *, branch_lengths=None, force_normal=None,
                  force_tangential=None) -> LammpsFabric:
    """Fabric tensors with the conventions of LAMMPS ``compute fabric`` (GRANULAR package).

    Follows the LAMMPS source (``compute_fabric.cpp``): with
    :math:`\\phi_{ab} = N_c^{-1}\\sum n_a n_b` (our ``N2``),
    the contact tensor is :math:`A_{ab} = \\tfrac{15}{2}(\\phi_{ab} - \\tfrac13
    \\phi_{cc}\\delta_{ab})`, which is exactly our third-kind ``D2``. The
    branch and force tensors weight each pair by
    :math:`1 / (N_c (1 + A_{cd} n_c n_d))` (the contact density) times the
    branch length ``l``, ``f_n`` or ``f_t``, giving :math:`X_{ab}`, and
    report :math:`\\tfrac{15}{2\\,\\mathrm{tr}X}(X_{ab} - \\tfrac13 \\mathrm{tr}X
    \\,\\delta_{ab})`; the tangential tensor uses
    :math:`\\tfrac{15}{3\\,\\mathrm{tr}X^{n}}(X^t_{ab} - \\tfrac13 \\mathrm{tr}X^t\\delta_{ab})`
    (Ouadfel & Rothenburg 2001). The LAMMPS manual prints
    :math:`\\mathrm{Tr}(\\phi)` where the code subtracts one third of the
    trace and normalises by :math:`N_c`; we follow the code.

    Parameters
    ----------
    normals : (M, 3) array_like of float, or Contacts
        Pair directions (sign irrelevant). With a Contacts object the
        branch lengths and force magnitudes default to its fields.
    branch_lengths, force_normal, force_tangential : (M,) array_like of float, optional
        Branch lengths (length) and force magnitudes (force).

    Returns
    -------
    LammpsFabric

    Examples
    --------
    >>> lf = lammps_fabric([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 0]])
    >>> lf.contact.round(6).tolist()
    [1.25, -0.625, -0.625, 0.0, 0.0, 0.0]
    """
    src = normals
    n = _as_directions(normals)
    norm = np.sqrt(np.einsum("ij,ij->i", n, n))
    if np.any(norm == 0):
        raise ValueError("`normals` contains zero vectors; LAMMPS never counts such pairs")
    n = n / norm[:, None]
    m = n.shape[0]
    if m == 0:
        z = np.zeros(6)
        return LammpsFabric(z, None, None, None, 0)
    if hasattr(src, "branch") and hasattr(src, "normals"):
        if branch_lengths is None:
            branch_lengths = src.distance
        if force_normal is None and src.force_normal is not None:
            force_normal = np.sqrt(np.einsum("ij,ij->i", src.force_normal, src.force_normal))
        if force_tangential is None and src.force_tangential is not None:
            force_tangential = np.sqrt(np.einsum("ij,ij->i", src.force_tangential,
                                                 src.force_tangential))
    phi = np.einsum("ni,nj->ij", n, n) / m
    a = 7.5 * (phi - np.trace(phi) / 3.0 * _DELTA)
    pref = 1.0 / (m * (1.0 + np.einsum("ni,nj,ij->n", n, n, a)))

    def tensor(values, name):
        v = _resolve_weights(None, values, m)
        x = np.einsum("n,ni,nj->ij", pref * v, n, n)
        return x, float(np.trace(x)) / 3.0

    def deviator(x, tr3, scale):
        return lammps_voigt(scale * (x - tr3 * _DELTA))

    br = fn = ft = None
    if branch_lengths is not None:
        x, tr3 = tensor(branch_lengths, "branch_lengths")
        br = deviator(x, tr3, 15.0 / (6.0 * tr3))
    if force_normal is not None:
        xn, trn3 = tensor(force_normal, "force_normal")
        fn = deviator(xn, trn3, 15.0 / (6.0 * trn3))
        if force_tangential is not None:
            xt, trt3 = tensor(force_tangential, "force_tangential")
            ft = deviator(xt, trt3, 15.0 / (9.0 * trn3))
    elif force_tangential is not None:
        raise ValueError("`force_tangential` needs `force_normal` (LAMMPS normalises by it)")
    return LammpsFabric(contact=lammps_voigt(a), branch=br, force_normal=fn,
                        force_tangential=ft, n_contacts=m)
