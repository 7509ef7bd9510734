"""Numba kernels for parsing whitespace-separated numbers in dump files.

Every number is converted to the correctly rounded double, bit-identical to
``strtod`` and Python's ``float``, by one of two exact fast paths:

* Clinger's fast path: a mantissa ``m <= 2**53`` and a power of ten
  ``|e| <= 22`` become ``m * 10**e`` (or ``m / 10**-e``) in one IEEE operation
  on exact operands (the usual case for the 6-digit numbers LIGGGHTS writes);
* the Eisel-Lemire algorithm (as in fast_float, Go's ``strconv`` and Rust's
  ``core`` float parsing) for any other mantissa of at most 19 significant
  digits with a decimal exponent in [-342, 308] (the 17-digit round-trip
  numbers of :func:`bedstruct.write_dump`): the normalised mantissa times a
  128-bit truncated power of ten gives the leading bits of the value and a
  bound on what the truncation left out. Where that bound cannot decide the
  rounding, exact integer arithmetic settles the cases that occur (exact ties,
  values with a short binary fraction written with 17+ digits); anything still
  undecided (near-ties, about one in 2**64 random inputs) is flagged.

Tokens neither path decides (more than 19 significant digits, results that
would be subnormal or overflow, ``nan``, ``inf``, malformed text) are flagged
so that the caller re-parses their line with an exact general parser; the
kernel never guesses.
"""

from __future__ import annotations

import numpy as np

from .._numba import njit, njit_parallel, prange

__all__ = ["parse_rows", "gather_rows", "POW10", "POW10_HI", "POW10_LO", "POW5", "POW2",
           "EL_MIN_EXP10", "EL_MAX_EXP10"]

#: Exactly representable powers of ten, 1e0 .. 1e22.
POW10 = np.array([10.0 ** k for k in range(23)], dtype=np.float64)

_MAX_EXACT = np.uint64(9007199254740992)  # 2**53

#: Decimal exponents covered by the Eisel-Lemire tables.
EL_MIN_EXP10, EL_MAX_EXP10 = -342, 308


def _pow10_128(q: int) -> int:
    """The 128 leading bits of ``10**q``, truncated: ``T`` in [2**127, 2**128) with
    ``10**q = (T + d) * 2**(floor(log2(10**q)) - 127)``, ``0 <= d < 1`` (exact integers)."""
    if q >= 0:
        v = 10 ** q
        n = v.bit_length()
        return v >> (n - 128) if n >= 128 else v << (128 - n)
    d = 10 ** -q  # never a power of two, so 2**(bits + 127) // d < 2**128
    return (1 << (d.bit_length() + 127)) // d


def _tables():
    t = [_pow10_128(q) for q in range(EL_MIN_EXP10, EL_MAX_EXP10 + 1)]
    hi = np.array([v >> 64 for v in t], dtype=np.uint64)
    lo = np.array([v & (2 ** 64 - 1) for v in t], dtype=np.uint64)
    # the kernel's floor(q * log2(10)) = (217706 * q) >> 16 holds over the whole table
    for q in range(EL_MIN_EXP10, EL_MAX_EXP10 + 1):
        exact = (10 ** q).bit_length() - 1 if q >= 0 else -(10 ** -q).bit_length()
        assert (217706 * q) >> 16 == exact
    return hi, lo


#: High and low 64 bits of the 128-bit truncated powers of ten 10**q, q = -342 .. 308.
POW10_HI, POW10_LO = _tables()
#: Powers of five 5**0 .. 5**27 (all below 2**63).
POW5 = np.array([5 ** n for n in range(28)], dtype=np.uint64)
#: ``POW2[e] = 2**(e - 1075)`` for the biased exponents e = 1 .. 2046 of normal doubles, so
#: that a 53-bit integer mantissa times ``POW2[e]`` is the double, exactly.
POW2 = np.array([0.0] + [2.0 ** (e - 1075) for e in range(1, 2047)] + [0.0], dtype=np.float64)

_U0 = np.uint64(0)
_U1 = np.uint64(1)
_U3 = np.uint64(3)
_U9 = np.uint64(9)
_U10 = np.uint64(10)
_U32 = np.uint64(32)
_U53 = np.uint64(53)
_U63 = np.uint64(63)
_LOW9 = np.uint64(0x1FF)
_LOW32 = np.uint64(0xFFFFFFFF)
_ALL = np.uint64(0xFFFFFFFFFFFFFFFF)
_B32 = np.uint64(1 << 32)
_B48 = np.uint64(1 << 48)
_B56 = np.uint64(1 << 56)
_B60 = np.uint64(1 << 60)
_B62 = np.uint64(1 << 62)
_B63 = np.uint64(1 << 63)

#: Row status codes returned by :func:`parse_rows`.
OK, BAD_COUNT, SLOW = 0, 1, 2


