"""`bedstruct info`: summaries of dump and data files, JSON output, errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bedstruct import Frame, write_dump
from bedstruct.cli import main


def _json(capsys):
    out = capsys.readouterr().out.strip().splitlines()
    return json.loads(out[-1])


def test_info_json_dump(tmp_path, capsys):
    path = tmp_path / "dump.liggghts"
    frames = [Frame([[0.5, 0.5, 0.5], [1.5, 0.5, 0.5]][:n], [0.5] * n, box=([0, 0, 0], [2, 1, 1]),
                    timestep=t) for n, t in ((2, 0), (1, 100))]
    frames[0].box = frames[0].box.replace(boundary="pp ff pp")
    write_dump(path, frames)
    assert main(["info", str(path), "--json"]) == 0
    s = _json(capsys)["files"][0]
    assert s["format"] == "lammps-dump-text" and s["n_frames"] == 2
    assert s["timesteps"] == [0, 100] and s["n_particles"] == [2, 1]
    assert s["box"]["lo"] == [0, 0, 0] and s["box"]["hi"] == [2, 1, 1]
    assert s["box"]["boundary"] == ["pp", "ff", "pp"] and s["box"]["periodic"] == [True, False, True]
    assert s["columns"] == ["id", "type", "x", "y", "z", "radius"]
    assert s["units"] is None and s["path"] == str(path)


def test_info_text_realdata_and_glob(realdata, capsys):
    pattern = str(realdata / "CFDEMproject+LIGGGHTS-PUBLIC/contactModels_v3.2.0/dump*.newModels")
    assert main(["info", pattern]) == 0
    out = capsys.readouterr().out
    assert "frames: 4 (timesteps 0 .. 20000)" in out and "boundary mm mm mm" in out
    data = realdata / "lammps+lammps/examples/granular/3ps.dat"
    assert main(["info", str(data), "--json"]) == 0
    s = _json(capsys)["files"][0]
    assert s["format"] == "lammps-data" and s["n_particles"] == [3]


def test_info_radius_option_and_notes(tmp_path, capsys):
    path = tmp_path / "noradius.dump"
    path.write_text("ITEM: TIMESTEP\n5\nITEM: NUMBER OF ATOMS\n1\nITEM: BOX BOUNDS pp pp pp\n"
                    "0 1\n0 1\n0 1\nITEM: ATOMS x y z\n0.5 0.5 0.5\n")
    assert main(["info", str(path), "--json"]) == 0
    assert any("--radius" in n for n in _json(capsys)["files"][0]["notes"])
    assert main(["info", str(path), "--radius", "0.1", "--json"]) == 0
    notes = _json(capsys)["files"][0]["notes"]
    assert any("ids 1..N synthesised" in n for n in notes)


def test_info_bad_file_exits_1_with_one_line(tmp_path, capsys):
    path = tmp_path / "bad.dump"
    path.write_text("ITEM: TIMESTEP\n5\nITEM: NUMBER OF ATOMS\n2\nITEM: BOX BOUNDS pp pp pp\n"
                    "0 1\n0 1\n0 1\nITEM: ATOMS id x y z radius\n1 0.5 0.5 0.5 0.1\n"
                    "2 0.5 oops 0.5 0.1\n")
    assert main(["info", str(path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "line 11" in err[0] and "non-numeric" in err[0]
    assert main(["info", str(tmp_path / "missing.dump")]) == 1
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_info_help(capsys):
    with pytest.raises(SystemExit) as info:
        main(["info", "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert "--json" in out and "--radius" in out and "Summarise" in out


def test_info_binary_and_dump_local(tmp_path, capsys, sc_frame):
    import numpy as np
    from bedstruct import Contacts, write_dump_local
    from bedstruct.io._binary import write_binary_dump
    data = np.array([[1, 1, 0.1, 0.2, 0.3, 0.05]])
    path = tmp_path / "d.bin"
    write_binary_dump(path, [dict(timestep=9, bounds=np.array([[0, 1.0]] * 3), tilt=None,
                                  boundary=("pp", "pp", "ff"), names="id type x y z radius".split(),
                                  data=data, units="si")])
    assert main(["info", str(path), "--json"]) == 0
    s = _json(capsys)["files"][0]
    assert s["format"] == "lammps-dump-binary" and s["timesteps"] == [9] and s["units"] == "si"
    empty = Contacts(i=[], j=[], branch=np.zeros((0, 3)), radii_i=[], radii_j=[],
                     n_particles=sc_frame.n_particles)
    write_dump_local(tmp_path / "c.local", sc_frame, empty)
    assert main(["info", str(tmp_path / "c.local"), "--json"]) == 0
    s = _json(capsys)["files"][0]
    assert s["format"] == "lammps-dump-local" and s["n_particles"] == [0]


def _frame(t, n=2):
    return Frame([[0.5, 0.5, 0.5], [1.5, 0.5, 0.5]][:n], [0.5] * n, box=([0, 0, 0], [2, 1, 1]),
                 timestep=t)


def test_info_glob_of_data_files_summarises_each(tmp_path, capsys):
    from bedstruct import write_data
    for k in range(3):
        write_data(tmp_path / f"d{k}.data", _frame(0, n=1 + k % 2), density=1000.0)
    assert main(["info", str(tmp_path / "d*.data"), "--json"]) == 0
    files = _json(capsys)["files"]
    assert [s["files"] for s in files] == [[str(tmp_path / f"d{k}.data")] for k in range(3)]
    assert [s["n_particles"] for s in files] == [[1], [2], [1]]
    assert all(s["format"] == "lammps-data" for s in files)


def test_info_checks_the_row_count_of_every_frame(tmp_path, capsys):
    path = tmp_path / "d.dump"
    write_dump(path, [_frame(t) for t in (0, 100, 200)])
    lines = path.read_text().splitlines(keepends=True)
    del lines[10 + 11]                   # a row of frame 2 (of 3)
    path.write_text("".join(lines))
    assert main(["info", str(path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "count mismatch" in err[0] and "line 22" in err[0]


def test_info_says_what_was_checked(tmp_path, capsys):
    path = tmp_path / "d.dump"
    write_dump(path, [_frame(t) for t in (0, 100, 200)])
    assert main(["info", str(path), "--json"]) == 0
    notes = " ".join(_json(capsys)["files"][0]["notes"])
    assert "row counts of all 3 frames" in notes and "frame 0 only" in notes


@pytest.mark.parametrize("content", ["", "  \n\n"])
def test_info_empty_file(tmp_path, capsys, content):
    path = tmp_path / "e.dump"
    path.write_text(content)
    assert main(["info", str(path), "--json"]) == 1       # the summary, then an error
    out = capsys.readouterr()
    s = json.loads(out.out.strip().splitlines()[-1])["files"][0]
    assert s["format"] == "empty" and s["n_frames"] == 0
    assert any("empty" in n for n in s["notes"])
    err = out.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("bedstruct info: error:") and "e.dump" in err[0]
    assert "no frames" in err[0]
    assert main(["info", str(path)]) == 1
    assert "no frames (the file is empty)" in capsys.readouterr().err
    # an empty file among good ones still fails, naming only the empty one
    good = tmp_path / "g.dump"
    write_dump(good, [_frame(0)])
    assert main(["info", str(good), str(path)]) == 1
    err = capsys.readouterr().err
    assert "e.dump" in err and "g.dump" not in err
    assert main(["info", str(good)]) == 0


def test_info_unrecognisable_file(tmp_path, capsys):
    path = tmp_path / "x.txt"
    path.write_text("hello world\nthis is not a dump\n")
    assert main(["info", str(path)]) == 1
    err = capsys.readouterr().err
    assert "not a recognisable" in err and "line 1" in err


def test_info_truncated_last_frame_exits_1(tmp_path, capsys):
    path = tmp_path / "t.dump"
    write_dump(path, [Frame([[0.5, 0.5, 0.5]], [0.125], box=[1, 1, 1], timestep=t)
                      for t in (0, 100)])
    path.write_bytes(path.read_bytes()[:-3])   # the last radius reads 0.12
    assert main(["info", str(path)]) == 1
    assert "truncated" in capsys.readouterr().err


def test_info_columns_option(tmp_path, capsys):
    from bedstruct.io._binary import write_binary_dump
    text = tmp_path / "old.dump"
    write_dump(text, _frame(5))
    text.write_text(text.read_text().replace("ITEM: ATOMS id type x y z radius", "ITEM: ATOMS"))
    assert main(["info", str(text)]) == 1
    capsys.readouterr()
    assert main(["info", str(text), "--columns", "id type x y z radius", "--json"]) == 0
    s = _json(capsys)["files"][0]
    assert s["columns"] == ["id", "type", "x", "y", "z", "radius"] and s["n_particles"] == [2]
    binary = tmp_path / "old.bin"
    write_binary_dump(binary, [dict(timestep=9, bounds=np.array([[0, 1.0]] * 3), tilt=None,
                                    boundary=("pp",) * 3, names=[],
                                    data=np.array([[1, 1, 0.1, 0.2, 0.3, 0.05]]))], revision=1)
    assert main(["info", str(binary), "--columns", "id type x y z radius", "--json"]) == 0
    s = _json(capsys)["files"][0]
    assert s["format"] == "lammps-dump-binary" and s["timesteps"] == [9]


def test_info_lenient_names_the_frames_it_leaves_out(tmp_path, capsys):
    """A non-numeric value in frame 2 and a cut-off last frame: strict stops at the cut with
    its line; --lenient summarises the good frames and lists both bad ones."""
    path = tmp_path / "damaged.dump"
    write_dump(path, [Frame([[0.5, 0.5, 0.5], [1.5, 0.5, 0.5]], [0.25, 0.25], box=[2, 1, 1],
                            timestep=t) for t in (0, 100, 200, 300)])
    lines = path.read_text().splitlines(keepends=True)
    bad = 11 + 11      # 1-based: the second row of frame 2 (11 lines a frame)
    lines[bad - 1] = lines[bad - 1].replace("1.5", "1.5.0")
    text = "".join(lines)[:-4]   # the last radius cut short: a truncated frame
    path.write_text(text)
    assert main(["info", str(path)]) == 1
    err = capsys.readouterr().err
    assert "line 44: truncated" in err
    with pytest.warns(UserWarning) as said:
        assert main(["info", str(path), "--lenient", "--json"]) == 0
    s = _json(capsys)["files"][0]
    assert s["timesteps"] == [0, 200] and s["n_frames"] == 2
    assert [(k["timestep"], k["line"]) for k in s["skipped"]] == [(300, 44), (100, bad)]
    assert all(k["path"] == str(path) for k in s["skipped"])
    assert len([w for w in said if str(path) in str(w.message)]) == 2
    with pytest.warns(UserWarning):
        assert main(["info", str(path), "--lenient"]) == 0
    out = capsys.readouterr().out
    assert f"skipped: frame at timestep 100 ({path}, line {bad}): non-numeric" in out


def test_info_lenient_warnings_are_one_line_each(tmp_path):
    """Run as a user would (a child process, warnings shown): a frame left out is one
    'bedstruct info: warning:' line, without Python's warning format and source line."""
    import os
    import subprocess
    import sys
    path = tmp_path / "cut.dump"
    write_dump(path, [Frame([[0.5, 0.5, 0.5], [1.5, 0.5, 0.5]], [0.25, 0.25], box=[2, 1, 1],
                            timestep=t) for t in (0, 100)])
    path.write_text(path.read_text()[:-4])
    run = subprocess.run([sys.executable, "-m", "bedstruct", "info", str(path), "--lenient"],
                         capture_output=True, text=True, timeout=300,
                         env={**os.environ, "PYTHONWARNINGS": "default"})
    assert run.returncode == 0, run.stderr
    lines = run.stderr.splitlines()
    assert lines and all(line.startswith("bedstruct info: warning: ") for line in lines), run.stderr
    assert "BedstructWarning" not in run.stderr and ".py:" not in run.stderr
