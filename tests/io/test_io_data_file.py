"""read_data / write_data details: styles, comments, tabs, tilt, errors."""

from __future__ import annotations

import numpy as np
import pytest

from bedstruct import Frame, read_data, write_data, write_dump
from bedstruct.errors import DumpFormatError

DATA = """LAMMPS data file # a title with a comment
# a full-line comment

 3 atoms   # trailing comment
\t2 atom types

0.0 4.0 xlo xhi
0.0 5.0 ylo yhi
-1.0 6.0 zlo zhi
0.5 -0.25 0.125 xy xz yz

Masses

1 1.0
2 2.0

Atoms # granular

3\t2\t0.2\t1000\t1.0 1.0 1.0\t0 1 -1
1 1 0.4 2000 2.0 2.0 2.0 0 0 0   # comment after a row
2 1 0.6 3000 3.0 3.0 3.0 1 0 0

Velocities

2 0.2 0 0 0 0 2.0
1 0.1 0 0 0 0 1.0
3 0.3 0 0 0 0 3.0
"""


def test_granular_style_comments_tabs_tilt(tmp_path):
    p = tmp_path / "d.data"
    p.write_text(DATA)
    f = read_data(p, boundary="pp pp ff", units="si")
    assert f.ids.tolist() == [1, 2, 3] and f.types.tolist() == [1, 1, 2]
    assert f.radii.tolist() == [0.2, 0.3, 0.1]
    assert f.positions.tolist() == [[2, 2, 2], [3, 3, 3], [1, 1, 1]]
    assert f.images.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, -1]]
    assert f.velocities[:, 0].tolist() == [0.1, 0.2, 0.3]   # joined by id, not by row
    assert f.omegas[:, 2].tolist() == [1.0, 2.0, 3.0]
    assert f.box.tilt.tolist() == [0.5, -0.25, 0.125] and f.box.boundary == ("pp", "pp", "ff")
    np.testing.assert_allclose(f.columns["mass"], np.array([2000, 3000, 1000])
                               * 4 / 3 * np.pi * np.array([0.2, 0.3, 0.1]) ** 3)
    assert f.columns["type_mass"].tolist() == [1.0, 1.0, 2.0]
    assert f.units.style == "si"
    assert any("boundary 'pp pp ff' given" in n for n in f.provenance.notes)


def test_atomic_style_needs_radius(tmp_path):
    p = tmp_path / "a.data"
    p.write_text("title\n\n1 atoms\n1 atom types\n0 1 xlo xhi\n0 1 ylo yhi\n0 1 zlo zhi\n\n"
                 "Atoms # atomic\n\n1 1 0.5 0.5 0.5\n")
    with pytest.raises(DumpFormatError, match="radius="):
        read_data(p)
    assert read_data(p, radius=0.1).radii.tolist() == [0.1]


@pytest.mark.parametrize("edit,match,line", [
    (("3 atoms", "4 atoms"), "atom count mismatch", None),
    (("1 1 0.4 2000 2.0 2.0 2.0 0 0 0", "1 1 0.4 2000 2.0 two 2.0 0 0 0"), "non-numeric", 20),
    (("1 1 0.4 2000 2.0 2.0 2.0 0 0 0", "1 1 0.4 2000 2.0 2.0 0 0 0"), "wrong number", 20),
    (("1 1 0.4 2000", "1 1 -0.4 2000"), "diameter must be positive", 20),
    (("2 atom types", "2 atom kinds"), "unknown data file header line", 5),
    (("Velocities", "Velocitys"), "unknown section name", 23),
])
def test_data_file_errors(tmp_path, edit, match, line):
    p = tmp_path / "bad.data"
    p.write_text(DATA.replace(*edit))
    with pytest.raises(DumpFormatError, match=match) as info:
        read_data(p)
    if line is not None:
        assert info.value.line == line


