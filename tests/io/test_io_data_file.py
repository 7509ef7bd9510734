"""read_data / write_data details: styles, comments, tabs, tilt, errors."""

from __future__ import annotations

import numpy as np
import pytest

from bedstruct import Frame, read_data, write_data
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
    assert any("boundary 'pp pp ff' assumed" in n for n in f.provenance.notes)


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
