"""Every malformed-input case gives a DumpFormatError naming file, line and expectation."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from bedstruct import read_dump
from bedstruct.errors import BedstructWarning, DumpFormatError

from _iohelpers import _dump_text_fixture, good_rows, write  # noqa: F401 (fixtures)

# rows of the frame written by dump_text start at line 10 (9 header lines)
FIRST_ROW = 10


def _err(path, **kw) -> DumpFormatError:
    with pytest.raises(DumpFormatError) as info:
        traj = read_dump(path, **kw)
        for _ in traj:
            pass
    err = info.value
    assert isinstance(err, ValueError)
    assert err.path == str(path)
    return err


def test_truncated_last_frame_strict_and_lenient(write, dump_text, good_rows):
    text = dump_text(good_rows, step=1) + dump_text(good_rows[:2], step=2, n=3)
    p = write("trunc.dump", text)
    err = _err(p)
    assert "truncated frame" in err.message and err.line == 9 + 3 + 9 + 2 + 1
    with pytest.warns(BedstructWarning, match="truncated last frame"):
        traj = read_dump(p, strict=False)
    assert traj.timesteps.tolist() == [1]
    assert traj[0].n_particles == 3


def test_truncated_in_the_middle_of_a_line(write, dump_text, good_rows):
    text = dump_text(good_rows, step=1) + dump_text(good_rows, step=2)
    p = write("cut.dump", text[:-9])  # the last row loses its end and the newline
    err = _err(p)
    assert "truncated frame" in err.message and err.line == 9 + 3 + 9 + 3
    with pytest.warns(BedstructWarning):
        assert read_dump(p, strict=False).timesteps.tolist() == [1]


def test_truncated_header_of_next_frame(write, dump_text, good_rows):
    p = write("head.dump", dump_text(good_rows, step=1) + "ITEM: TIMES")
    err = _err(p)
    assert "cut off" in err.message and err.line == 13
    with pytest.warns(BedstructWarning):
        traj = read_dump(p, strict=False)
    assert len(traj) == 1 and traj[0].n_particles == 3
    q = write("head2.dump", dump_text(good_rows, step=1) + "ITEM: TIMESTEP\n2\nITEM: NUMB")
    assert "truncated frame" in _err(q).message
    with pytest.warns(BedstructWarning):
        assert read_dump(q, strict=False).timesteps.tolist() == [1]


def test_truncation_is_only_skipped_at_the_end(write, dump_text, good_rows):
    # a short frame followed by another frame is a count mismatch, never skipped
    text = dump_text(good_rows[:2], step=1, n=3) + dump_text(good_rows, step=2)
    p = write("mid.dump", text)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        traj = read_dump(p, strict=False)
    with pytest.raises(DumpFormatError, match="count mismatch") as info:
        traj[0]
    assert info.value.line == 12


def test_non_numeric_token(write, dump_text, good_rows):
    rows = list(good_rows)
    rows[1] = "1 2 4.0 five 6.0 0.25"
    err = _err(write("nn.dump", dump_text(rows)))
    assert "non-numeric" in err.message and err.line == FIRST_ROW + 1
    assert err.text == rows[1]
    assert "x y z" in err.message  # says what was expected


@pytest.mark.parametrize("bad,k", [("1 2 4.0 5.0 6.0", 5), ("1 2 4.0 5.0 6.0 0.25 9", 7)])
def test_wrong_number_of_values(write, dump_text, good_rows, bad, k):
    rows = list(good_rows)
    rows[1] = bad
    err = _err(write("wn.dump", dump_text(rows + ["4 1 1 1 1 0.5"], step=1) + dump_text(rows)))
    assert "wrong number of values" in err.message and f"found {k}, expected 6" in err.message
    assert err.line == FIRST_ROW + 1


def test_compensating_wrong_counts_are_caught(write, dump_text, good_rows):
    # one row short and the next one long: the total count is right, the rows are not
    rows = ["2 1 1.0 2.0 3.0", "1 2 4.0 5.0 6.0 0.25 0.5", good_rows[2]]
    err = _err(write("comp.dump", dump_text(rows)))
    assert "wrong number of values" in err.message and err.line == FIRST_ROW


def test_atom_count_mismatch(write, dump_text, good_rows):
    err = _err(write("more.dump", dump_text(good_rows + ["4 1 1 1 1 0.5"], n=3)))
    assert "count mismatch" in err.message and err.line == FIRST_ROW + 3


@pytest.mark.parametrize("radius", ["0", "-0.5", "nan", "inf"])
def test_bad_radius(write, dump_text, good_rows, radius):
    rows = list(good_rows)
    rows[2] = f"3 1 7.5 8.5 9.5 {radius}"
    err = _err(write("rad.dump", dump_text(rows)))
    assert "positive and finite" in err.message and err.line == FIRST_ROW + 2
    assert err.text == rows[2]


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_non_finite_positions(write, dump_text, good_rows, value):
    rows = list(good_rows)
    rows[0] = f"2 1 1.0 {value} 3.0 0.5"
    err = _err(write("pos.dump", dump_text(rows)))
    assert "not finite" in err.message and err.line == FIRST_ROW


def test_unknown_header_item(write, dump_text, good_rows):
    text = dump_text(good_rows).replace("ITEM: NUMBER OF ATOMS", "ITEM: NUMBER OF BANANAS")
    err = _err(write("item.dump", text))
    assert "unknown header item" in err.message and err.line == 3
    assert "ITEM: TIMESTEP" in err.message


def test_non_integer_id_and_bad_flags(write, dump_text, good_rows):
    rows = list(good_rows)
    rows[1] = "1.5 2 4.0 5.0 6.0 0.25"
    err = _err(write("id.dump", dump_text(rows)))
    assert "integers" in err.message and err.line == FIRST_ROW + 1
    err = _err(write("flags.dump", dump_text(good_rows, flags="pp xx pp")))
    assert "boundary flags" in err.message and err.line == 5
    err = _err(write("box.dump", dump_text(good_rows).replace("0 10\n", "0 ten\n", 1)))
    assert "box line" in err.message and err.line == 6


def test_not_a_dump(write):
    err = _err(write("x.dump", "hello world\nthis is not a dump\n"))
    assert err.line == 1


def test_error_line_numbers_in_later_frames_and_gz(tmp_path, dump_text, good_rows):
    import gzip
    rows = list(good_rows)
    rows[2] = "3 1 7.5 8.5 9.5 0.5 oops"
    text = "".join(dump_text(good_rows, step=s) for s in range(3)) + dump_text(rows, step=3)
    p = tmp_path / "late.dump.gz"
    with gzip.open(p, "wb") as fh:
        fh.write(text.encode())
    err = _err(p)
    assert err.line == 3 * 12 + FIRST_ROW + 2
    # the same line read with plain Python
    assert text.splitlines()[err.line - 1] == rows[2]


def test_slow_path_numbers_parse_exactly(write, dump_text):
    # 17-digit mantissas, huge exponents, nan in an extra column: the general parser is used
    rows = [f"{k} 1 0.10000000000000001 1e300 2.2250738585072014e-308 0.5 nan"
            for k in range(1, 200)]
    f = read_dump(write("slow.dump", dump_text(rows, cols="id type x y z radius c_q")))[0]
    assert f.positions[0].tolist() == [0.1, 1e300, 2.2250738585072014e-308]
    assert np.isnan(f.columns["c_q"]).all()


@pytest.mark.parametrize("chunk", [7, 64, 1 << 23])
def test_scan_is_independent_of_chunk_size(tmp_path, monkeypatch, dump_text, good_rows, chunk):
    """Frame offsets, line numbers and the kept tail do not depend on where chunks end."""
    import gzip
    from bedstruct.io import _source
    text = ("ITEM: UNITS\nsi\nITEM: TIME\n0.5\n" + dump_text(good_rows, step=1)
            + dump_text(good_rows[:1], step=22) + dump_text(good_rows, step=333))
    p = tmp_path / "chunks.dump.gz"
    with gzip.open(p, "wb") as fh:
        fh.write(text.encode())
    monkeypatch.setattr(_source, "_CHUNK", chunk)
    scan = _source.scan_text(_source.Source(p))
    lines = text.splitlines(keepends=True)
    assert scan.timesteps == [1, 22, 333] and scan.counts == [3, 1, 3]
    assert scan.lines == [0, 4 + 12, 4 + 12 + 10]
    assert scan.starts == [0, len("".join(lines[:16])), len("".join(lines[:26]))]
    assert scan.tail == text[scan.starts[-1]:].encode() and scan.size == len(text)
    traj = read_dump(p)
    assert traj[0].units.style == "si" and traj[0].time == 0.5
    assert [f.n_particles for f in traj] == [3, 1, 3]


def test_truncated_gz_last_frame(tmp_path, dump_text, good_rows):
    import gzip
    text = dump_text(good_rows, step=1) + dump_text(good_rows, step=2)
    p = tmp_path / "t.dump.gz"
    with gzip.open(p, "wb") as fh:
        fh.write(text[:-30].encode())
    with pytest.raises(DumpFormatError, match="truncated"):
        read_dump(p)
    with pytest.warns(BedstructWarning):
        assert read_dump(p, strict=False).timesteps.tolist() == [1]


def test_corrupt_gzip_stream(tmp_path, dump_text, good_rows):
    import gzip
    raw = gzip.compress((dump_text(good_rows, step=1) * 50).encode())
    p = tmp_path / "bad.dump.gz"
    p.write_bytes(raw[: len(raw) // 2])  # the compressed stream itself is cut
    with pytest.raises(DumpFormatError, match="cannot decompress"):
        read_dump(p)


def test_missing_timestep_value(write, dump_text, good_rows):
    text = dump_text(good_rows, step=1) + dump_text(good_rows, step=2).replace("\n2\n", "\n\n", 1)
    err = _err(write("nots.dump", text))
    assert "expected the timestep" in err.message and err.line == 14
    err = _err(write("bad_ts.dump", dump_text(good_rows).replace("\n0\n", "\nzero\n", 1)))
    assert "integer" in err.message and err.line == 2


def test_content_before_the_first_timestep_is_an_error(write, dump_text, good_rows):
    text = dump_text(good_rows, step=1) + dump_text(good_rows, step=2)
    missing = write("missing_ts.dump", text.replace("ITEM: TIMESTEP\n1\n", "", 1))
    for strict in (True, False):
        err = _err(missing, strict=strict)
        assert err.line == 1 and "ITEM: TIMESTEP" in err.message
        assert err.text == "ITEM: NUMBER OF ATOMS"
    err = _err(write("comment.dump", "\n\n# comment\n" + text))
    assert err.line == 3 and err.text == "# comment"
    err = _err(write("junk.dump", "ITEM: TIMESTEP is next\n" + text))
    assert err.line == 1
    # blank lines before the first frame are harmless
    assert read_dump(write("blank.dump", "\n  \n" + text)).timesteps.tolist() == [1, 2]


@pytest.mark.parametrize("token", ["1..5", "0x1p-1", "1_0", "1.0D-01", "--1"])
@pytest.mark.parametrize("n_slow", [1, 200])
def test_bad_token_names_file_line_and_token(write, dump_text, token, n_slow):
    """Rows with a token outside the fast path (nan here) go to the general parser; a bad
    token there is reported exactly as on the fast path, never read as some number."""
    n = 250
    rows = [f"{k} 1 0.5 0.5 0.5 0.01 {'nan' if k <= n_slow else '1.5'}" for k in range(1, n + 1)]
    rows[150] = f"151 1 0.5 0.5 0.5 0.01 {token}"
    err = _err(write("slowbad.dump", dump_text(rows, cols="id type x y z radius f_temp")))
    assert err.line == FIRST_ROW + 150 and err.text == rows[150]
    assert repr(token) in err.message and "f_temp" in err.message


@pytest.mark.parametrize("lines,line,match", [
    ("1 0\n0 10\n0 10\n", 6, "below"),
    ("0 10\n0 nan\n0 10\n", 7, "finite"),
    ("0 10\n0 10\n-inf 10\n", 8, "finite"),
])
def test_bad_box_bounds_name_the_line(write, dump_text, good_rows, lines, line, match):
    text = dump_text(good_rows).replace("0 10\n0 10\n0 10\n", lines, 1)
    err = _err(write("box.dump", text))
    assert err.line == line and match in err.message


def test_bad_triclinic_box_names_the_header_line(write, dump_text, good_rows):
    # a bounding box narrower than its tilt gives hi < lo once converted back
    text = dump_text(good_rows).replace("ITEM: BOX BOUNDS pp pp pp\n0 10\n",
                                        "ITEM: BOX BOUNDS xy xz yz pp pp pp\n0 10 20\n", 1)
    text = text.replace("0 10\n0 10\n", "0 10 0\n0 10 0\n", 1)
    err = _err(write("tri.dump", text))
    assert err.line == 5 and "box" in err.message


def test_bad_box_bounds_in_a_binary_dump(tmp_path):
    from bedstruct.io._binary import write_binary_dump
    path = tmp_path / "box.bin"
    write_binary_dump(path, [dict(timestep=3, bounds=np.array([[0, 1.0], [1.0, 0], [0, 1.0]]),
                                  tilt=None, boundary=("pp",) * 3,
                                  names="id type x y z radius".split(),
                                  data=np.array([[1, 1, 0.5, 0.5, 0.5, 0.1]]))])
    err = _err(path)
    assert "below" in err.message and "timestep 3" in err.message


def test_ids_beyond_2_to_53_and_types_beyond_int32(write, dump_text):
    rows = ["9007199254740993 1 1 1 1 0.5", "9007199254740992 1 2 2 2 0.5"]
    err = _err(write("bigid.dump", dump_text(rows)))
    assert "2**53" in err.message and err.line == FIRST_ROW
    err = _err(write("bigtype.dump", dump_text(["1 3000000000 1 1 1 0.5", "2 1 2 2 2 0.5"])))
    assert "type" in err.message and err.line == FIRST_ROW


def test_repeated_ids_warn(write, dump_text):
    rows = ["1 1 1 1 1 0.5", "2 1 2 2 2 0.5", "1 1 3 3 3 0.5"]
    p = write("dupid.dump", dump_text(rows))
    for sort in (True, False):
        with pytest.warns(BedstructWarning, match="line 12: particle id 1 appears more than once"):
            with read_dump(p, sort_by_id=sort) as traj:
                f = traj[0]
        assert f.n_particles == 3


def test_general_triclinic_box_is_not_supported_yet(write, dump_text, good_rows):
    text = dump_text(good_rows).replace(
        "ITEM: BOX BOUNDS pp pp pp\n0 10\n0 10\n0 10\n",
        "ITEM: BOX BOUNDS abc origin pp pp pp\n10 0 0 0\n0 10 0 0\n0 0 10 0\n")
    err = _err(write("abc.dump", text))
    assert err.line == 5 and "not supported" in err.message


def test_gzip_members_cut_while_being_written(tmp_path):
    # frames appended as gzip members (as the engine writes) and the file cut inside one:
    # strict names the cut; otherwise every frame before it reads exactly
    import gzip
    import numpy as np
    from bedstruct import Frame, write_dump
    frames = [Frame(np.random.default_rng(k).uniform(0, 10, (200, 3)), np.full(200, 0.5),
                    box=([0, 0, 0], [10, 10, 10]), timestep=100 * k) for k in range(5)]
    plain = tmp_path / "all.dump"
    write_dump(plain, frames)
    whole = read_dump(plain)
    parts = plain.read_bytes().split(b"ITEM: TIMESTEP")[1:]
    members = [gzip.compress(b"ITEM: TIMESTEP" + part) for part in parts]
    p = tmp_path / "cut.dump.gz"
    for k_cut in (1, 3, 4):
        for frac in (0.1, 0.5, 0.95):
            cut = sum(len(m) for m in members[:k_cut]) + int(frac * len(members[k_cut]))
            p.write_bytes(b"".join(members)[:cut])
            with pytest.raises(DumpFormatError, match="cannot decompress.*cut"):
                read_dump(p)
            with pytest.warns(BedstructWarning) as said:
                t = read_dump(p, strict=False)
            said = [str(w.message) for w in said]
            assert any("compressed data end inside a member" in m for m in said)
            assert any(f"truncated last frame of {p} (timestep {100 * k_cut})" in m for m in said)
            assert t.timesteps.tolist() == [100 * k for k in range(k_cut)]
            for k in range(k_cut):
                np.testing.assert_array_equal(t[k].positions, whole[k].positions)
    p.write_bytes(b"".join(members))                      # complete: no warning, all frames
    assert read_dump(p).timesteps.tolist() == [0, 100, 200, 300, 400]
