"""Reading damaged dumps with ``on_error="skip"``: bad frames are left out with a
warning naming file, timestep and line, the good ones read as from a clean file;
the default stays strict with the same messages."""

from __future__ import annotations

import gzip
import pathlib
import warnings

import numpy as np
import pytest

import bedstruct.io
from bedstruct.errors import BedstructWarning, DumpFormatError
from bedstruct.io import SkippedFrame, read_dump

SAMPLE = pathlib.Path(__file__).resolve().parents[2] / "data" / "samples" / "spread" / "bed.dump.gz"
N_ROWS = 40
STEPS = (100, 200, 300, 400)


def _frames_text() -> list[str]:
    """Four frames (timesteps 100..400) of the first rows of the bundled spread bed,
    each a little shifted so that frames differ."""
    lines = gzip.open(SAMPLE, "rt").read().splitlines()
    head, rows = lines[:9], lines[9:9 + N_ROWS]
    out = []
    for k, step in enumerate(STEPS):
        h = list(head)
        h[1], h[3] = str(step), str(N_ROWS)
        shifted = []
        for r in rows:
            tok = r.split()
            tok[2] = repr(float(tok[2]) + 1e-6 * k)   # x
            shifted.append(" ".join(tok))
        out.append("\n".join(h + shifted) + "\n")
    return out


def _line_of(text: str, needle: str) -> int:
    """1-based line of the first line of ``text`` containing ``needle``."""
    return next(k for k, ln in enumerate(text.splitlines(), 1) if needle in ln)


def _lenient(path):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        traj = read_dump(path, on_error="skip")
        frames = list(traj)
    messages = [str(w.message) for w in caught if issubclass(w.category, BedstructWarning)]
    return traj, frames, messages


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    """The frames read strictly from the undamaged file (the reference)."""
    p = tmp_path_factory.mktemp("clean") / "clean.dump"
    p.write_text("".join(_frames_text()))
    with read_dump(p) as traj:
        return {f.timestep: f for f in traj}


def _check_kept(frames, clean, steps):
    assert [f.timestep for f in frames] == list(steps)
    for f in frames:
        ref = clean[f.timestep]
        np.testing.assert_array_equal(f.positions, ref.positions)
        np.testing.assert_array_equal(f.radii, ref.radii)
        np.testing.assert_array_equal(f.ids, ref.ids)


