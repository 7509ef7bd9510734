"""The short-number text parser (8 characters at a time, threads over spans and pieces)
gives exactly Python's ``float()``, bit for bit, and the same frames as the exact path."""

from __future__ import annotations

import re

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bedstruct.io import _kernels as K
from bedstruct.io._text import parse_lines_threaded, parse_token


@numba.njit
def short_number(text):
    """The short-number path alone on the token at ``text[0]``: (value, end, ok)."""
    return K._short_number(text.ctypes.data, 0, text.shape[0])


@numba.njit
def digit_run(word):
    """(leading digits, their value) of the 8 characters ``word``."""
    return K._digit_run(K._word(word.ctypes.data, 0))


DBL_MIN = 2.2250738585072014e-308
PAD = b" " * 24 + b"\n"


def bits(x) -> int:
    return int(np.float64(x).view(np.int64))


def as_text(s: str) -> np.ndarray:
    return np.frombuffer(s.encode("latin-1"), dtype=np.uint8)


# --- the 8-character digit runs -------------------------------------------------------------

def test_digit_run_every_length_and_terminator():
    rng = np.random.default_rng(5)
    for k in range(9):
        for stop in list(range(256)) + [48] * 4:
            digits = "".join(str(d) for d in rng.integers(0, 10, k))
            word = (digits.encode() + bytes([stop]) * 8)[:8]
            got_k, got_v = digit_run(np.frombuffer(word, dtype=np.uint8))
            want_k = len(word) - len(word.lstrip(b"0123456789"))
            assert got_k == want_k, (word, got_k)
            assert got_v == (int(word[:want_k]) if want_k else 0), word


# --- single tokens: the fast path alone, then the kernel with its fallback -------------------

def _fmt(x, style):
    return {"g": "%g", "g6": "%.6g", "g9": "%.9g", "e": "%e", "E": "%E", "f": "%f",
            "r": "%r", "17": "%.17g"}[style] % x


finite = st.floats(allow_nan=False, allow_infinity=False)
tokens = st.one_of(
    st.builds(_fmt, finite, st.sampled_from(["g", "g6", "g9", "e", "E", "f", "r", "17"])),
    st.builds(_fmt, st.floats(-1e3, 1e3), st.sampled_from(["g", "g6", "f", "r"])),
    st.integers(-10 ** 22, 10 ** 22).map(str),
    st.integers(-10 ** 7, 10 ** 7).map(str),
    st.sampled_from(["-0", "-0.0", "0", "+0", "0.0", "-0e5", "0e-400", "-0.000000000000"]),
    st.from_regex(r"\A[+-]?[0-9]{0,24}\.?[0-9]{0,24}([eE][+-]?[0-9]{1,5})?\Z").filter(bool),
    st.from_regex(r"\A-?[0-9]{1,7}(\.[0-9]{1,7})?(e[+-][0-9]{2,3})?\Z"),
)


@settings(max_examples=400, deadline=None)
@given(tokens)
def test_short_number_is_float_bit_for_bit(tok):
    text = as_text(tok + PAD.decode())
    v, end, ok = short_number(text)
    try:
        want = float(tok)
    except ValueError:
        assert not ok, tok
        return
    if ok:
        assert end == len(tok), tok
        assert bits(v) == bits(want), (tok, v, want)  # the sign of zero included
    digits = tok.lstrip("+-").split("e")[0].split("E")[0].replace(".", "")
    ordinary = (len(digits) <= 14 and "e" not in tok.lower() or
                len(digits) <= 14 and len(tok.lower().split("e")[1].lstrip("+-")) <= 3)
    if ordinary and (not digits.strip("0") or DBL_MIN < abs(want) < 1e300):
        assert ok, tok  # the short path takes every ordinary number, not only the easy ones


@settings(max_examples=300, deadline=None)
@given(tokens)
def test_parse_lines_token_is_float_or_refused(tok):
    """Through the kernel (short path, then the 19-digit path): one token per line."""
    for text in (tok, tok + PAD.decode() + "7"):
        arr = as_text(text)
        out = np.full(2, -999.0)
        got = K.parse_lines(arr, 0, arr.size, 1, out, np.zeros(1, np.int64),
                            np.ones(1, np.int64), 0)
        try:
            want = parse_token(tok)
        except ValueError:
            assert got == -1, tok
            continue
        if got != -1:
            assert bits(out[0]) == bits(want), (tok, out[0], want)


