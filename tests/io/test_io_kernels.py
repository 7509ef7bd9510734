"""The numba number parser agrees with Python's correctly rounded float() on every token."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bedstruct.io._kernels import parse_rows


def parse(lines, ncols):
    body = ("\n".join(lines)).encode()
    buf = np.frombuffer(body, dtype=np.uint8)
    nl = np.flatnonzero(buf == 10)
    ends = np.append(nl, buf.size).astype(np.int64)
    starts = np.concatenate([[0], nl + 1]).astype(np.int64)
    out = np.full((len(lines), ncols), -999.0)
    status = np.empty(len(lines), dtype=np.int8)
    parse_rows(buf, starts, ends, ncols, out.reshape(-1), np.arange(ncols), np.full(ncols, ncols),
               np.arange(len(lines)), status)
    return out, status


def _fmt(x, style):
    return {"g": "%g", "r": "%r", "e": "%.10e", "f": "%.8f", "17": "%.17g"}[style] % x


tokens = st.one_of(
    st.builds(_fmt, st.floats(allow_nan=False, allow_infinity=False), st.sampled_from("gref")),
    st.builds(_fmt, st.floats(min_value=-1e30, max_value=1e30), st.sampled_from(["17", "g"])),
    st.integers(-10 ** 20, 10 ** 20).map(str),
    st.from_regex(r"\A[+-]?[0-9]{0,20}\.?[0-9]{0,25}([eE][+-]?[0-9]{1,3})?\Z").filter(bool),
)


@settings(max_examples=150, deadline=None)
@given(st.lists(st.lists(tokens, min_size=3, max_size=3), min_size=1, max_size=8))
def test_fast_path_is_exact_and_flags_the_rest(rows):
    out, status = parse([" ".join(r) + "  " for r in rows], 3)
    for r, row in enumerate(rows):
        try:
            expected = [float(t) for t in row]
        except ValueError:
            assert status[r] == 2  # malformed token: handed to the general parser
            continue
        if status[r] == 0:
            assert out[r].tolist() == expected, row  # bit-identical, incl. the sign of zero
            assert [np.signbit(v) for v in out[r]] == [np.signbit(v) for v in expected]
        else:
            assert status[r] == 2


def test_counts_and_typical_dump_numbers():
    out, status = parse(["1 2 3", "1 2", "1 2 3 4", "  -0.0328584 1e-05 4.53791e-05 ", "",
                         "nan 1 2", "1.0.0 2 3"], 3)
    assert status.tolist() == [0, 1, 1, 0, 1, 2, 2]
    assert out[3].tolist() == [-0.0328584, 1e-05, 4.53791e-05]


def test_scatter_layout():
    """Columns go straight into separate (N,) and (N, 3) blocks, rows to any destination."""
    lines = ["3 1.5 2.5 3.5", "1 4.5 5.5 6.5", "2 7.5 8.5 9.5"]
    body = "\n".join(lines).encode()
    buf = np.frombuffer(body, dtype=np.uint8)
    nl = np.flatnonzero(buf == 10)
    ends = np.append(nl, buf.size).astype(np.int64)
    starts = np.concatenate([[0], nl + 1]).astype(np.int64)
    st = np.empty(3, dtype=np.int8)
    flat = np.full(12, -1.0)
    dest = np.array([2, 0, 1])  # row r goes to position id - 1
    parse_rows(buf, starts, ends, 4, flat, np.array([0, 3, 4, 5]), np.array([1, 3, 3, 3]),
               dest, st)
    assert st.tolist() == [0, 0, 0]
    assert flat[:3].tolist() == [1, 2, 3]
    assert flat[3:].reshape(3, 3).tolist() == [[4.5, 5.5, 6.5], [7.5, 8.5, 9.5], [1.5, 2.5, 3.5]]


# --- exactness of the 17-19 digit (Eisel-Lemire) path: fuzz against Python's float ---------

DBL_MIN, DBL_MAX = 2.2250738585072014e-308, 1.7976931348623157e308

HARD = [
    "9007199254740993", "9007199254740995", "9007199254740992.5", "18014398509481985",
    "2.2250738585072011e-308", "2.2250738585072012e-308", "2.2250738585072014e-308",
    "2.225073858507201e-308", "2.2250738585072009e-308", "1.7976931348623157e308",
    "1.7976931348623158e308", "1.7976931348623159e308", "-1.7976931348623157e308",
    "5e-324", "4.9406564584124654e-324", "2.4703282292062327e-324", "1e-400", "1e400",
    "0.1", "0.2", "0.3", "1e23", "8.98846567431158e307", "8.988465674311579e307",
    "8.9884656743115795e307", "8.98846567431158e+307", "4.35679719257803e-10",
    "7.2057594037927933e16", "123456789012345678", "1234567890123456789",
    "12345678901234567890", "9223372036854775807", "9223372036854775808",
    "18446744073709551615", "18446744073709551616", "1.8446744073709551615e19",
    "0.000000000000000000000000000000000001234567890123456789", "1e-342", "1e-343",
    "1e308", "1e309", "1e-307", "1e-308", "1e-309", "1e22", "1e-22", "9e22", "123e-400",
    "4503599627370496.5", "4503599627370497.5", "561351655411023.25", "-8672367567484189.0",
    "9007199254740993.0e0", "900719925474099.3e1", "0.9007199254740993e16",
    "2.9802322387695312e-8", "2.98023223876953125e-8", "1.00000000000000011102230246251565404",
    "1.0000000000000001110223024625156540", "1.000000000000000111", "0.1e-999999", "1e99999",
    "0e99999", "-0", "-0.0", "+0.0e-5", "00000000000000000000000001", "-.5", "5.", "+.5e1",
]


def _sig_digits(tok):
    t = tok.lstrip("+-").split("e")[0].split("E")[0].replace(".", "").lstrip("0")
    return len(t)


def _read_all(tokens):
    """Values of ``tokens`` as the readers produce them: the kernel, then the general
    parser for flagged tokens. Also returns the kernel's status per token."""
    out, status = parse(tokens, 1)
    out = out[:, 0].copy()
    for r in np.flatnonzero(status != 0):
        out[r] = float(tokens[r])
    return out, status