def test_write_data_requires_density(tmp_path, sc_frame):
    with pytest.raises(ValueError, match="density"):
        write_data(tmp_path / "x.data", sc_frame)
    f = Frame(sc_frame.positions, sc_frame.radii, box=sc_frame.box,
              columns={"density": np.full(sc_frame.n_particles, 7800.0)})
    write_data(tmp_path / "x.data", f)
    back = read_data(tmp_path / "x.data")
    assert back.columns["density"].tolist() == [7800.0] * f.n_particles
    assert "Atoms # sphere" in (tmp_path / "x.data").read_text()


def _hybrid(style, rows, bonds=True):
    return ("title\n\n2 atoms\n1 atom types\n" + ("1 bonds\n1 bond types\n" if bonds else "")
            + "\n0 10 xlo xhi\n0 10 ylo yhi\n0 10 zlo zhi\n\n"
            + (f"Atoms # {style}\n\n" if style else "Atoms\n\n") + "".join(r + "\n" for r in rows))


@pytest.mark.parametrize("style,rows", [
    ("hybrid bond sphere", ["1 1 1 2 3 7 0.5 2500", "2 1 4 5 6 8 0.25 1000"]),
    ("hybrid sphere bond", ["1 1 1 2 3 0.5 2500 7", "2 1 4 5 6 0.25 1000 8"]),
    ("hybrid molecular sphere", ["1 1 1 2 3 7 0.5 2500 0 0 1", "2 1 4 5 6 8 0.25 1000 0 0 0"]),
    ("hybrid granular bond/gran", ["1 1 1 2 3 0.5 2500 7", "2 1 4 5 6 0.25 1000 8"]),
    ("hybrid sphere full", ["1 1 1 2 3 0.5 2500 7 -1.5", "2 1 4 5 6 0.25 1000 8 1.5"]),
])
def test_hybrid_column_order_follows_the_sub_styles(tmp_path, style, rows):
    p = tmp_path / "h.data"
    p.write_text(_hybrid(style, rows))
    f = read_data(p)
    assert f.positions.tolist() == [[1, 2, 3], [4, 5, 6]]
    assert f.radii.tolist() == [0.25, 0.125]
    assert f.columns["density"].tolist() == [2500, 1000]
    assert f.columns["molecule"].tolist() == [7, 8]
    if "full" in style:
        assert f.columns["q"].tolist() == [-1.5, 1.5]
    if len(rows[0].split()) > 9:
        assert f.images.tolist() == [[0, 0, 1], [0, 0, 0]]


def test_liggghts_write_data_hybrid_layout_without_molecule(tmp_path):
    p = tmp_path / "h.data"
    p.write_text(_hybrid("", ["1 1 1 2 3 0.5 2500 0 0 1", "2 1 4 5 6 0.25 1000 0 0 0"]))
    f = read_data(p)
    assert f.radii.tolist() == [0.25, 0.125] and f.images.tolist() == [[0, 0, 1], [0, 0, 0]]
    assert "molecule" not in f.columns


@pytest.mark.parametrize("style,match", [
    ("hybrid sphere ellipsoid", "ellipsoid"),
    ("hybrid sphere foo", "foo"),
    ("hybrid", "sub-styles"),
    ("hybrid bond full sphere", "molecule"),
])
def test_unknown_hybrid_combinations_are_errors(tmp_path, style, match):
    p = tmp_path / "h.data"
    p.write_text(_hybrid(style, ["1 1 1 2 3 7 0.5 2500", "2 1 4 5 6 8 0.25 1000"]))
    with pytest.raises(DumpFormatError, match=match) as info:
        read_data(p)
    assert info.value.path == str(p)


def test_hybrid_without_a_diameter_needs_radius(tmp_path):
    p = tmp_path / "h.data"
    p.write_text(_hybrid("hybrid bond charge", ["1 1 1 2 3 7 0.5", "2 1 4 5 6 8 -0.5"]))
    with pytest.raises(DumpFormatError, match="radius="):
        read_data(p)
    f = read_data(p, radius=0.1)
    assert f.columns["molecule"].tolist() == [7, 8] and f.columns["q"].tolist() == [0.5, -0.5]