@numba.njit
def short_token(text):
    """The path of tokens of up to 15 characters alone on the token at ``text[0]``:
    (value, length found, ok)."""
    address = text.ctypes.data
    n = K._token_length(address, 0)
    if n == 16:
        return 0.0, n, False
    v, ok = K._short_token(address, 0, n)
    return v, n, ok


_PLAIN = re.compile(r"\A[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]{1,3})?\Z")


@settings(max_examples=400, deadline=None)
@given(tokens)
def test_short_token_is_float_bit_for_bit(tok):
    v, n, ok = short_token(as_text(tok + PAD.decode() + "1" * 8))
    assert n == min(len(tok), 16), tok  # the token ends at the first separator
    try:
        want = float(tok)
    except ValueError:
        assert not ok, tok
        return
    if ok:
        assert bits(v) == bits(want), (tok, v, want)  # the sign of zero included
    digits = tok.lstrip("+-").split("e")[0].split("E")[0].replace(".", "")
    if len(tok) < 16 and _PLAIN.match(tok) and (not digits.strip("0") or
                                                DBL_MIN < abs(want) < 1e300):
        assert ok, tok  # every plain decimal token of up to 15 characters takes this path


def test_short_token_refuses_what_is_not_a_plain_number():
    for tok in ["nan", "inf", "-inf", "1e5000", "1e-0300", "1.0.0", "1x", "--1", "1e", "1e+",
                ".", "-", "+", "e5", "0x10", "1-2", "1e-320", "1.5e+310"]:
        v, n, ok = short_token(as_text(tok + PAD.decode()))
        assert n == len(tok) and not ok, tok
    for tok in ["123456789012345", "-1.234567890e-5", "+.5", "5.", "-0", "900719925474099"]:
        v, n, ok = short_token(as_text(tok + PAD.decode()))
        assert ok and n == len(tok) and bits(v) == bits(float(tok)), tok


@settings(max_examples=300, deadline=None)
@given(st.lists(tokens, min_size=1, max_size=6), st.integers(1, 3))
def test_parse_lines_long_lines_token_is_float_or_refused(toks, spaces):
    """Lines long enough that every token but the last of the text is read by the path of
    tokens of up to 15 characters (longer ones by the 19-digit path)."""
    line = (" " * spaces).join(toks) + " " * 40
    arr = as_text("\n".join([line] * 3))
    out = np.full(3 * len(toks), -999.0)
    got = K.parse_lines(arr, 0, arr.size, len(toks), out, np.arange(len(toks)),
                        np.full(len(toks), len(toks)), 0)
    try:
        want = [parse_token(t) for t in toks] * 3
    except ValueError:
        assert got == -1, toks
        return
    if got != -1:
        assert got == 3
        assert out.view(np.int64).tolist() == np.array(want).view(np.int64).tolist(), toks


def test_typical_liggghts_tokens():
    toks = ["36236", "1", "0.0317048", "-0.0405453", "0.00754697", "-4.41813e-05",
            "0.00087953", "2.79263", "-2.85177", "10.2237", "2.51179e-05", "1e-05", "-0",
            "1.5e+300", "-2.2250738585072014e-308", "123456789", "0.1", "9007199254740993"]
    for tok in toks:
        v, end, ok = short_number(as_text(tok + PAD.decode()))
        assert ok and end == len(tok) and bits(v) == bits(float(tok)), tok
    for tok in ["nan", "inf", "-inf", "1e5000", "1.0.0", "1x", "--1", "1e", ".", "0x10",
                "1" * 25, "1e-320"]:
        assert not short_number(as_text(tok + PAD.decode()))[2], tok


@settings(max_examples=300, deadline=None)
@given(st.floats(1e-4, 1e-2), st.booleans())
def test_short_number_takes_round_trip_reprs_with_leading_zeros(x, neg):
    """``repr`` writes numbers in [1e-4, 1e-2) as ``0.00083094380215304``: up to 21 digits,
    at most 17 significant. The short path takes them (the zeros before the first nonzero
    digit are not significant) and reads them exactly."""
    tok = repr(-x if neg else x)
    v, end, ok = short_number(as_text(tok + PAD.decode()))
    assert ok and end == len(tok) and bits(v) == bits(float(tok)), tok


def test_short_number_counts_significant_digits_only():
    sig19, sig20 = "1234567890123456789", "12345678901234567891"
    for zeros in (0, 1, 3, 7, 8, 9, 17, 30):
        for tok in ("0." + "0" * zeros + sig19, "-0" * (zeros > 0) + "0" * zeros + sig19,
                    "0." + "0" * zeros + "1", "0" * zeros + "7.5e-3"):
            v, end, ok = short_number(as_text(tok + PAD.decode()))
            assert ok and end == len(tok) and bits(v) == bits(float(tok)), tok
        for tok in ("0." + "0" * zeros + sig20, "0" * zeros + sig20, sig19 + "0" * (zeros + 1)):
            assert not short_number(as_text(tok + PAD.decode()))[2], tok  # 20+ significant


