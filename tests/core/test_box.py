import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from bedstruct import Box

FLAGS = ["pp", "ff", "fs", "sm", "mm"]


def test_flags_and_periodic():
    box = Box([0, 0, 0], [1, 2, 3], boundary=("pp", "fs", "mm"))
    assert box.periodic == (True, False, False)
    assert box.boundary == ("pp", "fs", "mm")
    assert Box([0, 0, 0], [1, 1, 1], boundary="p f s").boundary == ("pp", "ff", "ss")


@pytest.mark.parametrize("bad", ["pf pp pp", "xx pp pp", "pp pp"])
def test_bad_flags_rejected(bad):
    with pytest.raises(ValueError, match="boundary"):
        Box([0, 0, 0], [1, 1, 1], boundary=bad)


def test_hi_below_lo_rejected():
    with pytest.raises(ValueError, match="hi"):
        Box([0, 0, 0], [1, -1, 1])


def test_triclinic_bounds_roundtrip():
    box = Box([0, -1, 2], [10, 9, 7], tilt=[2.5, -1.0, 0.5], boundary="pp pp ff")
    again = Box.from_lammps_bounds(box.lammps_bounds(), tilt=box.tilt, boundary=box.boundary)
    assert again == box
    # bounding box encloses all 8 corners
    corners = np.array([[a, b, c] for a in (0, 1) for b in (0, 1) for c in (0, 1)], float)
    xyz = box.cartesian(corners)
    bb = box.lammps_bounds()
    assert np.allclose(xyz.min(0), bb[:, 0]) and np.allclose(xyz.max(0), bb[:, 1])


@settings(max_examples=60, deadline=None)
@given(st.lists(st.sampled_from(FLAGS), min_size=3, max_size=3),
       st.lists(st.floats(-0.4, 0.4), min_size=3, max_size=3),
       st.integers(0, 2**31))
def test_minimum_image_is_shortest(flags, tilt_frac, seed):
    rng = np.random.default_rng(seed)
    lengths = rng.uniform(1, 5, 3)
    tilt = np.array(tilt_frac) * np.array([lengths[0], lengths[0], lengths[1]])
    box = Box(np.zeros(3) - 1.0, lengths - 1.0, tilt=tilt, boundary=flags)
    d = rng.uniform(-0.2, 0.2, size=(50, 3)) * lengths.min()
    shifts = rng.integers(-2, 3, size=(50, 3)) * np.array(box.periodic)
    shifted = d + shifts @ box.matrix.T
    back = box.minimum_image(shifted)
    assert np.allclose(back, d, atol=1e-9)
    # non-periodic axes untouched (in a tilted box an image along c also moves x)
    for k, p in enumerate(box.periodic):
        if not p and not box.is_triclinic:
            assert np.allclose(back[:, k], shifted[:, k])


@settings(max_examples=60, deadline=None)
@given(st.lists(st.sampled_from(FLAGS), min_size=3, max_size=3), st.integers(0, 2**31),
       st.booleans())
def test_wrap_lands_inside_and_is_periodic_shift(flags, seed, triclinic):
    rng = np.random.default_rng(seed)
    lengths = rng.uniform(1, 5, 3)
    tilt = rng.uniform(-0.4, 0.4, 3) * [lengths[0], lengths[0], lengths[1]] if triclinic else np.zeros(3)
    box = Box([0.5, -2, 1], np.array([0.5, -2, 1]) + lengths, tilt=tilt, boundary=flags)
    x = box.cartesian(rng.uniform(-3, 4, size=(40, 3)))
    w = box.wrap(x)
    s = box.fractional(w)
    per = np.array(box.periodic)
    assert np.all((s[:, per] >= 0) & (s[:, per] < 1))
    # difference is a lattice vector along periodic axes only
    n = np.linalg.solve(box.matrix, (x - w).T).T
    assert np.allclose(n, np.round(n), atol=1e-8)
    assert np.allclose(n[:, ~per], 0, atol=1e-9)


def test_from_box_variants():
    assert Box.from_box([1, 2, 3]).volume == 6.0
    assert Box.from_box([0, 1, 0, 2, 0, 3]).volume == 6.0
    assert Box.from_box(([0, 0, 0], [1, 1, 2]), boundary="pp pp ff").periodic == (True, True, False)
    with pytest.raises(TypeError):
        Box.from_box("nonsense")
