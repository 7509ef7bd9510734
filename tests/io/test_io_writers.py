"""Writers: atomic output, refused input with clear messages, dtypes kept, and the
MDAnalysis exchange keeping what the frame knows."""

from __future__ import annotations

import os

import numpy as np
import pytest

from bedstruct import Frame, load_hdf5, read_dump, save_hdf5, write_dump
from bedstruct.core import Box
from bedstruct.errors import DumpFormatError
from bedstruct.io import summarise, write_dump_local


def _frame(n=3, **kw):
    rng = np.random.default_rng(n)
    return Frame(rng.uniform(0, 1, (n, 3)), np.full(n, 0.05), box=[1, 1, 1], **kw)


def _frames_then_crash(frames):
    yield from frames
    raise KeyboardInterrupt


@pytest.mark.parametrize("ext", ["dump", "dump.gz"])
def test_write_dump_that_stops_leaves_the_old_file(tmp_path, ext):
    path = tmp_path / f"bed.{ext}"
    write_dump(path, [_frame(timestep=1), _frame(timestep=2)])
    before = path.read_bytes()
    with pytest.raises(KeyboardInterrupt):
        write_dump(path, _frames_then_crash([_frame(timestep=7)]))
    assert path.read_bytes() == before
    with pytest.raises(TypeError, match="Frame"):
        write_dump(path, [_frame(timestep=9), "not a frame"])
    assert path.read_bytes() == before
    assert os.listdir(tmp_path) == [path.name]          # no temporary file left


def test_write_dump_over_the_file_being_read(tmp_path):
    path = tmp_path / "bed.dump"
    frames = [_frame(timestep=t) for t in (0, 10, 20)]
    write_dump(path, frames)
    write_dump(path, read_dump(path), columns="id x y z radius")
    back = read_dump(path)
    assert back.timesteps.tolist() == [0, 10, 20]
    np.testing.assert_array_equal(back[2].positions, frames[2].positions)


@pytest.mark.parametrize("ext", ["dump", "dump.gz"])
def test_append_that_stops_cuts_the_file_back(tmp_path, ext):
    path = tmp_path / f"bed.{ext}"
    write_dump(path, _frame(timestep=1))
    before = path.read_bytes()
    with pytest.raises(KeyboardInterrupt):
        write_dump(path, _frames_then_crash([_frame(timestep=2)]), append=True)
    assert path.read_bytes() == before
    assert read_dump(path).timesteps.tolist() == [1]


