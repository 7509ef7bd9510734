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