@njit(inline="always")
def _digits(buf, i, e, m):
    """Append the decimal digits starting at ``buf[i]`` to the uint64 ``m``: (m, index after
    them). Exact while ``m`` has at most 19 digits."""
    while i < e:
        d = np.int64(buf[i]) - 48
        if d < 0 or d > 9:
            break
        m = m * _U10 + np.uint64(d)
        i += 1
    return m, i


@njit(inline="always")
def _zeros(buf, i, e):
    """Index after the '0' characters starting at ``buf[i]``."""
    while i < e and buf[i] == 48:
        i += 1
    return i


@njit(inline="always")
def _mul128(a, b):
    """The 128-bit product of two uint64 as (high, low) words, from 32-bit halves."""
    a0 = a & _LOW32
    a1 = a >> _U32
    b0 = b & _LOW32
    b1 = b >> _U32
    p00 = a0 * b0
    p01 = a0 * b1
    p10 = a1 * b0
    p11 = a1 * b1
    mid = (p00 >> _U32) + (p01 & _LOW32) + (p10 & _LOW32)  # < 3 * 2**32: no overflow
    hi = p11 + (p01 >> _U32) + (p10 >> _U32) + (mid >> _U32)
    lo = (mid << _U32) | (p00 & _LOW32)
    return hi, lo


@njit(inline="always")
def _normalise(w):
    """(w shifted left until its top bit is set, the shift) for a nonzero uint64."""
    n = 0
    if w < _B32:
        w = w << np.uint64(32)
        n += 32
    if w < _B48:
        w = w << np.uint64(16)
        n += 16
    if w < _B56:
        w = w << np.uint64(8)
        n += 8
    if w < _B60:
        w = w << np.uint64(4)
        n += 4
    if w < _B62:
        w = w << np.uint64(2)
        n += 2
    if w < _B63:
        w = w << _U1
        n += 1
    return w, n