# --- rows and spans ---------------------------------------------------------------------------

rows_strategy = st.lists(st.lists(tokens, min_size=4, max_size=4), min_size=1, max_size=40)


def _block(rows):
    return "\n".join(" ".join(r) + ("  " if k % 3 == 0 else "") for k, r in enumerate(rows))


@settings(max_examples=150, deadline=None)
@given(rows_strategy, st.integers(1, 5))
def test_threaded_spans_equal_float(rows, threads):
    """Lines parsed in spans on several threads: all read exactly, or refused."""
    arr = as_text(_block(rows))
    out = np.full((len(rows), 4), -999.0)
    ok = parse_lines_threaded(arr, 0, arr.size, 4, out.reshape(-1), np.arange(4),
                              np.full(4, 4), threads=threads)
    if ok:
        want = np.array([[parse_token(t) for t in r] for r in rows])
        assert out.view(np.int64).tolist() == want.view(np.int64).tolist()


def test_threaded_spans_on_a_long_text():
    rng = np.random.default_rng(8)
    vals = np.column_stack([np.arange(1, 20001), rng.normal(size=(20000, 3)),
                            rng.uniform(1e-5, 3e-5, 20000)])
    text = "\n".join("%d %g %g %g %g" % tuple(r) for r in vals.tolist())
    arr = as_text(text)
    want = np.array([[float(t) for t in line.split()] for line in text.splitlines()])
    for threads in (1, 2, 3, 8):
        out = np.empty((20000, 5))
        assert parse_lines_threaded(arr, 0, arr.size, 5, out.reshape(-1), np.arange(5),
                                    np.full(5, 5), threads=threads)
        assert out.view(np.int64).tolist() == want.view(np.int64).tolist()


def test_parse_lines_refuses_irregular_lines():
    for text in ["1 2\n3", "1 2\n\n3 4", "1 2 3\n4 5", "1 nan\n3 4", "1 2\n3 4x"]:
        arr = as_text(text)
        assert K.parse_lines(arr, 0, arr.size, 2, np.empty(4), np.arange(2), np.full(2, 2),
                             0) == -1, text
    arr = as_text("1 2\n3 4")
    assert K.count_lines(arr, 0, arr.size) == 2


# --- whole frames: the streaming reader against float() ---------------------------------------

@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("chunk", [61, 4096, 1 << 21])
def test_stream_threads_and_pieces_equal_float(tmp_path, monkeypatch, threads, chunk):
    from bedstruct import read_dump
    from bedstruct._numba import get_num_threads, set_num_threads
    from bedstruct.io import _stream
    monkeypatch.setattr(_stream, "_STREAM_CHUNK", chunk)
    rng = np.random.default_rng(threads)
    n = 3000
    data = np.column_stack([rng.permutation(n) + 1, rng.integers(1, 3, n),
                            rng.uniform(-0.05, 0.05, (n, 3)), rng.normal(0, 10, (n, 3)),
                            rng.uniform(1e-5, 3e-5, n)])
    lines = ["%d %d " % tuple(r[:2]) + " ".join("%g" % v for v in r[2:]) for r in data.tolist()]
    lines[7] = lines[7].replace(lines[7].split()[3], "-0")  # a negative zero
    p = tmp_path / "d.dump"
    p.write_text("ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n%d\nITEM: BOX BOUNDS pp pp ff\n"
                 "-1 1\n-1 1\n-1 1\nITEM: ATOMS id type x y z vx vy vz radius\n" % n
                 + "\n".join(lines) + "\n")
    want = np.array([[float(t) for t in line.split()] for line in lines])
    want = want[np.argsort(want[:, 0])]
    old = get_num_threads()
    set_num_threads(min(threads, old))
    try:
        f = read_dump(p)[0]
    finally:
        set_num_threads(old)
    assert f.ids.tolist() == list(range(1, n + 1))
    for got, cols in ((f.positions, [2, 3, 4]), (f.velocities, [5, 6, 7]), (f.radii, 8)):
        assert got.view(np.int64).tolist() == want[:, cols].view(np.int64).tolist()
    assert np.signbit(f.positions[f.ids == int(lines[7].split()[0])][0, 1])


# --- every third-party dump: the new path equals the exact path -------------------------------