@pytest.mark.parametrize("edit,line,match", [
    (("0.0 4.0 xlo xhi", "4.0 0.0 xlo xhi"), 7, "below"),
    (("0.0 5.0 ylo yhi", "0.0 nan ylo yhi"), 8, "finite"),
    (("0.5 -0.25 0.125 xy xz yz", "0.5 inf 0.125 xy xz yz"), 10, "finite"),
])
def test_bad_box_in_a_data_file_names_the_line(tmp_path, edit, line, match):
    p = tmp_path / "box.data"
    p.write_text(DATA.replace(*edit))
    with pytest.raises(DumpFormatError, match=match) as info:
        read_data(p)
    assert info.value.line == line and info.value.path == str(p)


@pytest.mark.parametrize("content", ["", "\n\n   \n"])
def test_empty_data_file(tmp_path, content):
    p = tmp_path / "e.data"
    p.write_text(content)
    with pytest.raises(DumpFormatError, match="empty"):
        read_data(p)


@pytest.mark.parametrize("bad", ["mm", 5])
def test_data_units_argument_is_checked(tmp_path, bad):
    p = tmp_path / "d.data"
    p.write_text(DATA)
    with pytest.raises(ValueError, match="si, cgs, micro"):
        read_data(p, units=bad)
    assert read_data(p, units="real").units.style == "real"


def test_repeated_atom_ids_warn(tmp_path):
    from bedstruct.errors import BedstructWarning
    p = tmp_path / "dup.data"
    p.write_text(DATA.replace("2 1 0.6 3000", "1 1 0.6 3000"))
    with pytest.warns(BedstructWarning, match="line 21: atom id 1 appears more than once"):
        read_data(p)


@pytest.mark.parametrize("title, timestep", [
    ("LAMMPS data file via write_data, version 2 Aug 2023, timestep = 101, units = si", 101),
    ("LAMMPS data file via write_data, version Version LIGGGHTS-PUBLIC 3.8.0, timestep = 0", 0),
    ("LAMMPS data file written by bedstruct (timestep 2500)", 2500),
    ("LAMMPS data file # a title with a comment", 0),
])
def test_the_timestep_of_the_write_data_title_line_is_read(tmp_path, title, timestep):
    p = tmp_path / "t.data"
    p.write_text(title + DATA[DATA.index("\n"):])
    assert read_data(p).timestep == timestep


def test_bedstruct_write_data_keeps_the_timestep(tmp_path):
    frame = Frame([[1.0, 1.0, 1.0]], [0.5], box=[2, 2, 2], timestep=4200)
    write_data(tmp_path / "w.data", frame, density=1.0)
    assert read_data(tmp_path / "w.data").timestep == 4200


def test_boundary_of_a_data_file_is_assumed_or_given_and_noted(tmp_path):
    """Data files do not record boundary flags: pp pp pp (the LAMMPS default) is assumed and
    noted as assumed; a given boundary is used and noted as given."""
    from bedstruct.io import read
    p = tmp_path / "b.data"
    p.write_text(DATA)
    frame = read_data(p)
    assert frame.box.boundary == ("pp", "pp", "pp")
    assert any("boundary 'pp pp pp' assumed" in n and "--boundary" in n
               for n in frame.provenance.notes)
    for given in ("pp pp ff", ("p", "p", "f"), ["pp", "pp", "ff"]):
        frame = read_data(p, boundary=given)
        assert frame.box.boundary == ("pp", "pp", "ff") and frame.box.periodic == (True, True, False)
        assert any("boundary 'pp pp ff' given" in n for n in frame.provenance.notes)
    assert read(p, boundary="ff ff ff")[0].box.boundary == ("ff", "ff", "ff")
    with pytest.raises(ValueError, match="boundary flag for z"):
        read_data(p, boundary="pp pp pf")
    # a dump states its own boundary
    dump = tmp_path / "b.dump"
    write_dump(dump, frame)
    with pytest.raises(ValueError, match="is for data files.*states its own"):
        read(dump, boundary="pp pp ff")


def test_timestep_of_a_real_liggghts_data_file(realdata):
    p = realdata / "lexiarlen+LIGGGHTS_SEAICE/lexi_tests/dynamic_forcing/test/test.data"
    if not p.is_file():
        pytest.skip(f"{p} not found")
    assert read_data(p).timestep == 101