def test_write_dump_local_that_stops_leaves_the_old_file(tmp_path, monkeypatch):
    import bedstruct.io.dump_local as dump_local
    from bedstruct import Contacts
    frame = Frame([[0.5, 0.5, 0.5], [1.4, 0.5, 0.5]], [0.5, 0.5], box=[2, 1, 1])
    c = Contacts(i=[0], j=[1], branch=[[0.9, 0, 0]], radii_i=[0.5], radii_j=[0.5],
                 n_particles=2)
    path = tmp_path / "pairs.local"
    write_dump_local(path, frame, c)
    before = path.read_bytes()

    def interrupted(arrays, n):
        raise KeyboardInterrupt
    monkeypatch.setattr(dump_local, "_format_rows", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_dump_local(path, frame, c)
    assert path.read_bytes() == before


def test_extra_column_named_like_a_written_column_is_refused(tmp_path):
    f = _frame()
    clash = Frame(f.positions, f.radii, box=f.box, columns={"x": np.full(3, 9.0)})
    with pytest.raises(ValueError, match="'x'"):
        write_dump(tmp_path / "a.dump", clash)
    vec = Frame(f.positions, f.radii, box=f.box, velocities=np.ones((3, 3)),
                columns={"vx": np.zeros(3)})
    with pytest.raises(ValueError, match="'vx'"):
        write_dump(tmp_path / "a.dump", vec)


@pytest.mark.parametrize("values", [np.array(["a", "b", "c"]), np.array([None, 1, 2], dtype=object),
                                    np.array([1j, 2, 3])])
def test_non_numeric_column_is_a_clear_error(tmp_path, values):
    f = _frame()
    with pytest.raises(ValueError, match="column 'c' holds"):
        write_dump(tmp_path / "a.dump", Frame(f.positions, f.radii, box=f.box,
                                              columns={"c": values}))
    assert not os.listdir(tmp_path)


def test_unsigned_and_bool_columns_are_written_as_their_values(tmp_path):
    f = _frame()
    big = np.array([2 ** 63 + 5, 1, 0], dtype=np.uint64)
    path = tmp_path / "a.dump"
    write_dump(path, Frame(f.positions, f.radii, box=f.box,
                           columns={"u": big, "b": np.array([True, False, True])}))
    rows = path.read_text().splitlines()[-3:]
    assert [r.split()[-2:] for r in rows] == [["9223372036854775813", "1"], ["1", "0"],
                                              ["0", "1"]]


def test_bad_arguments_and_names_are_clear_errors(tmp_path):
    with pytest.raises(TypeError, match="Frame"):
        write_dump(tmp_path / "a.dump", 5)
    with pytest.raises(IsADirectoryError, match="directory"):
        write_dump(tmp_path, _frame())
    f = _frame()
    with pytest.raises(ValueError, match="cannot be written"):
        write_dump(tmp_path / "a.dump", Frame(f.positions, f.radii, box=f.box,
                                              columns={"dichte\u00e9": np.ones(3)}))


def test_zst_without_zstandard_names_the_package(tmp_path, monkeypatch):
    import sys
    monkeypatch.setitem(sys.modules, "zstandard", None)
    with pytest.raises(ImportError, match="pip install zstandard"):
        write_dump(tmp_path / "a.dump.zst", _frame())
    assert not os.listdir(tmp_path)


def test_hdf5_keeps_bool_and_string_columns(tmp_path):
    f = _frame()
    cols = {"flag": np.array([True, False, True]), "name": np.array(["a", "bb", "\u00e9"]),
            "n": np.arange(3, dtype=np.int32)}
    save_hdf5(tmp_path / "a.h5", Frame(f.positions, f.radii, box=f.box, columns=cols),
              results={"mask": np.array([True, False]), "labels": ["x", 1], "none": "__none__",
                       "huge": 2 ** 70})
    stored = load_hdf5(tmp_path / "a.h5")
    back = stored.frames[0].columns
    for name, arr in cols.items():
        assert back[name].dtype == arr.dtype, name
        np.testing.assert_array_equal(back[name], arr)
    assert stored.results["mask"].dtype == bool
    assert stored.results["labels"] == ["x", 1]
    assert stored.results["none"] == "__none__"
    assert stored.results["huge"] == 2 ** 70


def test_hdf5_refuses_unstorable_values_by_name(tmp_path):
    f = _frame()
    with pytest.raises(ValueError, match="column 'obj'"):
        save_hdf5(tmp_path / "a.h5", Frame(f.positions, f.radii, box=f.box,
                                           columns={"obj": np.array([None, 1, 2], dtype=object)}))
    with pytest.raises(ValueError, match="result 'when'"):
        save_hdf5(tmp_path / "a.h5", f, results={"when": np.datetime64("2020-01-01")})
    assert not os.listdir(tmp_path)


def test_load_hdf5_of_another_file_is_a_value_error(tmp_path):
    path = tmp_path / "bed.dump"
    write_dump(path, _frame())
    with pytest.raises(ValueError, match="not an HDF5 file"):
        load_hdf5(path)
    with pytest.raises(FileNotFoundError, match="no such file"):
        load_hdf5(tmp_path / "missing.h5")


def test_summarise_names_an_hdf5_file(tmp_path):
    save_hdf5(tmp_path / "bed.h5", _frame())
    with pytest.raises(DumpFormatError, match="HDF5"):
        summarise(tmp_path / "bed.h5")


def test_mdanalysis_keeps_units_time_omegas_images_and_columns():
    pytest.importorskip("MDAnalysis")
    from bedstruct import from_universe, to_universe
    rng = np.random.default_rng(3)
    f = Frame(rng.uniform(0, 1, (4, 3)), np.full(4, 0.05),
              box=Box([-1, 0, 0], [1, 1, 1], [0.2, 0, 0], "pp pp ff"), timestep=5, time=0.25,
              ids=[4, 3, 2, 1], omegas=rng.normal(size=(4, 3)), images=rng.integers(-2, 3, (4, 3)),
              columns={"mass": rng.uniform(1, 2, 4)}, units="cgs")
    back = from_universe(to_universe(f))
    s = f.sorted_by_id()
    assert back.units == f.units and back.time == 0.25
    np.testing.assert_array_equal(back.omegas, s.omegas)
    np.testing.assert_array_equal(back.images, s.images)
    np.testing.assert_array_equal(back.columns["mass"], s.columns["mass"])
    part = from_universe(to_universe(f).atoms[[0, 2]])          # ids 4 and 2
    np.testing.assert_array_equal(part.omegas, f.omegas[[2, 0]])


def test_mdanalysis_universe_of_unknown_units_is_not_labelled_si():
    mda = pytest.importorskip("MDAnalysis")
    from bedstruct import from_universe
    u = mda.Universe.empty(3, trajectory=True)
    u.atoms.positions = np.arange(9.0).reshape(3, 3)
    u.dimensions = [10, 10, 10, 90, 90, 90]
    frame = from_universe(u, radius=0.5)
    assert frame.units.style is None
    assert frame.ids.tolist() == [1, 2, 3] and frame.types.tolist() == [1, 1, 1]
    assert any("unit style unknown" in note for note in frame.provenance.notes)
    with pytest.raises(TypeError, match="MDAnalysis Universe"):
        from_universe("universe.pdb")
