"""read_dump_local: how contacts find their particles when the atom ids cannot be used."""

from __future__ import annotations

import numpy as np
import pytest

from bedstruct import read_dump, read_dump_local
from bedstruct.errors import DumpFormatError

# a dump without an 'id' column: the reader numbers the rows 1..4 in file order
ATOMS = """ITEM: TIMESTEP
100
ITEM: NUMBER OF ATOMS
4
ITEM: BOX BOUNDS pp ff ff
0 10
0 10
0 10
ITEM: ATOMS x y z radius
5 5 1 1
1 1 1 1
3 1 1 1
9.5 1 1 1
"""

HEAD = """ITEM: TIMESTEP
100
ITEM: NUMBER OF ENTRIES
{n}
ITEM: BOX BOUNDS pp ff ff
0 10
0 10
0 10
ITEM: ENTRIES {names}
"""

# LIGGGHTS ids of the simulation (not 1..4 in file order): the pair 11-13 is rows 1 and 2,
# the pair 11-17 rows 1 and 3 across the periodic x boundary (particle 17 dumped at its
# image, -0.5, as LIGGGHTS dumps the ghost atom)
POS_ID_FORCE = ["1 1 1 3 1 1 11 13 0 -0.5 0 0",
                "1 1 1 -0.5 1 1 11 17 1 0.25 0 0"]


def _files(tmp_path, rows, n_cols):
    atoms = tmp_path / "noid.dump"
    atoms.write_text(ATOMS)
    local = tmp_path / "pairs.local"
    names = " ".join(f"c_pgl[{k + 1}]" for k in range(n_cols))
    local.write_text(HEAD.format(n=len(rows), names=names) + "\n".join(rows) + "\n")
    return atoms, local


def test_contacts_of_a_dump_without_ids_are_refused_without_positions(tmp_path):
    """The reader's made-up ids 1..N are not the simulation's: joining the contact file's ids
    to them would pair the wrong particles, so the join is refused."""
    rows = [r.split(None, 6)[6] for r in POS_ID_FORCE]   # keywords 'id force' only
    atoms, local = _files(tmp_path, rows, 6)
    frame = read_dump(atoms)[0]
    with pytest.raises(DumpFormatError, match="no 'id' column.*cannot be matched") as info:
        read_dump_local(local, keywords=["id", "force"], frames=frame)
    assert info.value.line == 9 and "'pos'" in str(info.value)


def test_contacts_of_a_dump_without_ids_are_matched_by_their_dumped_positions(tmp_path):
    atoms, local = _files(tmp_path, POS_ID_FORCE, 12)
    frame = read_dump(atoms)[0]
    c = read_dump_local(local, keywords=["pos", "id", "force"], frames=frame)[100]
    assert c.i.tolist() == [1, 1] and c.j.tolist() == [2, 3]
    assert c.branch.tolist() == [[2.0, 0.0, 0.0], [-1.5, 0.0, 0.0]]
    assert c.periodic.tolist() == [False, True]
    # the simulation's ids stay with the contacts
    assert c.columns["id1"].tolist() == [11, 11] and c.columns["id2"].tolist() == [13, 17]
    # a dumped position with no particle under it names the row
    bad = POS_ID_FORCE[:1] + ["1 1 1 6 6 6 11 19 0 0 0 0"]
    atoms, local = _files(tmp_path, bad, 12)
    with pytest.raises(DumpFormatError, match="contact row 2: no particle .* within") as info:
        read_dump_local(local, keywords=["pos", "id", "force"], frames=frame)
    assert info.value.line == 11


def test_contacts_with_positions_and_no_ids_are_matched_by_position(tmp_path):
    """A layout that has positions but no ids (mapped with columns=) joins by position, also
    to an atom dump that has ids."""
    rows = [" ".join(r.split()[:6]) for r in POS_ID_FORCE]
    atoms, local = _files(tmp_path, rows, 6)
    body = ATOMS.split("ITEM: ATOMS x y z radius\n")
    atoms.write_text(body[0] + "ITEM: ATOMS id x y z radius\n" + "".join(
        f"{i} {row}\n" for i, row in zip((21, 11, 13, 17), body[1].splitlines())))
    frame = read_dump(atoms)[0]   # sorted by id: rows 11, 13, 17, 21
    names = ["x1", "y1", "z1", "x2", "y2", "z2"]
    c = read_dump_local(local, columns=names, frames=frame)[100]
    assert c.ids_i.tolist() == [11, 11] and c.ids_j.tolist() == [13, 17]
    assert c.periodic.tolist() == [False, True]


def test_a_layout_the_reader_cannot_guess_names_both_ways_to_say_it(tmp_path):
    """The message names the Python arguments and the command-line options."""
    atoms, local = _files(tmp_path, POS_ID_FORCE, 12)
    with pytest.raises(DumpFormatError) as info:
        read_dump_local(local, frames=read_dump(atoms)[0])
    text = str(info.value)
    assert "keywords=" in text and "columns=" in text
    assert "--contact-keywords" in text and "--contact-columns 'c_pgl[1]=id1 c_pgl[2]=id2" in text
    with pytest.raises(DumpFormatError, match="--contact-columns"):
        read_dump_local(local, keywords=["id"], frames=read_dump(atoms)[0])


def test_contacts_are_not_joined_to_repeated_ids(tmp_path):
    """A contact naming an id that two particles of the atom frame carry could be either:
    the join is refused, naming the id."""
    atoms = tmp_path / "ids.dump"
    atoms.write_text(ATOMS.replace("ITEM: ATOMS x y z radius", "ITEM: ATOMS id x y z radius")
                     .replace("5 5 1 1\n1 1 1 1\n3 1 1 1\n9.5 1 1 1",
                              "3 5 5 1 1\n1 1 1 1 1\n3 3 1 1 1\n2 9.5 1 1 1"))
    local = tmp_path / "pairs.local"
    local.write_text(HEAD.format(n=1, names="c_p[1] c_p[2] c_p[3] c_p[4] c_p[5] c_p[6]")
                     + "1 3 0 0.5 0 0\n")
    with pytest.warns(UserWarning, match="id 3 appears more than once"):
        frame = read_dump(atoms)[0]
    with pytest.raises(DumpFormatError, match=r"id 3 appears more than once.*timestep 100"):
        read_dump_local(local, keywords=["id", "force"], frames=frame)
