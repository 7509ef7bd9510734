"""Numba kernels for parsing whitespace-separated numbers in dump files.

Numbers are converted with Clinger's fast path: a decimal with at most 18
digits, a mantissa ``m <= 2**53`` and a power of ten ``|e| <= 22``
becomes ``m * 10**e`` (or ``m / 10**-e``) in one IEEE operation on exact
operands, which is the correctly rounded result (the same value ``strtod`` and
Python's ``float`` give). Tokens outside the fast path (more digits, ``nan``,
``inf``, malformed text) are flagged so that the caller re-parses their line
with an exact general parser; the kernel never guesses.
"""

from __future__ import annotations

import numpy as np

from .._numba import njit, njit_parallel, prange

__all__ = ["parse_rows", "gather_rows", "POW10"]

#: Exactly representable powers of ten, 1e0 .. 1e22.
POW10 = np.array([10.0 ** k for k in range(23)], dtype=np.float64)

_MAX_EXACT = 9007199254740992  # 2**53

#: Row status codes returned by :func:`parse_rows`.
OK, BAD_COUNT, SLOW = 0, 1, 2


@njit(inline="always")
def _digits(buf, i, e, m):
    """Append the decimal digits starting at ``buf[i]`` to ``m``: (m, index after them)."""
    while i < e:
        d = np.int64(buf[i]) - 48
        if d < 0 or d > 9:
            break
        m = m * 10 + d
        i += 1
    return m, i


@njit(inline="always")
def _number(buf, i, e, pow10):
    """Parse the token starting at ``buf[i]``: returns (value, index after it, exact)."""
    neg = False
    c = buf[i]
    if c == 45:
        neg = True
        i += 1
    elif c == 43:
        i += 1
    # all mantissa digits, integer and fraction part, into one integer
    t0 = i
    m, i = _digits(buf, i, e, np.int64(0))
    nd = i - t0
    exp10 = 0
    if i < e and buf[i] == 46:
        i += 1
        t1 = i
        m, i = _digits(buf, i, e, m)
        exp10 = t1 - i
        nd += i - t1
    # more than 18 digits (leading zeros included) could overflow: general parser
    ok = nd > 0 and nd <= 18
    if i < e and (buf[i] == 101 or buf[i] == 69):
        i += 1
        eneg = False
        if i < e and buf[i] == 45:
            eneg = True
            i += 1
        elif i < e and buf[i] == 43:
            i += 1
        ex = 0
        t2 = i
        while i < e:
            d = np.int64(buf[i]) - 48
            if d < 0 or d > 9:
                break
            if ex < 100000:
                ex = ex * 10 + d
            i += 1
        if i == t2:
            ok = False
        exp10 += -ex if eneg else ex
    if i < e and buf[i] > 32:  # junk glued to the number: the general parser decides
        ok = False
        while i < e and buf[i] > 32:
            i += 1
    v = np.nan
    if ok:
        if m == 0:
            v = 0.0
        else:
            if m > _MAX_EXACT or exp10 > 22 or exp10 < -22:
                while m % 10 == 0:
                    m //= 10
                    exp10 += 1
            if m <= _MAX_EXACT and exp10 >= -22 and exp10 <= 22:
                if exp10 < 0:
                    v = float(m) / pow10[-exp10]
                else:
                    v = float(m) * pow10[exp10]
            elif m <= _MAX_EXACT and exp10 > 22 and exp10 <= 37:
                # m * 10**(exp10 - 22) may still be an exact integer
                mm = m
                for _ in range(exp10 - 22):
                    if mm > _MAX_EXACT // 10:
                        ok = False
                        break
                    mm *= 10
                if ok:
                    v = float(mm) * pow10[22]
            else:
                ok = False
    return (-v if neg else v), i, ok


@njit(inline="always")
def _parse_line(buf, s, e, ncols, out, base, stride, drow, pow10):
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
        v, i, ok = _number(buf, i, e, pow10)
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
        status[r] = _parse_line(buf, starts[r], ends[r], ncols, out, base, stride, dest[r], POW10)


@njit_parallel
def gather_rows(data, order, cols, out):
    """``out[r, k] = data[order[r], cols[k]]`` (row reordering and column selection at once)."""
    m = cols.shape[0]
    for r in prange(order.shape[0]):
        src = order[r]
        for k in range(m):
            out[r, k] = data[src, cols[k]]