def _check(tokens, *, fast_when_normal=True):
    got, status = _read_all(tokens)
    expected = np.array([float(t) for t in tokens])
    bad = np.flatnonzero(got.view(np.uint64) != expected.view(np.uint64))
    assert bad.size == 0, [(tokens[i], got[i], expected[i], status[i]) for i in bad[:10]]
    bad_fast = np.flatnonzero((status == 0) & (got.view(np.uint64) != expected.view(np.uint64)))
    assert bad_fast.size == 0
    if fast_when_normal:
        # every token of at most 19 significant digits whose value is a normal double
        # takes a fast path (only subnormals, overflow and longer tokens go slow; values
        # just below DBL_MIN that round up to it may go either way)
        slow = [tokens[i] for i in np.flatnonzero(status != 0)
                if _sig_digits(tokens[i]) <= 19 and DBL_MIN < abs(expected[i]) <= DBL_MAX]
        assert not slow, slow[:10]
    return status


def _random_doubles(rng, n):
    """Doubles from random bit patterns: both signs, every binary exponent
    (subnormals included), no nan/inf."""
    bits = rng.integers(0, 2 ** 64, n, dtype=np.uint64, endpoint=False)
    x = bits.view(np.float64)
    return x[np.isfinite(x)]


def test_fuzz_random_doubles_all_formats_bit_identical():
    rng = np.random.default_rng(20240611)
    x = _random_doubles(rng, 20000)
    # plus typical DEM magnitudes (most of the mass of real dumps)
    y = np.concatenate([rng.uniform(-0.05, 0.05, 5000), rng.normal(0, 1e-3, 5000),
                        rng.normal(0, 10, 5000), rng.uniform(1e-5, 3e-5, 5000)])
    vals = np.concatenate([x, y]).tolist()
    tokens = []
    for fmt in ("%r", "%.17g", "%.16g", "%.15g", "%.9g", "%.6g", "%.17e", "%.18e"):
        tokens += [fmt % v for v in vals]
    assert len(tokens) >= 200_000
    status = _check(tokens)
    assert (status == 0).mean() > 0.99


def test_fuzz_near_the_limits():
    """Neighbours of DBL_MIN, DBL_MAX, 2**53 and of powers of two across the range."""
    vals = []
    for centre in [DBL_MIN, DBL_MAX, 2.0 ** 53, 2.0 ** 63, 2.0 ** 64, 1e23, 1e-5, 1.0,
                   5e-324, 8.98846567431158e307] + [2.0 ** k for k in range(-1074, 1024, 7)]:
        x = np.float64(centre)
        for direction in (np.inf, -np.inf):
            y = x
            for _ in range(6):
                with np.errstate(over="ignore"):
                    y = np.nextafter(y, direction)
                vals.append(float(y))
        vals.append(float(x))
    vals = [v for v in vals if np.isfinite(v)]
    tokens = []
    for v in vals:
        for fmt in ("%r", "%.17g", "%.16g", "%.15g", "%.18g", "%.19g", "%.20g", "%.25g"):
            tokens += [fmt % v, fmt % -v]
    _check(tokens)


