"""bedstruct.io.read and detect_format: the reader is chosen from the content."""

from __future__ import annotations

import gzip

import numpy as np
import pytest

from bedstruct import Frame
from bedstruct.errors import DumpFormatError
from bedstruct.io import (detect_format, read, read_data, read_dump, save_hdf5, write_data,
                          write_dump, write_dump_local)
from bedstruct.io._binary import write_binary_dump

GRAN = "lammps+lammps/examples/granular"
LIGGGHTS = "CFDEMproject+LIGGGHTS-PUBLIC/contactModels_v3.2.0"
ASHRIVA = "ashriva16+granular-force-chains/LAMMPS/examples"


@pytest.fixture
def frame():
    rng = np.random.default_rng(3)
    pos = rng.uniform(0.0, 4.0, size=(20, 3))
    return Frame(pos, np.full(20, 0.2), box=[4, 4, 4], ids=np.arange(1, 21), timestep=7)


def test_each_format_is_recognised_from_its_content_not_its_name(tmp_path, frame):
    write_dump(tmp_path / "a.txt", frame)
    write_dump(tmp_path / "b.gz", frame)
    write_data(tmp_path / "c.dump", frame, density=7800.0)  # a data file under a dump's name
    save_hdf5(tmp_path / "d.bin", [frame])
    snap = dict(timestep=0, bounds=np.array([[0, 1.0]] * 3), tilt=None, boundary=("pp",) * 3,
                names="id type x y z radius".split(), data=np.array([[1, 1, 0.5, 0.5, 0.5, 0.1]]),
                units=None)
    write_binary_dump(tmp_path / "e.data", [snap])  # a binary dump under a data file's name
    assert [detect_format(tmp_path / n) for n in ("a.txt", "b.gz", "c.dump", "d.bin", "e.data")] \
        == ["dump", "dump", "data", "hdf5", "dump-binary"]


def test_read_gives_the_frames_of_the_matching_reader(tmp_path, frame):
    write_dump(tmp_path / "bed.dump.gz", [frame, Frame(frame.positions + 0.1, frame.radii,
                                                       box=frame.box, ids=frame.ids, timestep=9)])
    write_data(tmp_path / "bed.lammps", frame, density=7800.0)
    save_hdf5(tmp_path / "bed.h5", [frame])
    traj = read(tmp_path / "bed.dump.gz")
    ref = read_dump(tmp_path / "bed.dump.gz")
    assert traj.timesteps.tolist() == [7, 9] == ref.timesteps.tolist()
    np.testing.assert_array_equal(traj[1].positions, ref[1].positions)
    data = read(tmp_path / "bed.lammps")
    assert len(data) == 1
    np.testing.assert_array_equal(data[0].positions, read_data(tmp_path / "bed.lammps").positions)
    h5 = read(tmp_path / "bed.h5")
    np.testing.assert_array_equal(h5[0].positions, frame.positions)


def test_a_contact_file_is_refused_by_read_with_where_to_go(tmp_path, frame):
    from bedstruct.analysis import find_contacts
    contacts = find_contacts(frame)
    write_dump_local(tmp_path / "contacts.dump", frame, contacts)
    assert detect_format(tmp_path / "contacts.dump") == "dump-local"
    with pytest.raises(DumpFormatError, match="read_dump_local"):
        read(tmp_path / "contacts.dump")


def test_empty_unknown_and_mixed_inputs_are_named_errors(tmp_path, frame):
    (tmp_path / "empty.dump").write_bytes(b"")
    with pytest.raises(DumpFormatError, match=r"empty\.dump.*empty file"):
        read(tmp_path / "empty.dump")
    (tmp_path / "notes.txt").write_text("hello world\n")
    with pytest.raises(DumpFormatError, match=r"notes\.txt.*'hello world"):
        detect_format(tmp_path / "notes.txt")
    with gzip.open(tmp_path / "empty.gz", "wb"):
        pass
    with pytest.raises(DumpFormatError, match="empty file"):
        detect_format(tmp_path / "empty.gz")
    write_dump(tmp_path / "a.dump", frame)
    write_data(tmp_path / "b.data", frame, density=7800.0)
    with pytest.raises(DumpFormatError, match=r"different formats.*a\.dump \(dump\).*b\.data \(data\)"):
        read([tmp_path / "a.dump", tmp_path / "b.data"])
    with pytest.raises(FileNotFoundError, match="missing"):
        detect_format(tmp_path / "missing.dump")


def test_third_party_files_are_recognised(realdata):
    expected = {
        realdata / GRAN / "3ps.dat": "data",
        realdata / GRAN / "spheres12.data": "data",
        realdata / LIGGGHTS / "dump800.newModels": "dump",
        realdata / ASHRIVA / "visualize.du": "dump",
        realdata / ASHRIVA / "dump.neigh": "dump-local",
    }
    assert {p: detect_format(p) for p in expected} == expected
    assert read(realdata / GRAN / "3ps.dat")[0].n_particles == 3


def test_a_path_that_is_not_a_regular_file_says_so(tmp_path):
    """/dev/null exists: it is not a regular file, not a missing one; a folder is a folder."""
    import os
    if not os.path.exists(os.devnull) or os.path.isfile(os.devnull):
        pytest.skip(f"{os.devnull} is not a device here")
    with pytest.raises(DumpFormatError, match="not a regular file"):
        read(os.devnull)
    with pytest.raises(IsADirectoryError, match="a directory"):
        detect_format(tmp_path)