@njit(inline="always")
def _dyadic(w, q, pow5, pow2):
    """``w * 10**q`` for ``-27 <= q < 0`` when it is a dyadic rational: (value, ok).

    When ``5**-q`` divides ``w`` the value is the integer ``w // 5**-q`` times
    ``2**q``; converting that integer to a double rounds correctly (IEEE) and the
    scaling is exact. The values Eisel-Lemire cannot decide for such ``q`` are
    of this kind (numbers with a short binary fraction written with more than
    16 digits, such as ``561351655411023.25``, and exact halfway points): any
    other value is more than 2**-117 (relative) away from every 54-bit binary
    number, far outside the 2**-126 uncertainty of the 128-bit product.
    """
    if q < 0 and q >= -27:
        p = pow5[-q]
        if w % p == _U0:
            return float(w // p) * pow2[1075 + q], True
    return 0.0, False


@njit(inline="always")
def _eisel_lemire(w, q, pow10_hi, pow10_lo, pow5, pow2):
    """The correctly rounded double nearest ``w * 10**q`` (w a nonzero uint64): (value, ok).

    Follows Go's ``strconv.eiselLemire64`` (table rounded down). Where that
    algorithm cannot decide, exact arithmetic settles the cases that can occur
    in practice: ties for ``0 <= q <= 27`` (where ``10**q`` fits the table
    exactly, so the product is exact) go to even, and dyadic values for
    ``-27 <= q < 0`` go to :func:`_dyadic`. ``ok`` is False for the rest
    (near-ties with ``|q| > 27``, about one in 2**64 random inputs), for ``q``
    outside the table and for results that would be subnormal or overflow: the
    caller then uses an exact general parser.
    """
    if q < EL_MIN_EXP10 or q > EL_MAX_EXP10:
        return 0.0, False
    w0 = w
    w, clz = _normalise(w)
    k = q - EL_MIN_EXP10
    # 64 x 128-bit product, first with the high word of the power only: the true
    # product of w and 10**q lies in [x, x + w) units of the low word x_lo
    x_hi, x_lo = _mul128(w, pow10_hi[k])
    if (x_hi & _LOW9) == _LOW9 and x_lo + w < w:
        # a carry from what was left out could reach the kept bits: use the low word too
        y_hi, y_lo = _mul128(w, pow10_lo[k])
        m_lo = x_lo + y_hi
        m_hi = x_hi
        if m_lo < x_lo:
            m_hi += _U1
        if (m_hi & _LOW9) == _LOW9 and m_lo == _ALL and y_lo + w < w:
            return _dyadic(w0, q, pow5, pow2)  # still undecided
        x_hi = m_hi
        x_lo = m_lo
    msb = x_hi >> _U63
    shift = msb + _U9
    mant = x_hi >> shift  # 54 bits: the 53 of the double and one rounding bit
    e2 = ((217706 * q) >> 16) + 1086 + np.int64(msb) - clz
    if x_lo == _U0 and (x_hi & _LOW9) == _U0 and (mant & _U3) == _U1:
        # maybe exactly halfway, with an even lower neighbour
        if q < 0 or q > 27:
            return _dyadic(w0, q, pow5, pow2)
        if (x_hi & ((_U1 << shift) - _U1)) == _U0:
            mant -= _U1  # an exact tie (the product is exact here): round down, to even
    mant = (mant + (mant & _U1)) >> _U1
    if (mant >> _U53) != _U0:
        mant = mant >> _U1
        e2 += 1
    if e2 <= 0 or e2 >= 2047:
        return 0.0, False  # subnormal or overflow
    return float(mant) * pow2[e2], True


@njit(inline="always")
def _number(buf, i, e, pow10, pow10_hi, pow10_lo, pow5, pow2):
    """Parse the token starting at ``buf[i]``: returns (value, index after it, exact)."""
    neg = False
    c = buf[i]
    if c == 45:
        neg = True
        i += 1
    elif c == 43:
        i += 1
    # all mantissa digits, integer and fraction part, into one integer; leading zeros
    # are not significant digits
    t0 = i
    i = _zeros(buf, i, e)
    t1 = i
    m, i = _digits(buf, i, e, _U0)
    nsig = i - t1
    nd = i - t0
    exp10 = 0
    if i < e and buf[i] == 46:
        i += 1
        t2 = i
        if nsig == 0:
            i = _zeros(buf, i, e)
        t3 = i
        m, i = _digits(buf, i, e, m)
        nsig += i - t3
        nd += i - t2
        exp10 = t2 - i
    # more than 19 significant digits could overflow: general parser
    ok = nd > 0 and nsig <= 19
    if i < e and (buf[i] == 101 or buf[i] == 69):
        i += 1
        eneg = False
        if i < e and buf[i] == 45:
            eneg = True
            i += 1
        elif i < e and buf[i] == 43:
            i += 1
        ex = 0
        t4 = i
        while i < e:
            d = np.int64(buf[i]) - 48
            if d < 0 or d > 9:
                break
            if ex < 100000:
                ex = ex * 10 + d
            i += 1
        if i == t4:
            ok = False
        exp10 += -ex if eneg else ex
    if i < e and buf[i] > 32:  # junk glued to the number: the general parser decides
        ok = False
        while i < e and buf[i] > 32:
            i += 1
    v = np.nan
    if ok:
        if m == _U0:
            v = 0.0
        elif m <= _MAX_EXACT and exp10 >= -22 and exp10 <= 22:
            if exp10 < 0:
                v = float(m) / pow10[-exp10]
            else:
                v = float(m) * pow10[exp10]
        else:
            v, ok = _eisel_lemire(m, exp10, pow10_hi, pow10_lo, pow5, pow2)
    return (-v if neg else v), i, ok


@njit(inline="always")
def _parse_line(buf, s, e, ncols, out, base, stride, drow, pow10, pow10_hi, pow10_lo,
                pow5, pow2):
    col = 0
    slow = False
    i = s
    while True:
        while i < e and buf[i] <= 32:
            i += 1
        if i >= e:
            break
        if col >= ncols:
            return 1
        v, i, ok = _number(buf, i, e, pow10, pow10_hi, pow10_lo, pow5, pow2)
        if not ok:
            slow = True
        out[base[col] + drow * stride[col]] = v
        col += 1
    if col != ncols:
        return 1
    return 2 if slow else 0


@njit_parallel
def parse_rows(buf, starts, ends, ncols, out, base, stride, dest, status):
    """Parse ``ncols`` numbers from each line ``buf[starts[r]:ends[r]]``.

    Value ``c`` of line ``r`` goes to ``out[base[c] + dest[r] * stride[c]]`` of
    the flat array ``out`` (a row-major (N, ncols) block has ``base = 0..ncols-1``,
    ``stride = ncols``, ``dest = 0..N-1``; other layouts scatter the columns
    straight into their final arrays, rows in any order). ``status[r]`` becomes
    0 (parsed exactly), 1 (wrong number of values) or 2 (a token needs the
    general parser: re-parse the line).
    """
    for r in prange(starts.shape[0]):
        status[r] = _parse_line(buf, starts[r], ends[r], ncols, out, base, stride, dest[r], POW10,
                                POW10_HI, POW10_LO, POW5, POW2)


@njit_parallel
def gather_rows(data, order, cols, out):
    """``out[r, k] = data[order[r], cols[k]]`` (row reordering and column selection at once)."""
    m = cols.shape[0]
    for r in prange(order.shape[0]):
        src = order[r]
        for k in range(m):
            out[r, k] = data[src, cols[k]]

