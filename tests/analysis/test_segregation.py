"""Segregation: distances between PSDs, index, heap vs bed vs pile."""

from __future__ import annotations

import numpy as np
import pytest

from bedstruct import Box, Frame
from bedstruct.analysis import (compare_psd, heap_mask, particle_size_distribution, segregation,
                                segregation_index, wasserstein_psd)


def test_wasserstein_of_a_shift_is_the_shift():
    rng = np.random.default_rng(0)
    r = rng.uniform(10, 30, 2000)
    a = particle_size_distribution(r, weighting="number")
    b = particle_size_distribution(r + 2.5, weighting="number")      # diameters shift by 5
    assert wasserstein_psd(a, b) == pytest.approx(5.0, rel=1e-9)
    c = compare_psd(a, b)
    assert c.d50_shift == pytest.approx(5.0, rel=1e-9) and c.d10_shift == pytest.approx(5.0, rel=1e-9)
    # volume weighting: the distance is the area between the weighted CDFs
    va, vb = (particle_size_distribution(x, weighting="volume") for x in (r, r + 2.5))
    grid = np.linspace(10, 80, 200_001)
    cdf = [np.searchsorted(p.diameters, grid, side="right") for p in (va, vb)]
    wa = np.concatenate([[0], np.cumsum(va.weights)])[cdf[0]] / va.weights.sum()
    wb = np.concatenate([[0], np.cumsum(vb.weights)])[cdf[1]] / vb.weights.sum()
    assert wasserstein_psd(va, vb) == pytest.approx(np.trapezoid(np.abs(wa - wb), grid), rel=1e-3)
    with pytest.raises(ValueError, match="weighting"):
        wasserstein_psd(particle_size_distribution(r), particle_size_distribution(r, weighting="number"))


def graded_bed(gradient, n=3000, seed=1):
    rng = np.random.default_rng(seed)
    pos = rng.uniform([0, 0, 0], [30, 5, 3], (n, 3))
    base = rng.uniform(0.2, 0.4, n)
    r = base * (1 + gradient * pos[:, 0] / 30)
    return Frame(pos, r, box=Box([0, 0, 0], [30, 5, 10], boundary="ff pp ff"))


def test_index_grows_with_gradient():
    idx = [segregation_index(graded_bed(g), n_windows=6) for g in (0.0, 0.2, 0.5)]
    assert idx[0] < 0.02 < idx[1] < idx[2]
    # a graded bed split only across y sees no segregation
    assert segregation_index(graded_bed(0.5), n_windows=(1, 4, 1)) < 0.02
    # permuting radii randomly removes segregation
    f = graded_bed(0.5)
    mixed = Frame(f.positions, np.random.default_rng(2).permutation(f.radii), box=f.box)
    assert segregation_index(mixed, n_windows=6) < 0.02


def test_heap_vs_bed_vs_initial():
    rng = np.random.default_rng(3)
    initial = rng.uniform(0.2, 0.4, 4000)
    n = 4000
    x = rng.uniform(0, 30, n)
    pos = np.c_[x, rng.uniform(0, 5, n), rng.uniform(0, 3, n)]
    # coarse particles ride ahead of the blade at x = 24 (moving +x)
    order = np.argsort(initial)
    r = np.empty(n)
    r[np.argsort(x)] = initial[order]                   # size grows along x: bed graded too
    f = Frame(pos, r, box=Box([0, 0, 0], [30, 5, 10], boundary="ff pp ff"))
    s = segregation(f, 24.0, initial=initial, n_windows=4)
    assert s.heap.n_particles + s.bed.n_particles == n
    assert s.heap_vs_bed.d50_shift > 0 and s.heap_vs_initial.d50_shift > 0 > s.bed_vs_initial.d50_shift
    assert np.all(np.diff(s.along_d50) > 0) and len(s.along_bed) == 4 and s.index > 0.05
    assert s.heap_vs_bed.wasserstein > 0
    # blade moving the other way: the heap is on the low side
    back = segregation(f, 6.0, direction=-1)
    assert back.heap_vs_bed.d50_shift < 0
    assert heap_mask(f, 6.0, direction=-1).sum() == back.heap.n_particles
    with pytest.raises(ValueError, match="direction"):
        heap_mask(f, 6.0, direction=0)


def test_plots():
    from bedstruct.plot import plot_psd, plot_psd_along_bed
    f = graded_bed(0.5)
    s = segregation(f, 25.0, initial=f.radii, n_windows=3)
    fig, ax = plot_psd_along_bed(s)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[0].startswith("bed start") and labels[-1].startswith("initial pile")
    fig, ax = plot_psd([s.bed, s.heap], labels=["bed", "heap"], cumulative=True)
    assert ax.lines[0].get_ydata()[-1] == pytest.approx(1.0)


def test_index_value_and_explicit_windows():
    # two windows of equal counts, mean diameters 0.4 and 0.8: CV = 0.2 / 0.6
    x = np.linspace(0.5, 9.5, 200)
    f = Frame(np.c_[x, np.ones(200), np.ones(200)], np.where(x < 5, 0.2, 0.4), box=([0, 0, 0], [10, 2, 2]))
    lo, hi = [[0, 0, 0], [5, 0, 0]], [[5, 2, 2], [10, 2, 2]]
    for w in ("number", "volume"):
        assert segregation_index(f, lo, hi, weighting=w) == pytest.approx(1 / 3)
        assert segregation_index(f, n_windows=2, weighting=w) == pytest.approx(1 / 3)
    with pytest.raises(ValueError, match="weighting"):
        segregation_index(f, weighting="mass")
