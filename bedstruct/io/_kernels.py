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

Two readers of lines share those paths. :func:`parse_lines` walks a span of
text token by token: it finds each token's extent from the separators among its
first 16 characters, reads a token of up to 15 characters (every ``%g`` number)
from those characters alone (:func:`_short_token`) and longer ones eight
characters at a time (:func:`_short_number`); it is serial and releases the
GIL, so the orchestrators run it on several threads over separate spans or
pieces of a frame, and it refuses a span with any irregular line.
:func:`parse_rows` takes lines by their bounds and reports, row by row, which
are irregular (the exact error messages are built from that). Putting the
parsed rows in id order is the work of :mod:`bedstruct.io._order_kernels`.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba.core import types
from numba.cpython.unsafe.numbers import trailing_zeros as _trailing_zeros
from numba.extending import intrinsic

from .._numba import njit, njit_parallel, prange

__all__ = ["parse_rows", "parse_lines", "count_lines", "POW10_INT", "POW10", "POW10_HI", "POW10_LO", "POW5", "POW2",
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
def _b(buf, i):
    """``buf[i]`` for ``0 <= i < len(buf)``, indexed as unsigned: no negative-index
    wraparound test, so neighbouring loads can merge into one."""
    return buf[np.uint64(i)]


@njit(inline="always")
def _digits(buf, i, e, m):
    """Append the decimal digits starting at ``_b(buf, i)`` to the uint64 ``m``: (m, index after
    them). Exact while ``m`` has at most 19 digits."""
    while i < e:
        d = np.int64(_b(buf, i)) - 48
        if d < 0 or d > 9:
            break
        m = m * _U10 + np.uint64(d)
        i += 1
    return m, i


@njit(inline="always")
def _zeros(buf, i, e):
    """Index after the '0' characters starting at ``_b(buf, i)``."""
    while i < e and _b(buf, i) == 48:
        i += 1
    return i


@intrinsic
def _mul128(typingctx, a, b):
    """The 128-bit product of two uint64 as (high, low) words: one 64 x 64 -> 128-bit
    multiplication."""
    def codegen(context, builder, sig, args):
        i64, i128 = ir.IntType(64), ir.IntType(128)
        x, y = (builder.zext(context.cast(builder, v, t, types.uint64), i128)
                for v, t in zip(args, sig.args))
        p = builder.mul(x, y)
        hi = builder.trunc(builder.lshr(p, ir.Constant(i128, 64)), i64)
        return context.make_tuple(builder, sig.return_type, [hi, builder.trunc(p, i64)])
    return types.UniTuple(types.uint64, 2)(a, b), codegen


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
def _decimal_value(m, exp10, pow10, pow10_hi, pow10_lo, pow5, pow2):
    """The double nearest ``m * 10**exp10`` (``m`` an unsigned decimal mantissa), and whether
    it was found: exactly by Clinger's fast path (``m`` below 2**53, ``|exp10| <= 22``: one
    correctly rounded multiplication or division), else by Eisel-Lemire, which declines
    (``ok`` False) the rare cases it cannot round with certainty."""
    if m == _U0:
        return 0.0, True
    if m <= _MAX_EXACT and exp10 >= -22 and exp10 <= 22:
        if exp10 < 0:
            return float(m) / pow10[-exp10], True
        return float(m) * pow10[exp10], True
    return _eisel_lemire(m, exp10, pow10_hi, pow10_lo, pow5, pow2)


@njit(inline="always")
def _number(buf, i, e, pow10, pow10_hi, pow10_lo, pow5, pow2):
    """Parse the token starting at ``_b(buf, i)``: returns (value, index after it, exact)."""
    neg = False
    c = _b(buf, i)
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
    if i < e and _b(buf, i) == 46:
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
    if i < e and (_b(buf, i) == 101 or _b(buf, i) == 69):
        i += 1
        eneg = False
        if i < e and _b(buf, i) == 45:
            eneg = True
            i += 1
        elif i < e and _b(buf, i) == 43:
            i += 1
        ex = 0
        t4 = i
        while i < e:
            d = np.int64(_b(buf, i)) - 48
            if d < 0 or d > 9:
                break
            if ex < 100000:
                ex = ex * 10 + d
            i += 1
        if i == t4:
            ok = False
        exp10 += -ex if eneg else ex
    if i < e and _b(buf, i) > 32:  # junk glued to the number: the general parser decides
        ok = False
        while i < e and _b(buf, i) > 32:
            i += 1
    v = np.nan
    if ok:
        v, ok = _decimal_value(m, exp10, pow10, pow10_hi, pow10_lo, pow5, pow2)
    return (-v if neg else v), i, ok


@njit(inline="always")
def _parse_line(buf, s, e, ncols, out, base, stride, drow, pow10, pow10_hi, pow10_lo,
                pow5, pow2):
    col = 0
    slow = False
    i = s
    while True:
        while i < e and _b(buf, i) <= 32:
            i += 1
        if i >= e:
            break
        if col >= ncols:
            return 1
        v, i, ok = _number(buf, i, e, pow10, pow10_hi, pow10_lo, pow5, pow2)
        if not ok:
            slow = True
        out[np.uint64(base[col] + drow * stride[col])] = v
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


# --- short numbers: eight characters at a time ----------------------------------------------
#
# The ``%g`` numbers LAMMPS and LIGGGHTS write (``36236``, ``-0.0405453``, ``-4.41813e-05``)
# have runs of at most seven digits. :func:`_short_number` reads each run of digits as one
# 8-byte word: a mask finds how many of its characters are digits and three multiplications
# give their value (the SWAR method of fast_float), so a number costs a few branches that do
# not depend on its length. Zeros before the first nonzero digit (``0.00083094380215304``) are
# not counted against the 19 significant digits a uint64 holds. Anything it does not take (a run
# reaching the end of the text, more than 19 significant digits, exponents of more than three
# digits, nan, inf, junk) goes to :func:`_number`.

@intrinsic
def _byte(typingctx, address, i):
    """The byte at memory address ``address + i``, as an int64 (no bounds check)."""
    def codegen(context, builder, sig, args):
        base = builder.inttoptr(args[0], ir.IntType(8).as_pointer())
        k = context.cast(builder, args[1], sig.args[1], types.intp)
        return builder.zext(builder.load(builder.gep(base, [k])), ir.IntType(64))
    return types.int64(address, i), codegen


@intrinsic
def _word(typingctx, address, i):
    """The 8 bytes at memory address ``address + i`` as one little-endian uint64 (first
    byte lowest; an unaligned load, no bounds check)."""
    def codegen(context, builder, sig, args):
        base = builder.inttoptr(args[0], ir.IntType(8).as_pointer())
        k = context.cast(builder, args[1], sig.args[1], types.intp)
        at = builder.bitcast(builder.gep(base, [k]), ir.IntType(64).as_pointer())
        return builder.load(at, align=1)
    return types.uint64(address, i), codegen


#: Powers of ten 10**0 .. 10**8 as integers.
POW10_INT = np.array([10 ** k for k in range(9)], dtype=np.uint64)

_U8 = np.uint64(8)
_U16 = np.uint64(16)
_B64_0F = np.uint64(0x0F0F0F0F0F0F0F0F)
_B64_F0 = np.uint64(0xF0F0F0F0F0F0F0F0)
_B64_30 = np.uint64(0x3030303030303030)
_B64_06 = np.uint64(0x0606060606060606)
_B64_33 = np.uint64(0x3333333333333333)
_B64_7F = np.uint64(0x7F7F7F7F7F7F7F7F)
_B64_80 = np.uint64(0x8080808080808080)
_B64_FF00 = np.uint64(0x00FF00FF00FF00FF)
_B64_FFFF = np.uint64(0x0000FFFF0000FFFF)
_MUL1 = np.uint64(2561)             # 10 * 2**8 + 1
_MUL2 = np.uint64(6553601)          # 100 * 2**16 + 1
_MUL3 = np.uint64(42949672960001)   # 10000 * 2**32 + 1


@njit(inline="always")
def _digit_run(w):
    """(k, value): the number of leading ASCII digits of the 8 characters ``w`` (first
    character in the lowest byte) and the value of those ``k`` digits."""
    # a byte is a digit when its high nibble is 3 and adding 6 keeps it 3 (0x30-0x39); a carry
    # out of a byte >= 0xFA only reaches the bytes after that non-digit
    t = (w & _B64_F0) | (((w + _B64_06) & _B64_F0) >> np.uint64(4))
    y = t ^ _B64_33                                  # zero bytes: digits
    nz = (((y & _B64_7F) + _B64_7F) | y) & _B64_80   # 0x80 in every non-digit byte
    k = 8
    if nz != _U0:
        k = np.int64(_trailing_zeros(nz)) >> 3
    # the k digits moved to the top bytes (zeros, read as leading zero digits, below them)
    v = (w << np.uint64((64 - 8 * k) & 63)) if k > 0 else _U0
    v = ((v & _B64_0F) * _MUL1) >> _U8
    v = ((v & _B64_FF00) * _MUL2) >> _U16
    v = ((v & _B64_FFFF) * _MUL3) >> _U32
    return k, v


@njit(inline="always")
def _mantissa_run(address, i, e, m, nd, ns):
    """Append the digits at ``address + i`` to ``m`` eight at a time: (m, digits so far,
    significant digits so far, index after them, ok). Zeros before the first nonzero digit
    are digits but not significant ones (``0.00123`` has six digits, three significant), so
    that ``m`` holds at most ``ns`` digits. ``ok`` is False when a word would reach past
    ``e``."""
    while True:
        if i + 8 > e:
            return m, nd, ns, i, False
        w = _word(address, i)
        k, v = _digit_run(w)
        if m == _U0:  # the '0' characters that open the word are not significant
            z = w ^ _B64_30
            lz = 8 if z == _U0 else np.int64(_trailing_zeros(z)) >> 3
            ns += k - min(lz, k)
        else:
            ns += k
        m = m * POW10_INT[k] + v
        nd += k
        i += k
        if k < 8:
            return m, nd, ns, i, True


@njit(inline="always")
def _short_number(address, i, e):
    """Parse the token at ``address + i`` (``i < e``, the text readable up to ``address +
    e``) when it is a short decimal number: (value, index after it, ok); ``ok`` False
    leaves the token to :func:`_number`.

    Exact like :func:`_number`: Clinger's one-operation path for a mantissa of at most
    2**53 and a power of ten within 1e22, the Eisel-Lemire path otherwise.
    """
    c = _byte(address, i)
    neg = c == 45
    if c == 45 or c == 43:
        i += 1
    m, nd, ns, i, ok = _mantissa_run(address, i, e, _U0, 0, 0)
    if not ok:
        return 0.0, i, False
    exp10 = 0
    if i < e and _byte(address, i) == 46:
        i += 1
        m, nd, ns, j, ok = _mantissa_run(address, i, e, m, nd, ns)
        if not ok:
            return 0.0, i, False
        exp10 = i - j
        i = j
    if nd == 0 or ns > 19:
        return 0.0, i, False
    if i < e and (_byte(address, i) == 101 or _byte(address, i) == 69):
        i += 1
        eneg = False
        if i < e and (_byte(address, i) == 45 or _byte(address, i) == 43):
            eneg = _byte(address, i) == 45
            i += 1
        ex = 0
        t = i
        while i < e and i - t < 4:
            d = np.int64(_byte(address, i)) - 48
            if d < 0 or d > 9:
                break
            ex = ex * 10 + d
            i += 1
        if i == t or i - t == 4:
            return 0.0, i, False
        exp10 += -ex if eneg else ex
    if i < e and _byte(address, i) > 32:
        return 0.0, i, False
    v, ok = _decimal_value(m, exp10, POW10, POW10_HI, POW10_LO, POW5, POW2)
    if not ok:
        return 0.0, i, False
    return (-v if neg else v), i, True


@njit(inline="always")
def _count_lines(buf, a, b):
    """Number of newline characters in ``buf[a:b]``."""
    n = 0
    for i in range(a, b):
        n += _b(buf, i) == 10
    return n


# --- tokens of up to 15 characters: the hot path of parse_lines -----------------------------------
#
# A token's extent is found first, from the separators (bytes <= 32) among the 16 characters
# from its start, and its value is then read from those characters alone: the address of the
# next token does not wait for the value of this one, so the processor overlaps consecutive
# tokens. The characters are read through the text's address (:func:`_byte`, :func:`_word`)
# rather than through the array, so that the inlined helpers add no reference counting to
# the loop.

_B64_5F = np.uint64(0x5F5F5F5F5F5F5F5F)


@njit(inline="always")
def _separators(w):
    """0x80 in every byte of the 8 characters ``w`` that is at most 32 (space, tab,
    newline, ...), 0 in the others."""
    # (c & 0x7F) + 0x5F sets the high bit from c & 0x7F >= 0x21 on, without a carry out
    return ~(((w & _B64_7F) + _B64_5F) | w) & _B64_80


@njit(inline="always")
def _token_length(address, i):
    """Characters before the first separator among the 16 at ``address + i`` (0 to 15);
    16 when there is none."""
    s1 = _separators(_word(address, i))
    s2 = _separators(_word(address, i + 8))
    n2 = 16 if s2 == _U0 else 8 + (np.int64(_trailing_zeros(s2)) >> 3)
    return (np.int64(_trailing_zeros(s1)) >> 3) if s1 != _U0 else n2


@njit(inline="always")
def _digits16(address, i, m):
    """Append the run of up to 16 digits at ``address + i`` to ``m``: (m, digits)."""
    k, v = _digit_run(_word(address, i))
    m = m * POW10_INT[k] + v
    if k == 8:
        k2, v2 = _digit_run(_word(address, i + 8))
        m = m * POW10_INT[k2] + v2
        k += k2
    return m, k


@njit(inline="always")
def _short_token(address, s, n):
    """The value of the token of ``n < 16`` characters at ``address + s`` (followed by a
    separator, 24 readable bytes from ``s`` on): (value, ok). ``ok`` is False for anything
    but an optional sign, digits with an optional point, and an exponent of one to three
    digits, and where :func:`_decimal_value` declines; the caller then reads the token with
    :func:`_short_number` and :func:`_number`."""
    c = _byte(address, s)
    neg = c == 45
    q = s + 1 if (c == 45 or c == 43) else s
    m, nd = _digits16(address, q, _U0)
    q += nd
    exp10 = 0
    if _byte(address, q) == 46:
        m, k = _digits16(address, q + 1, m)
        nd += k
        exp10 = -k
        q += 1 + k
    if nd == 0:
        return 0.0, False
    e = s + n
    if q < e:
        c = _byte(address, q)
        if c != 101 and c != 69:
            return 0.0, False
        q += 1
        c = _byte(address, q)
        eneg = c == 45
        if c == 45 or c == 43:
            q += 1
        k, ex = _digit_run(_word(address, q))
        if k == 0 or k > 3 or q + k != e:
            return 0.0, False
        exp10 += -np.int64(ex) if eneg else np.int64(ex)
    v, ok = _decimal_value(m, exp10, POW10, POW10_HI, POW10_LO, POW5, POW2)
    return (-v if neg else v), ok


@njit(inline="always")
def _parse_part(buf, a, b, ncols, out, base, stride, row, pow10, pow10_hi, pow10_lo, pow5,
                pow2):
    """Parse the whole lines of ``buf[a:b]`` as rows ``row, row + 1, ...``: the row after
    the last one, or -1 when any line is not ``ncols`` numbers the kernel reads exactly."""
    address = buf.ctypes.data
    i = a
    while i < b:
        for col in range(ncols):
            while i < b and _byte(address, i) <= 32 and _byte(address, i) != 10:
                i += 1
            if i >= b or _byte(address, i) == 10:
                return -1
            ok = False
            if i + 32 <= b:  # a token of up to 15 characters, read from its 16
                n = _token_length(address, i)
                if n < 16:
                    v, ok = _short_token(address, i, n)
                    j = i + n
            if not ok:
                v, j, ok = _short_number(address, i, b)
                if not ok:
                    v, j, ok = _number(buf, i, b, pow10, pow10_hi, pow10_lo, pow5, pow2)
                    if not ok:
                        return -1
            out[base[col] + row * stride[col]] = v
            i = j
        while i < b and _byte(address, i) <= 32 and _byte(address, i) != 10:
            i += 1
        if i < b and _byte(address, i) != 10:
            return -1
        row += 1
        i += 1
    return row


@njit
def count_lines(buf, start, stop):
    """The number of lines of ``buf[start:stop]``: its newlines, plus one for a last
    line without a newline.

    Examples
    --------
    >>> import numpy as np
    >>> count_lines(np.frombuffer(b"1 2\\n3 4\\n5 6", dtype=np.uint8), 0, 11)
    3
    """
    n = _count_lines(buf, start, stop)
    if stop > start and _b(buf, stop - 1) != 10:
        n += 1
    return n


@njit
def parse_lines(buf, start, stop, ncols, out, base, stride, row0):
    """Parse the lines of ``buf[start:stop]`` (``ncols`` numbers each) as rows ``row0...``.

    Value ``c`` of row ``r`` goes to ``out[base[c] + r * stride[c]]`` (the layout of
    :func:`parse_rows`). Every line but the last ends with a newline; the text
    should not end with blank lines, and ``out`` must hold as many rows as the
    text has lines (:func:`count_lines`). The kernel releases the GIL, so that
    threads can parse separate spans of one text at once.

    Returns the row after the last one parsed, or -1 when a line is not ``ncols``
    numbers that the kernel reads exactly (a wrong count, a blank line, ``nan``,
    more than 19 significant digits, ...): the caller then parses the text row by
    row with :func:`parse_rows` to learn which.

    Examples
    --------
    >>> import numpy as np
    >>> text = np.frombuffer(b"1 2.5 -3e-2\\n4 5 6\\n", dtype=np.uint8)
    >>> out = np.zeros(6)
    >>> parse_lines(text, 0, text.size, 3, out, np.arange(3), np.full(3, 3), 0)
    2
    >>> out.tolist()
    [1.0, 2.5, -0.03, 4.0, 5.0, 6.0]
    """
    return _parse_part(buf, start, stop, ncols, out, base, stride, row0, POW10, POW10_HI,
                       POW10_LO, POW5, POW2)