def _damage(kind: str, frames: list[str]) -> tuple[str, int, int]:
    """The file text with one frame damaged: (text, timestep of the bad frame, bad line)."""
    frames = list(frames)
    if kind == "non-numeric":
        rows = frames[1].splitlines(keepends=True)
        tok = rows[9 + 7].split()
        tok[4] = "0.00x1"
        rows[9 + 7] = " ".join(tok) + "\n"
        frames[1] = "".join(rows)
        text = "".join(frames)
        return text, 200, _line_of(text, "0.00x1")
    if kind == "count":   # the header says 40 rows but 39 follow
        rows = frames[2].splitlines(keepends=True)
        del rows[9 + 20]
        frames[2] = "".join(rows)
        text = "".join(frames)
        start = len("".join(frames[:2]).splitlines())
        return text, 300, start + 9 + N_ROWS   # the line where the next frame begins
    if kind == "truncated":   # the last frame cut in the middle of a row
        cut = frames[-1].index("\n", len(frames[-1]) // 2) - 11
        frames[-1] = frames[-1][:cut]
        text = "".join(frames)
        return text, STEPS[len(frames) - 1], text.count("\n") + 1
    if kind == "timestep":   # a garbled timestep value
        frames[1] = frames[1].replace("ITEM: TIMESTEP\n200\n", "ITEM: TIMESTEP\n2#0\n")
        text = "".join(frames)
        return text, None, _line_of(text, "2#0")
    raise AssertionError(kind)


@pytest.mark.parametrize("kind", ["non-numeric", "count", "truncated", "timestep"])
def test_skip_leaves_out_the_bad_frame_only(tmp_path, clean, kind):
    text, step, line = _damage(kind, _frames_text())
    p = tmp_path / f"{kind}.dump"
    p.write_text(text)
    # strict (default): an error naming the file and the line
    with pytest.raises(DumpFormatError) as info:
        with read_dump(p) as traj:
            list(traj)
    assert info.value.path == str(p) and info.value.line == line, str(info.value)
    # skip: the other frames read exactly as from the clean file
    traj, frames, messages = _lenient(p)
    _check_kept(frames, clean, [s for s in STEPS if s != (step or 200)])
    assert len(traj) == len(STEPS) - 1
    (skipped,) = traj.skipped
    assert isinstance(skipped, SkippedFrame)
    assert (skipped.path, skipped.timestep, skipped.line) == (str(p), step, line)
    assert skipped.reason.startswith(info.value.message)   # as the strict reader says it
    assert len(messages) == 1
    msg = messages[0]
    assert str(p) in msg and f"line {line}" in msg and f"timestep {step or 'unknown'}" in msg
    assert skipped.reason in msg


def test_several_bad_frames_and_files(tmp_path, clean):
    """A glob of two files, each with a bad frame: both named, the rest sorted by timestep."""
    frames = _frames_text()
    a_text, _, a_line = _damage("non-numeric", frames[:2])
    b_text, _, b_line = _damage("truncated", frames)   # timesteps 100..400, 400 cut off
    b_text = b_text[len(frames[0]) + len(frames[1]):]    # 300 and the cut 400
    b_line -= len((frames[0] + frames[1]).splitlines())
    (tmp_path / "a.dump").write_text(a_text)
    (tmp_path / "b.dump").write_text(b_text.replace("ITEM: TIMESTEP\n300", "ITEM: TIMESTEP\n50"))
    with pytest.raises(DumpFormatError):
        with read_dump(str(tmp_path / "*.dump")) as traj:
            list(traj)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        traj = bedstruct.io.read(str(tmp_path / "*.dump"), on_error="skip")
    assert traj.timesteps.tolist() == [50, 100]
    assert [(pathlib.Path(s.path).name, s.timestep, s.line) for s in traj.skipped] == [
        ("a.dump", 200, a_line), ("b.dump", 400, b_line)]
    np.testing.assert_array_equal(traj[0].positions, clean[300].positions)
    np.testing.assert_array_equal(traj[1].positions, clean[100].positions)
    assert traj.skipped[0].to_dict()["line"] == a_line


def test_clean_file_skips_nothing_and_bad_option(tmp_path, clean):
    p = tmp_path / "clean.dump"
    p.write_text("".join(_frames_text()))
    traj, frames, messages = _lenient(p)
    assert traj.skipped == [] and messages == []
    _check_kept(frames, clean, STEPS)
    with pytest.raises(ValueError, match="'raise'.*'skip'"):
        read_dump(p, on_error="ignore")
    with pytest.raises(ValueError, match="on_error"):
        bedstruct.io.read(p, on_error=True)


def test_the_unit_style_of_a_frame_left_out_still_holds(tmp_path):
    """LAMMPS states ITEM: UNITS before the first frame only: with that frame left out,
    the later frames are still in those units."""
    frames = _frames_text()
    bad = frames[0].splitlines(keepends=True)
    bad[12] = bad[12].replace(" ", " 1x ", 1)       # line 13 of the frame: a token too many
    p = tmp_path / "units.dump"
    p.write_text("ITEM: UNITS\nsi\n" + "".join(bad) + frames[1])
    traj, kept, messages = _lenient(p)
    assert [f.timestep for f in kept] == [200] and len(messages) == 1
    assert kept[0].units.style == "si"
    assert (traj.skipped[0].timestep, traj.skipped[0].line) == (100, 2 + 13)
