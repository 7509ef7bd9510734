"""Files cut off anywhere in their last frame: strict=True names the line where the
file looks truncated, strict=False keeps the complete frames and warns."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from bedstruct import Frame, read_dump, read_dump_local
from bedstruct.errors import BedstructWarning, DumpFormatError

from _iohelpers import _dump_text_fixture, good_rows, write  # noqa: F401 (fixtures)


def _read_all(path, **kw):
    traj = read_dump(path, **kw)
    try:
        return [traj[k] for k in range(len(traj))]
    finally:
        traj.close()


def _lenient(path, **kw):
    """Frames read with strict=False and whether a BedstructWarning was given."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        frames = _read_all(path, strict=False, **kw)
    return frames, any(issubclass(w.category, BedstructWarning) for w in caught)


def _cut_line(text: str, cut: int) -> int:
    """1-based line where a file holding ``text[:cut]`` ends (the partial or missing line)."""
    return text[:cut].count("\n") + 1


def _check_every_cut(tmp_path, text, first_complete, n_complete):
    """Cut ``text`` at every byte after ``first_complete`` and check both modes."""
    p = tmp_path / "cut.dump"
    for cut in range(first_complete + 1, len(text)):
        p.write_text(text[:cut])
        with pytest.raises(DumpFormatError) as info:
            _read_all(p)
        err = info.value
        where = f"cut at byte {cut}: {text[max(0, cut - 30):cut]!r} -> {err}"
        assert "truncated" in err.message, where
        assert err.path == str(p) and err.line == _cut_line(text, cut), where
        frames, warned = _lenient(p)
        assert warned, where
        assert [f.timestep for f in frames] == list(range(1, n_complete + 1)), where
        for f in frames:
            assert f.n_particles == 3 and f.radii.tolist() == [0.25, 0.5, 0.5], where


def test_every_byte_cut_of_the_last_frame(tmp_path, dump_text, good_rows):
    """A two-frame file (the second with ITEM: TIME first) cut at every byte of frame 2."""
    first = "ITEM: UNITS\nsi\nITEM: TIME\n0.5\n" + dump_text(good_rows, step=1)
    text = first + "ITEM: TIME\n1.5\n" + dump_text(good_rows, step=2)
    _check_every_cut(tmp_path, text, len(first), 1)
    for cut, n in ((len(first), 1), (len(text), 2)):  # the complete files: no warning
        (tmp_path / "ok.dump").write_text(text[:cut])
        frames, warned = _lenient(tmp_path / "ok.dump")
        assert len(frames) == n and not warned
        assert len(_read_all(tmp_path / "ok.dump")) == n


def test_every_byte_cut_of_a_one_frame_file(tmp_path, dump_text, good_rows):
    text = dump_text(good_rows, step=1)
    _check_every_cut(tmp_path, text, 0, 0)


def test_every_byte_cut_of_a_triclinic_frame(tmp_path, dump_text, good_rows):
    first = dump_text(good_rows, step=1)
    second = dump_text(good_rows, step=2).replace(
        "ITEM: BOX BOUNDS pp pp pp\n0 10\n0 10\n0 10\n",
        "ITEM: BOX BOUNDS xy xz yz pp pp pp\n0 11 1.0\n0 10 0.0\n0 10 0.0\n")
    _check_every_cut(tmp_path, first + second, len(first), 1)


def test_cut_inside_the_last_number_of_a_real_file(realdata, tmp_path):
    """`head -c -3` leaves 0.002 of the last radius 0.0025: never read as a number."""
    src = realdata / "CFDEMproject+LIGGGHTS-PUBLIC/contactModels_v3.2.0/dump800.newModels"
    raw = src.read_bytes()
    assert raw.endswith(b" 0.0025 \n")  # LIGGGHTS ends rows with a space
    p = tmp_path / "cut.dump"
    p.write_bytes(raw[:-3])
    assert p.read_bytes().endswith(b" 0.002")
    with pytest.raises(DumpFormatError, match="truncated") as info:
        read_dump(p)
    assert info.value.line == raw.count(b"\n") and "newline" in info.value.message
    with pytest.warns(BedstructWarning, match="truncated"):
        traj = read_dump(p, strict=False)
    assert len(traj) == 0


def test_missing_final_newline_counts_as_truncated(write, dump_text, good_rows):
    text = dump_text(good_rows, step=1) + dump_text(good_rows, step=2)
    p = write("noeol.dump", text.rstrip("\n"))
    with pytest.raises(DumpFormatError, match="truncated") as info:
        read_dump(p)
    assert info.value.line == 24
    frames, warned = _lenient(p)
    assert warned and [f.timestep for f in frames] == [1]


def _local_text(step, rows, n=None):
    n = len(rows) if n is None else n
    return (f"ITEM: TIMESTEP\n{step}\nITEM: NUMBER OF ENTRIES\n{n}\nITEM: BOX BOUNDS pp pp pp\n"
            "0 10\n0 10\n0 10\nITEM: ENTRIES id1 id2 c_x\n" + "".join(r + "\n" for r in rows))


@pytest.fixture
def pair_frames():
    return [Frame([[1.0, 1, 1], [2.0, 1, 1]], [0.6, 0.6], box=[10, 10, 10], timestep=t)
            for t in (1, 2)]


def test_dump_local_cut_off_header_and_last_number(write, pair_frames):
    rows = ["1 2 0.125"]
    text = _local_text(1, rows) + _local_text(2, rows)
    for name, cut_text, line in (("h.local", _local_text(1, rows) + "ITEM: TIMES", 11),
                                 ("n.local", text[:-3], 20)):
        p = write(name, cut_text)
        with pytest.raises(DumpFormatError, match="truncated") as info:
            read_dump_local(p, frames=pair_frames)
        assert info.value.line == line
        with pytest.warns(BedstructWarning):
            out = read_dump_local(p, frames=pair_frames, strict=False)
        assert list(out) == [1] and out[1].columns["c_x"].tolist() == [0.125]
    assert list(read_dump_local(write("ok.local", text), frames=pair_frames)) == [1, 2]


def test_dump_local_every_byte_cut(tmp_path, pair_frames):
    first = _local_text(1, ["1 2 0.125"])
    text = first + _local_text(2, ["1 2 0.25"])
    p = tmp_path / "c.local"
    for cut in range(len(first) + 1, len(text)):
        p.write_text(text[:cut])
        with pytest.raises(DumpFormatError, match="truncated") as info:
            read_dump_local(p, frames=pair_frames)
        assert info.value.line == _cut_line(text, cut), cut
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            out = read_dump_local(p, frames=pair_frames, strict=False)
        assert list(out) == [1] and caught, cut


def test_surplus_row_after_the_last_frame_is_not_truncation(write, dump_text, good_rows):
    """A (cut) extra data row after a complete last frame is a count mismatch, not skipped."""
    text = dump_text(good_rows, step=1) + dump_text(good_rows, step=2, n=2)
    for content in (text, text[:-4]):
        p = write("surplus.dump", content)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with pytest.raises(DumpFormatError, match="count mismatch") as info:
                _read_all(p, strict=False)
        assert info.value.line == 24


def test_values_of_a_complete_last_frame_are_unchanged(write, dump_text, good_rows):
    f = _read_all(write("ok.dump", dump_text(good_rows, step=1)))[0]
    np.testing.assert_array_equal(f.radii, [0.25, 0.5, 0.5])
