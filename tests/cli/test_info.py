"""`bedstruct info`: summaries of dump and data files, JSON output, errors."""

from __future__ import annotations

import json

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