def test_fuzz_exact_dyadics_and_halfway_points():
    """Values with a terminating binary fraction written in full (the cases where the
    truncated power of ten alone cannot decide) and exact ties between two doubles,
    rounded to even."""
    rng = np.random.default_rng(7)
    tokens = []
    for _ in range(20000):
        m = int(rng.integers(2 ** 52, 2 ** 53))
        k = int(rng.integers(-40, 30))
        for num, den_pow in ((m, -k), (2 * m + 1, 1 - k)):  # the double, the tie above it
            if den_pow <= 0:
                s = str(num << -den_pow)
            else:  # num / 2**den_pow = num * 5**den_pow / 10**den_pow, exactly
                digits = str(num * 5 ** den_pow).rjust(den_pow + 1, "0")
                s = digits[:-den_pow] + "." + digits[-den_pow:]
            tokens.append(s)
            tokens.append(("-" if rng.integers(2) else "") + s)
        tokens.append("%.17g" % (m * 2.0 ** k))
    _check(tokens)


def test_fuzz_18_19_20_digit_tokens():
    """Random digit strings of 18, 19 and 20 significant digits with a decimal point
    anywhere and exponents across the range (20 digits: the general parser)."""
    rng = np.random.default_rng(11)
    tokens = []
    for _ in range(30000):
        n = int(rng.integers(18, 21))
        digits = str(int(rng.integers(1, 10))) + "".join(map(str, rng.integers(0, 10, n - 1)))
        p = int(rng.integers(0, n + 1))
        mant = digits[:p] + "." + digits[p:] if p < n else digits
        ex = int(rng.integers(-340, 300))
        tokens.append(f"{'-' if rng.integers(2) else ''}{mant}e{ex}")
        tokens.append(mant)
    status = _check(tokens)
    long_ = np.array([_sig_digits(t) > 19 for t in tokens])
    assert (status[long_] == 2).all()


def test_hard_cases():
    _check(HARD)
    out, status = parse(["9007199254740993", "1e23", "8.98846567431158e307", "0.1",
                         "2.2250738585072014e-308", "1.7976931348623157e308",
                         "561351655411023.25"], 1)
    assert status.tolist() == [0] * 7
    assert out[:, 0].tolist() == [9007199254740992.0, 1e23, 8.98846567431158e307, 0.1,
                                  2.2250738585072014e-308, 1.7976931348623157e308,
                                  561351655411023.25]


def test_tables_are_exact():
    from fractions import Fraction

    from bedstruct.io._kernels import EL_MAX_EXP10, EL_MIN_EXP10, POW2, POW10_HI, POW10_LO
    for q in (EL_MIN_EXP10, -300, -28, -27, -1, 0, 1, 27, 28, 55, 56, 300, EL_MAX_EXP10):
        t = (int(POW10_HI[q - EL_MIN_EXP10]) << 64) | int(POW10_LO[q - EL_MIN_EXP10])
        assert 2 ** 127 <= t < 2 ** 128
        e = ((217706 * q) >> 16) - 127
        exact = Fraction(10) ** q / Fraction(2) ** e
        assert t <= exact < t + 1  # truncated, never rounded up
    assert POW2[1] == 5e-324 and POW2[1075] == 1.0 and POW2[2046] == 2.0 ** 971


def test_write_dump_17_digits_reads_back_bit_identical(tmp_path, monkeypatch):
    """A dump written by write_dump (shortest round-trip repr, up to 17 digits) reads back
    bit-identically, entirely through the kernel's fast paths."""
    from bedstruct import Box, Frame, read_dump, write_dump
    from bedstruct.io import _stream, _text

    def no_general_parser(*args, **kwargs):
        raise AssertionError("a token took the general parser")

    for mod in (_text, _stream):
        monkeypatch.setattr(mod, "general_block", no_general_parser)
        monkeypatch.setattr(mod, "parse_token", no_general_parser)
    rng = np.random.default_rng(3)
    n = 3000
    box = Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.15], boundary="pp pp ff")
    pos = box.cartesian(rng.uniform(0, 1, (n, 3)))
    pos[:5] = [[0.1 - 0.05, 0.0, 0.0], [1e-300, -1e-300, 2.0 ** -1000],
               [561351655411023.25, -8672367567484189.0, 9007199254740992.0],
               [1e23, 8.98846567431158e307, DBL_MIN], [DBL_MAX, -DBL_MAX, 0.1]]
    frame = Frame(pos, rng.uniform(1e-5, 3e-5, n), box=box, timestep=1000,
                  ids=rng.permutation(n) + 1, types=rng.integers(1, 3, n),
                  velocities=rng.normal(0, 0.1, (n, 3)),
                  forces=rng.normal(0, 1e-3, (n, 3)) * 10.0 ** rng.integers(-200, 200, (n, 1)),
                  omegas=rng.normal(0, 10, (n, 3)))
    path = tmp_path / "dump17.liggghts"
    write_dump(path, frame)
    got = read_dump(path)[0]
    ref = frame.sorted_by_id()
    for name in ("positions", "radii", "velocities", "forces", "omegas"):
        a, b = getattr(ref, name), getattr(got, name)
        assert a.view(np.uint64).tolist() == b.view(np.uint64).tolist(), name
    np.testing.assert_array_equal(got.ids, ref.ids)
