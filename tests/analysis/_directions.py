"""Direction helpers shared by the fabric and harmonics tests (not a conftest, see
tests/io/_iohelpers.py for why)."""

from __future__ import annotations

import numpy as np


def unit(x):
    """Rows of ``x`` scaled to unit length."""
    x = np.asarray(x, dtype=float)
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


def random_rotation(rng):
    """A uniformly random proper rotation (QR of a Gaussian matrix, signs fixed, det +1)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    return q