def _text_dumps(root):
    return sorted(p for p in root.rglob("*") if p.is_file() and p.read_bytes()[:5] == b"ITEM:")


def _frames(path):
    """(raw frame by the reader's text path, its data rows read by Python's float()),
    for every frame but the malformed one of pygran's test/traj.dump (a count mismatch,
    see test_io_realdata)."""
    from bedstruct.errors import DumpFormatError
    from bedstruct.io._source import Source, scan_text
    from bedstruct.io._text import parse_text_frame
    src = Source(path)
    scan = scan_text(src)
    for k, start in enumerate(scan.starts):
        buf = src.read_range(start, scan.end(k) - start)
        try:
            raw = parse_text_frame(buf, path=str(path), line0=scan.lines[k],
                                   at_eof=k == len(scan.starts) - 1)
        except DumpFormatError as exc:
            assert "count mismatch" in str(exc) and path.name == "traj.dump", exc
            continue
        body = buf[raw.body_offset:].rstrip()
        rows = [[float(t) for t in ln.split()] for ln in body.decode("latin-1").split("\n")
                if ln.strip()]
        yield raw, np.array(rows, dtype=np.float64).reshape(raw.n, len(raw.names)), body
    src.close()


def test_realdata_every_frame_equals_float(realdata):
    files = _text_dumps(realdata)
    assert len(files) >= 9
    n_frames = n_values = 0
    for path in files:
        for raw, want, _ in _frames(path):
            assert raw.data.view(np.int64).tolist() == want.view(np.int64).tolist(), path
            n_frames += 1
            n_values += want.size
    assert n_frames >= 11 and n_values > 100_000


def test_realdata_blocks_take_the_short_path(realdata):
    """The numbers of the real files are the ordinary kind: the kernel reads every block
    without the row-by-row fallback, and the streaming reader gives the same frames."""
    from bedstruct import read_dump
    from bedstruct.io._text import parse_lines_threaded
    for path in _text_dumps(realdata):
        atoms = b"ITEM: ATOMS" in path.read_bytes()[:4096]
        frames = list(_frames(path))
        for k, (raw, want, body) in enumerate(frames):
            if raw.n == 0:
                continue
            arr = np.frombuffer(body, dtype=np.uint8)
            out = np.empty(want.size)
            ncols = want.shape[1]
            assert parse_lines_threaded(arr, 0, arr.size, ncols, out, np.arange(ncols),
                                        np.full(ncols, ncols), threads=2), path
            assert out.view(np.int64).tolist() == want.reshape(-1).view(np.int64).tolist()
            if atoms and "x" in raw.names:
                f = read_dump(path)[k]
                order = np.argsort(want[:, raw.names.index("id")]) if "id" in raw.names \
                    else np.arange(raw.n)
                xyz = want[order][:, [raw.names.index(c) for c in "xyz"]]
                assert f.positions.view(np.int64).tolist() == xyz.view(np.int64).tolist()


def test_dump_local_large_block_equals_float(tmp_path):
    """A contact block large enough to be parsed in one span per thread reads bit for bit
    as float() reads its text."""
    from bedstruct import Frame, read_dump_local
    rng = np.random.default_rng(4)
    n, m = 2000, 20000
    frame = Frame(rng.uniform(0, 10, (n, 3)), np.full(n, 0.1), box=[10, 10, 10],
                  ids=np.arange(1, n + 1))
    i = rng.integers(1, n + 1, m)
    j = i % n + 1
    area = rng.uniform(1e-6, 1e-4, m)
    area[5] = 1e-05
    lines = ["%d %d %g" % row for row in zip(i.tolist(), j.tolist(), area.tolist())]
    p = tmp_path / "contacts.dump"
    p.write_text("ITEM: TIMESTEP\n0\nITEM: NUMBER OF ENTRIES\n%d\nITEM: BOX BOUNDS pp pp pp\n"
                 "0 10\n0 10\n0 10\nITEM: ENTRIES c_1[1] c_1[2] c_2[1]\n" % m
                 + "\n".join(lines) + "\n")
    assert p.stat().st_size > 2 * 65536  # one span per thread
    c = read_dump_local(p, columns={"c_1[1]": "id1", "c_1[2]": "id2", "c_2[1]": "area"},
                        frames=frame)[0]
    want = np.array([float(ln.split()[2]) for ln in lines])
    assert c.n_contacts == m
    assert np.asarray(c.area).view(np.int64).tolist() == want.view(np.int64).tolist()
    assert c.i.tolist() == (i - 1).tolist() and c.j.tolist() == (j - 1).tolist()
