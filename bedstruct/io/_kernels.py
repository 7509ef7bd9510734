"""Numba kernels for parsing whitespace-separated numbers in dump files.

Numbers are converted with Clinger's fast path: a decimal with at most 19
significant digits, a mantissa ``m <= 2**53`` and a power of ten ``|e| <= 22``
becomes ``m * 10**e`` (or ``m / 10**-e``) in one IEEE operation on exact
operands, which is the correctly rounded result (the same value ``strtod`` and
Python's ``float`` give). Tokens outside the fast path (more digits, ``nan``,
``inf``, malformed text) are flagged so that the caller re-parses their line
with an exact general parser; the kernel never guesses.
"""

from __future__ import annotations

import numpy as np

from .._numba import njit, njit_parallel, prange

__all__ = ["parse_rows", "POW10"]

#: Exactly representable powers of ten, 1e0 .. 1e22.
POW10 = np.array([10.0 ** k for k in range(23)], dtype=np.float64)

_MAX_EXACT = 9007199254740992  # 2**53

#: Row status codes returned by :func:`parse_rows`.
OK, BAD_COUNT, SLOW = 0, 1, 2


@njit(inline="always")
def _parse_line(buf, s, e, ncols, out, r, pow10):
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
        neg = False
        c = buf[i]
        if c == 45:
            neg = True
            i += 1
        elif c == 43:
            i += 1
        m = np.int64(0)
        nd = 0
        exp10 = 0
        any_digit = False
        inexact = False
        ok = True
        while i < e and buf[i] >= 48 and buf[i] <= 57:
            d = np.int64(buf[i] - 48)
            any_digit = True
            if nd < 18:
                if m > 0 or d > 0:
                    m = m * 10 + d
                    nd += 1
            else:
                exp10 += 1
                if d != 0:
                    inexact = True
            i += 1
        if i < e and buf[i] == 46:
            i += 1
            while i < e and buf[i] >= 48 and buf[i] <= 57:
                d = np.int64(buf[i] - 48)
                any_digit = True
                if nd < 18:
                    if m > 0 or d > 0:
                        m = m * 10 + d
                        nd += 1
                    exp10 -= 1
                elif d != 0:
                    inexact = True
                i += 1
        if not any_digit:
            ok = False
        if ok and i < e and (buf[i] == 101 or buf[i] == 69):
            i += 1
            eneg = False
            if i < e and buf[i] == 45:
                eneg = True
                i += 1
            elif i < e and buf[i] == 43:
                i += 1
            ex = 0
            edig = False
            while i < e and buf[i] >= 48 and buf[i] <= 57:
                if ex < 100000:
                    ex = ex * 10 + (buf[i] - 48)
                edig = True
                i += 1
            if not edig:
                ok = False
            exp10 += -ex if eneg else ex
        if i < e and buf[i] > 32:
            ok = False
            while i < e and buf[i] > 32:
                i += 1
        v = np.nan
        if not ok or inexact:
            slow = True
        elif m == 0:
            v = 0.0
        else:
            if m > _MAX_EXACT:
                while m % 10 == 0:
                    m //= 10
                    exp10 += 1
            if m > _MAX_EXACT:
                slow = True
            elif exp10 == 0:
                v = float(m)
            elif exp10 > 0 and exp10 <= 22:
                v = float(m) * pow10[exp10]
            elif exp10 < 0 and exp10 >= -22:
                v = float(m) / pow10[-exp10]
            elif exp10 > 22 and exp10 <= 37:
                # m * 10**(exp10-22) may still be an exact integer
                mm = m
                k = exp10 - 22
                exact = True
                for _ in range(k):
                    if mm > _MAX_EXACT // 10:
                        exact = False
                        break
                    mm *= 10
                if exact:
                    v = float(mm) * pow10[22]
                else:
                    slow = True
            else:
                slow = True
        out[r, col] = -v if neg else v
        col += 1
    if col != ncols:
        return 1
    return 2 if slow else 0


@njit_parallel
def parse_rows(buf, starts, ends, ncols, out, status):
    """Parse ``ncols`` numbers from each line ``buf[starts[r]:ends[r]]`` into ``out[r]``.

    ``status[r]`` becomes 0 (parsed exactly), 1 (wrong number of values) or
    2 (a token needs the general parser: re-parse the line).
    """
    for r in prange(starts.shape[0]):
        status[r] = _parse_line(buf, starts[r], ends[r], ncols, out, r, POW10)
