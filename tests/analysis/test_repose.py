"""Angle of repose on synthetic piles of known angle."""

from __future__ import annotations

import math

import numpy as np
import pytest

import bedstruct
from bedstruct import Box, Frame
from bedstruct.analysis import (angle_of_repose, dynamic_angle_of_repose, dynamic_repose_series,
                                free_surface_profile)


def wedge_pile(angle_deg, *, half_width=30.0, length=12.0, seed=0, cone=False, shell=4.0):
    """Random polydisperse spheres filling a surface shell of a wedge (or cone) of known angle."""
    rng = np.random.default_rng(seed)
    t = math.tan(math.radians(angle_deg))
    height = half_width * t
    xc, yc = half_width + 2, length / 2
    n = int(60 * half_width * length * (1 + t) / (2 if not cone else 1))
    x = rng.uniform(0, 2 * half_width + 4, 4 * n)
    y = rng.uniform(0, length if not cone else 2 * half_width + 4, 4 * n)
    r = rng.uniform(0.3, 0.6, 4 * n)
    dist = np.hypot(x - xc, y - yc) if cone else np.abs(x - xc)
    surf = np.clip(height - t * dist, 0.0, None)
    z = surf - r - rng.uniform(0, shell, 4 * n)
    keep = (z >= r) & (surf > 0)
    pos = np.c_[x, y, z][keep]
    hi = [2 * half_width + 4, length if not cone else 2 * half_width + 4, height + 2]
    box = Box([0, 0, 0], hi, boundary="ff pp ff" if not cone else "ff ff ff")
    return Frame(pos, r[keep], box=box)


@pytest.mark.parametrize("angle", [25.0, 33.0, 40.0])
def test_static_wedge_angle_recovered(angle):
    f = wedge_pile(angle, seed=int(angle))
    res = bedstruct.angle_of_repose(f, spacing=0.25)
    assert abs(res.left_deg - angle) < 0.5 and abs(res.right_deg - angle) < 0.5
    assert abs(res.angle_deg - angle) < 0.5
    assert 0 < res.angle_std_deg < 0.5
    assert res.left.slope > 0 > res.right.slope
    med = angle_of_repose(f, spacing=0.25, statistic="median")
    assert abs(med.angle_deg - angle) < 0.5


def test_cone_silhouette():
    f = wedge_pile(33.0, half_width=20.0, cone=True, seed=3)
    res = angle_of_repose(f, spacing=0.25)
    assert abs(res.angle_deg - 33.0) < 0.5
    # the pile seen along y gives the same angle (rotation invariance)
    g = Frame(f.positions[:, [1, 0, 2]], f.radii, box=Box(f.box.lo[[1, 0, 2]], f.box.hi[[1, 0, 2]],
                                                             boundary="ff ff ff"))
    assert abs(angle_of_repose(g, spacing=0.25, axis=1).angle_deg - res.angle_deg) < 0.3


def test_one_flank_and_errors():
    f = wedge_pile(30.0, seed=5)
    x = f.positions[:, 0]
    half = f.select(x <= 32.0)                    # pile cut at its crest: only the left flank
    res = angle_of_repose(half, spacing=0.25)
    assert abs(res.left_deg - 30.0) < 0.5 and res.right is None and np.isnan(res.right_deg)
    assert res.angle_deg == res.left_deg
    with pytest.raises(ValueError, match="fit_range"):
        angle_of_repose(f, fit_range=(0.8, 0.2))
    with pytest.raises(ValueError, match="axis"):
        angle_of_repose(f, axis=2)
    with pytest.raises(ValueError, match="flat"):
        angle_of_repose(Frame([[1, 1, 1]], [0.5], box=[3, 3, 3]), spacing=2.0)


def heap_frame(angle_deg, blade, direction, seed=0):
    """A bed layer of thickness 2 plus a heap ahead of a blade, random spheres."""
    rng = np.random.default_rng(seed)
    t = math.tan(math.radians(angle_deg))
    L, W = 60.0, 8.0
    n = 40000
    x = rng.uniform(0, L, n)
    y = rng.uniform(0, W, n)
    r = rng.uniform(0.3, 0.6, n)
    ahead = (x - blade) * direction
    heap = np.where(ahead > 0, np.clip(10.0 - t * ahead, 0, None), 0.0)
    surf = 2.0 + heap
    z = surf - r - rng.uniform(0, 3.0, n)
    keep = z >= r
    box = Box([0, 0, 0], [L, W, 20], boundary="ff pp ff")
    return Frame(np.c_[x, y, z][keep], r[keep], box=box, timestep=seed)


@pytest.mark.parametrize("direction", [1, -1])
def test_dynamic_angle(direction):
    blade = 20.0 if direction == 1 else 40.0
    f = heap_frame(30.0, blade, direction)
    res = dynamic_angle_of_repose(f, blade, direction=direction, spacing=0.25)
    assert abs(res.angle_deg - 30.0) < 0.5
    assert (res.right if direction == 1 else res.left) is not None
    assert res.base == pytest.approx(2.0, abs=0.5)      # bed surface found ahead of the heap


