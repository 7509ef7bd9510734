"""`bedstruct report` on the command line: contact layouts, data-file boundaries and
timesteps, option values, paths that are not files, and how warnings are printed."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from bedstruct import Box, Frame, write_data, write_dump, write_dump_local
from bedstruct.analysis import find_contacts
from bedstruct.cli import main
from bedstruct.report import build as build_mod
from bedstruct.report.inputs import load_report_inputs


@pytest.fixture(autouse=True)
def _summary_and_packing_only(monkeypatch):
    """The reports here run only the sections the tests read (the input is judged as always)."""
    monkeypatch.setattr(build_mod, "SECTIONS",
                        [s for s in build_mod.SECTIONS if s[0] in ("summary", "packing")])


def _bed(boundary="pp pp ff", timestep=101) -> Frame:
    """A touching simple-cubic bed 6 x 4 x 3 (d = 1) at the bottom of a box 10 high."""
    g = np.stack(np.meshgrid(np.arange(6), np.arange(4), np.arange(3), indexing="ij"),
                 -1).reshape(-1, 3)
    return Frame(g + 0.5, np.full(len(g), 0.5), box=Box([0, 0, 0], [6, 4, 10], boundary=boundary),
                 ids=np.arange(1, len(g) + 1) * 3, timestep=timestep)


def _property_local(path, frame, pairs):
    """Contacts in the layout of LAMMPS `compute property/local patom1 patom2` with
    `compute pair/local dist eng force p1 p2 p3` (as in dump.neigh)."""
    rows = []
    for k, (a, b) in enumerate(pairs):
        d = frame.positions[b] - frame.positions[a]
        rows.append(f"{k + 1} {frame.ids[a]} {frame.ids[b]} {float(np.linalg.norm(d))!r} -1.0 0 0 0")
    path.write_text(f"ITEM: TIMESTEP\n{frame.timestep}\nITEM: NUMBER OF ENTRIES\n{len(rows)}\n"
                    "ITEM: BOX BOUNDS pp pp ff\n0 6\n0 4\n0 10\n"
                    "ITEM: ENTRIES index c_1[1] c_1[2] c_2[1] c_2[2] c_2[3] c_2[4] c_2[5]\n"
                    + "\n".join(rows) + "\n")


COLUMNS = "c_1[1]=id1 c_1[2]=id2 c_2[1]=dist c_2[3]=fx c_2[4]=fy c_2[5]=fz"


def test_contact_columns_read_a_property_local_contact_dump(tmp_path, capsys):
    frame = _bed()
    dump, local = tmp_path / "bed.dump", tmp_path / "dump.neigh"
    write_dump(dump, frame)
    pairs = [(a, a + 12) for a in range(60)]   # the neighbours along x
    _property_local(local, frame, pairs)
    out = str(tmp_path / "r")
    # without a description the error names the command-line options
    assert main(["report", str(dump), "--contacts", str(local), "--no-3d", "--out", out]) == 1
    err = capsys.readouterr().err
    assert "--contact-columns 'c_1[1]=id1 c_1[2]=id2 ...'" in err and "--contact-keywords" in err
    assert "columns={" in err   # and the Python argument, for API users
    assert main(["report", str(dump), "--contacts", str(local), "--contact-columns", COLUMNS,
                 "--no-3d", "--json", "--out", out]) == 0
    doc = json.loads((tmp_path / "r" / "report.json").read_text())
    assert doc["inputs"]["contacts"] == str(local)
    # the same map, comma separated, read through the report's loader
    frames, _, contacts, _ = load_report_inputs([str(dump)], contacts=str(local),
                                                contact_columns={"c_1[1]": "id1", "c_1[2]": "id2"})
    assert contacts.n_contacts == 60 and contacts.ids_i.tolist() == frame.ids[:60].tolist()


def test_contacts_are_not_joined_to_a_frame_whose_ids_repeat(tmp_path, capsys):
    # a particle added above the bed with id 6, which another one has: a contact naming 6
    # could be either, so the join is refused
    frame = _bed()
    dump, local = tmp_path / "bed.dump", tmp_path / "dump.neigh"
    _property_local(local, frame, [(a, a + 12) for a in range(60)])
    write_dump(dump, Frame(np.vstack([frame.positions, [0.5, 0.5, 5.5]]), np.full(frame.n_particles + 1, 0.5),
                           box=frame.box, ids=np.append(frame.ids, frame.ids[1]), timestep=frame.timestep))
    with pytest.warns(UserWarning, match="more than once"):
        code = main(["report", str(dump), "--contacts", str(local), "--contact-columns", COLUMNS,
                     "--no-3d", "--out", str(tmp_path / "r")])
    assert code == 1
    err = capsys.readouterr().err
    assert "cannot join contacts by particle id" in err and "id 6 appears more than once" in err, err
    assert not (tmp_path / "r" / "report.json").exists()


@pytest.mark.parametrize("spec, expected", [
    ("c_1[1]=id1 c_1[2]=id2", {"c_1[1]": "id1", "c_1[2]": "id2"}),
    ("c_1[1]=id1,c_1[2]=id2", {"c_1[1]": "id1", "c_1[2]": "id2"}),
    ("- id1 id2 - fx fy fz -", [None, "id1", "id2", None, "fx", "fy", "fz", None]),
])
def test_contact_columns_forms(spec, expected):
    from bedstruct.cli.report import _contact_columns
    assert _contact_columns(spec) == expected


def test_contact_columns_of_the_real_dump_neigh(realdata):
    base = realdata / "ashriva16+granular-force-chains/LAMMPS/examples"
    if not (base / "dump.neigh").is_file():
        pytest.skip(f"{base}/dump.neigh not found")
    from bedstruct.cli.report import _contact_columns
    _, _, contacts, _ = load_report_inputs([str(base / "visualize.du")],
                                           contacts=str(base / "dump.neigh"),
                                           contact_columns=_contact_columns(COLUMNS))
    assert contacts.n_contacts == 9000


def _json_summary(capsys):
    out, err = capsys.readouterr()
    return json.loads(out.strip().splitlines()[-1]), err


def test_a_data_file_is_read_with_the_boundary_given_or_the_one_assumed_said(tmp_path, capsys):
    """Data files do not record their boundary: the report says what it assumed (pp pp pp,
    the LAMMPS default, so the empty space above the bed counts in the packing) and
    --boundary sets it. The write_data timestep is read, so contacts of that step join."""
    frame = _bed()
    data = tmp_path / "bed.data"
    write_data(data, frame, density=1.0)
    local = tmp_path / "pairs.local"
    write_dump_local(local, frame, find_contacts(frame))
    assert main(["report", str(data), "--contacts", str(local), "--no-3d", "--json",
                 "--out", str(tmp_path / "a")]) == 0
    assumed, err = _json_summary(capsys)
    assert "note: boundary 'pp pp pp' assumed for the data file" in err and "--boundary" in err
    assert assumed["values"]["summary.timestep"] == 101
    assert assumed["values"]["summary.boundary"] == "pp pp pp"
    inputs = json.loads((tmp_path / "a" / "report.json").read_text())["inputs"]
    assert inputs["boundary"].startswith("pp pp pp (assumed")
    assert main(["report", str(data), "--boundary", "p p f", "--no-3d", "--json",
                 "--out", str(tmp_path / "g")]) == 0
    given, err = _json_summary(capsys)
    assert "note:" not in err
    assert given["values"]["summary.boundary"] == "pp pp ff"
    inputs = json.loads((tmp_path / "g" / "report.json").read_text())["inputs"]
    assert inputs["boundary"].startswith("pp pp ff (given")
    # the bed fills its bounding box along the bounded axis: pi/6 for simple cubic
    assert given["values"]["packing.bounding_box_fraction"] == pytest.approx(np.pi / 6)
    assert assumed["values"]["packing.bounding_box_fraction"] < 0.5 * np.pi / 6
    # a dump states its own boundary
    write_dump(tmp_path / "bed.dump", frame)
    assert main(["report", str(tmp_path / "bed.dump"), "--boundary", "pp pp ff",
                 "--out", str(tmp_path / "d")]) == 1
    assert "is for data files" in capsys.readouterr().err


def test_the_boundary_of_data_files_read_by_one_glob_is_said(tmp_path):
    for t in (100, 101):
        write_data(tmp_path / f"bed{t}.data", _bed(timestep=t), density=1.0)
    _, _, _, inputs = load_report_inputs([str(tmp_path / "bed*.data")], frames="all")
    assert inputs["frames_in_input"] == 2
    assert inputs["boundary"].startswith("pp pp pp (assumed")


@pytest.mark.parametrize("bad, option", [
    (["--radius", "-1"], "--radius"), (["--radius", "0"], "--radius"),
    (["--radius", "inf"], "--radius"),
    (["--heat", "--heat-stop-fraction", "2"], "--heat-stop-fraction"),
    (["--heat-stop-fraction", "-1"], "--heat-stop-fraction"),
    (["--heat-stop-fraction", "1"], "--heat-stop-fraction"),
    (["--repose-base", "nan"], "--repose-base"),
    (["--heat-length-unit", "-1e-6"], "--heat-length-unit"),
    (["--boundary", "pp pp"], "--boundary"), (["--boundary", "pf pp pp"], "--boundary"),
    (["--contact-columns", "c_1[1]=id1 id2"], "--contact-columns"),
    (["--contact-columns", "=id1"], "--contact-columns"),
])
def test_option_values_out_of_range_exit_2_before_reading(tmp_path, capsys, bad, option):
    with pytest.raises(SystemExit) as info:
        main(["report", str(tmp_path / "not-read.dump"), "--out", str(tmp_path / "r"), *bad])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert f"bedstruct report: error: argument {option}" in err
    assert not (tmp_path / "r").exists()


def test_a_path_that_is_not_a_regular_file(tmp_path, capsys):
    if not os.path.exists(os.devnull) or os.path.isfile(os.devnull):
        pytest.skip(f"{os.devnull} is not a device here")
    assert main(["report", os.devnull, "--out", str(tmp_path / "r")]) == 1
    err = capsys.readouterr().err
    assert "not a regular file" in err and "no such file" not in err


def test_lenient_warnings_are_one_line_each(tmp_path):
    """Run as a user would (a child process, warnings shown): each frame left out is one
    'bedstruct report: warning:' line, without the Python warning format and source line."""
    frames = [_bed(timestep=t) for t in (0, 10)]
    path = tmp_path / "cut.dump"
    write_dump(path, frames)
    path.write_text(path.read_text()[:-1])   # the last line loses its newline: cut off
    run = subprocess.run([sys.executable, "-m", "bedstruct", "report", str(path), "--lenient",
                          "--no-3d", "--out", str(tmp_path / "r")], capture_output=True,
                         text=True, timeout=300, env={**os.environ, "PYTHONWARNINGS": "default"})
    assert run.returncode == 0, run.stderr
    lines = run.stderr.splitlines()
    assert lines and all(line.startswith("bedstruct report: ") for line in lines), run.stderr
    assert any(line.startswith("bedstruct report: warning: skipping the truncated last frame")
               and "timestep 10" in line for line in lines)
    assert "BedstructWarning" not in run.stderr and ".py:" not in run.stderr


def test_the_report_leaves_the_warning_format_as_it_found_it(tmp_path, capsys):
    """The one-line format of bedstruct's warnings is the command's: a caller running it in
    its own process gets its own format back, also when the command fails."""
    import warnings
    before = warnings.formatwarning
    write_dump(tmp_path / "bed.dump", _bed())
    assert main(["report", str(tmp_path / "bed.dump"), "--no-3d", "--out",
                 str(tmp_path / "r")]) == 0
    assert warnings.formatwarning is before
    assert main(["report", str(tmp_path / "missing.dump"), "--out", str(tmp_path / "m")]) == 1
    assert warnings.formatwarning is before
    capsys.readouterr()


def test_contact_keywords_and_columns_together_are_a_usage_error(tmp_path, capsys):
    assert main(["report", str(tmp_path / "not-read.dump"), "--contacts", "c.local",
                 "--contact-keywords", "pos id", "--contact-columns", COLUMNS,
                 "--out", str(tmp_path / "r")]) == 2
    assert "not both" in capsys.readouterr().err