def test_dynamic_series():
    frames = [heap_frame(a, 20.0, 1, seed=k) for k, a in enumerate((28.0, 32.0, 36.0))]
    s = dynamic_repose_series(frames, [20.0] * 3, spacing=0.25)
    np.testing.assert_allclose(s.angle_deg, [28.0, 32.0, 36.0], atol=0.5)
    assert s.timesteps.tolist() == [0, 1, 2]
    # a frame without particles ahead of the blade gives NaN, not an error
    s2 = dynamic_repose_series(frames[:1], lambda f: 100.0, spacing=0.25)
    assert np.isnan(s2.angle_deg[0])


def test_profile_statistic():
    f = Frame([[0.5, 0.5, 0.5], [0.5, 1.5, 1.5]], [0.5, 0.5], box=([0, 0, 0], [1, 2, 3]))
    x, h = free_surface_profile(f, spacing=0.5, statistic="max")
    assert np.allclose(h, 1.5 + math.sqrt(0.125))


def test_plots():
    from bedstruct.plot import plot_repose, plot_repose_series
    f = wedge_pile(30.0, seed=7)
    res = angle_of_repose(f, spacing=0.25)
    fig, ax = plot_repose(res)
    assert len(ax.lines) == 3 and "30." in ax.get_legend().get_texts()[1].get_text()
    s = dynamic_repose_series([heap_frame(30.0, 20.0, 1)], [20.0], spacing=0.25)
    fig, ax = plot_repose_series(s, time=[0.5])
    assert ax.get_xlabel() == "time"


def _sample_pile():
    import tomllib
    from pathlib import Path
    root = Path(__file__).parents[2] / "data" / "samples" / "repose"
    frame = bedstruct.read_dump(root / "pile.dump.gz", units="si")[-1]
    with open(root / "config.toml", "rb") as fh:
        return frame, tomllib.load(fh)


def test_pile_angle_is_the_repose_runs_measurement():
    # given the run's plate level and ledge, pile_angle gives the run's numbers to the bit
    from bedstruct.analysis import pile_angle
    from bedstruct.workflows.repose import measure_pile
    frame, cfg = _sample_pile()
    r_max = float(frame.radii.max())
    run = measure_pile(frame, cfg, r_max=r_max)
    L, W, _ = cfg["repose"]["box"]
    ped = cfg["repose"]["pedestal_fraction"]
    ledge = (((L - ped * L) / 2 - 2 * r_max, (L + ped * L) / 2 + 2 * r_max), (0.0, W))
    p = pile_angle(frame, base=0.0, bounds=ledge)
    assert (p.angle_deg, p.angle_std_deg, p.repose.left_deg, p.repose.right_deg) == run[:4]
    assert not p.base_found and p.n_left_out > 0                 # falling clumps left out
    # found from the pile alone: its plate (z = 0) and an angle within the replicates' 29.9 +- 1.0
    auto = pile_angle(frame)
    assert auto.base_found and abs(auto.base) < 1e-6
    assert auto.angle_deg == pytest.approx(29.9, abs=1.5)
    assert auto.repose.flank_difference_deg == pytest.approx(abs(auto.repose.left_deg - auto.repose.right_deg))


def test_pile_angle_of_a_lattice_heap_and_errors():
    from bedstruct.analysis import pile_angle
    g = np.stack(np.meshgrid(np.arange(80) * 0.5 + 0.25, [0.25, 0.75], np.arange(24) * 0.5 + 0.25,
                             indexing="ij"), -1).reshape(-1, 3)
    for deg in (25.0, 35.0):
        heap = g[g[:, 2] <= 12 - np.tan(np.radians(deg)) * np.abs(g[:, 0] - 20)]
        p = pile_angle(bedstruct.Frame(heap, np.full(len(heap), 0.26), box=([0, 0, 0], [40, 1, 14])))
        assert p.angle_deg == pytest.approx(deg, abs=1.5)
        assert p.base == pytest.approx(0.0, abs=0.02) and p.n_left_out == 0
    few = bedstruct.Frame(g[:5], np.full(5, 0.26), box=([0, 0, 0], [40, 1, 14]))
    with pytest.raises(ValueError, match="only 5 particles"):
        pile_angle(few)
    with pytest.raises(ValueError, match="`axis`"):
        pile_angle(few, axis=2)


def test_pile_angle_of_a_cone_is_its_silhouette_and_a_wedge_keeps_the_median():
    # the median height across a cone lies below its flank line (27.9 deg for 33)
    from bedstruct.analysis import pile_angle
    cone = wedge_pile(33.0, half_width=20.0, cone=True, seed=3)
    p = pile_angle(cone, base=0.0)
    assert p.shape == "cone" and p.angle_deg == pytest.approx(33.0, abs=0.7)
    # "auto" reports the same fit as asking for the cone
    c = pile_angle(cone, base=0.0, shape="cone").repose
    assert (p.repose.left_deg, p.repose.right_deg) == (c.left_deg, c.right_deg)
    np.testing.assert_array_equal(p.repose.profile_h, c.profile_h)
    assert pile_angle(cone, base=0.0, shape="wedge").angle_deg < 30.0
    # a wedge across a periodic width, and the bundled repose run's pile between side walls
    wedge = wedge_pile(33.0, seed=33)
    w = pile_angle(wedge, base=0.0)
    assert w.shape == "wedge" and w.angle_deg == pytest.approx(33.0, abs=0.5)
    frame, _ = _sample_pile()
    assert pile_angle(frame).shape == "wedge"
    with pytest.raises(ValueError, match="`shape`"):
        pile_angle(cone, shape="dome")
