"""Insertion: raindrop positions never overlap; PSD sampling; saved piles."""

import numpy as np
import pytest

from bedstruct import Box
from bedstruct.dem import ContactModel, Material, Simulation, raindrop_positions, sample_radii


def test_raindrop_positions_do_not_overlap_and_fit_region():
    rng = np.random.default_rng(0)
    radii = rng.uniform(20e-6, 60e-6, 400)
    ex = np.array([[0.5e-3, 0.5e-3, 0.5e-3]])
    pos, ok = raindrop_positions((0, 0, 0), (1e-3, 1e-3, 1e-3), radii, existing=ex,
                                 existing_radii=[2e-4], rng=1)
    r = radii[ok]
    allp = np.vstack([pos, ex])
    allr = np.concatenate([r, [2e-4]])
    d = np.sqrt(((allp[:, None] - allp[None]) ** 2).sum(-1))
    np.fill_diagonal(d, np.inf)
    assert np.all(d >= allr[:, None] + allr[None] - 1e-15)
    assert np.all(pos - r[:, None] >= 0) and np.all(pos + r[:, None] <= 1e-3)
    assert ok.sum() > 300


def test_sample_radii_forms():
    assert np.all(sample_radii(3, 1e-5) == 1e-5)
    arr = sample_radii(100, [1e-5, 2e-5], rng=0)
    assert set(np.unique(arr)) <= {1e-5, 2e-5}
    r = sample_radii(20000, {10: 20e-6, 50: 30e-6, 90: 45e-6, "bounds": (10e-6, 90e-6)}, rng=0)
    assert np.all((2 * r >= 10e-6) & (2 * r <= 90e-6))
    with pytest.raises(ValueError):
        sample_radii(3, lambda n, g: -np.ones(n))


def _volume_quantiles(diameters, levels):
    d = np.sort(diameters)
    cum = np.cumsum(d ** 3)
    return np.interp(np.asarray(levels) / 100.0, (cum - 0.5 * d ** 3) / cum[-1], d)


def test_sample_radii_any_percentiles_are_volume_based():
    # percentiles of a log-normal volume distribution (median 30 um, sigma 0.35): any set of
    # levels gives radii whose volume-weighted percentiles are those numbers
    from scipy.special import ndtri
    levels = [16, 50, 84]
    pct = {k: 30e-6 * np.exp(0.35 * ndtri(k / 100)) for k in levels}
    d = 2 * sample_radii(200000, pct, rng=4)
    np.testing.assert_allclose(_volume_quantiles(d, levels), list(pct.values()), rtol=0.01)
    # drawn by number: the number median of a log-normal lies 3 sigma^2 below (Hatch-Choate)
    assert np.median(d) == pytest.approx(30e-6 * np.exp(-3 * 0.35 ** 2), rel=0.01)
    # the {10, 50, 90} path (a fitted family) reads the same distribution alike
    three = {k: 30e-6 * np.exp(0.35 * ndtri(k / 100)) for k in (10, 50, 90)}
    d3 = 2 * sample_radii(200000, three, rng=5)
    np.testing.assert_allclose(_volume_quantiles(d3, levels), list(pct.values()), rtol=0.02)
    # bounds truncate
    r = sample_radii(5000, {**pct, "bounds": (20e-6, 45e-6)}, rng=6)
    assert 2 * r.min() >= 20e-6 and 2 * r.max() <= 45e-6
    with pytest.raises(ValueError, match="bracket"):
        sample_radii(5, {**pct, "bounds": (25e-6, 45e-6)})


def test_psd_fit_object_is_sampled():
    from bedstruct.analysis.psd import psd_from_percentiles
    fit = psd_from_percentiles(29.84e-6, 52.08e-6, 86.11e-6, (25e-6, 105e-6))
    r = sample_radii(5000, fit, rng=2)
    assert r.min() >= 12.5e-6 and r.max() <= 52.5e-6


def test_insert_saved_pile_twice_keeps_geometry():
    model = ContactModel(Material(1e7, 0.3, 2500.0))
    box = Box([0, 0, 0], [2e-3, 2e-3, 4e-3], boundary="pp pp ff")
    sim = Simulation(box, model, n_threads=1, seed=3)
    n = sim.insert_raindrop(50, 1e-4, region=((0, 0, 0), (2e-3, 2e-3, 1e-3)))
    pile = sim.frame()
    sim2 = Simulation(box, model, n_threads=1)
    sim2.insert_frame(pile)
    sim2.insert_frame(pile, offset=(0, 0, 2e-3))
    fr = sim2.frame()
    assert fr.n_particles == 2 * n and len(np.unique(fr.ids)) == 2 * n
    assert np.allclose(fr.positions[n:] - fr.positions[:n], [0, 0, 2e-3])


def test_raindrop_fills_a_periodic_width_evenly_without_overlaps_across_it():
    # a region spanning the periodic y: centres anywhere across it (a strip one diameter
    # and a radius wide next to the upper face stayed empty), and no sphere overlaps the
    # images of its neighbours across the period
    W = 0.7e-3
    sim = Simulation(Box([0, 0, 0], [2.5e-3, W, 3e-3], boundary="ff pp ff"),
                     ContactModel(Material(1e6, 0.3, 8000.0)), n_threads=1, seed=3)
    r = np.random.default_rng(0).uniform(40e-6, 70e-6, 400)
    assert sim.insert_raindrop(400, r, region=((0, 0, 0), (2.5e-3, W, 2e-3))) == 400
    y = sim.x[:, 1]
    counts = np.histogram(y, bins=7, range=(0, W))[0]
    assert counts.min() > 0.6 * counts.mean()
    d = sim.x[:, None, :] - sim.x[None, :, :]
    d[..., 1] -= W * np.round(d[..., 1] / W)
    gap = np.sqrt((d ** 2).sum(-1)) - (sim.rad[:, None] + sim.rad[None, :])
    np.fill_diagonal(gap, np.inf)
    assert gap.min() >= 0.0
    # a region covering part of the period keeps its spheres inside it
    sim2 = Simulation(Box([0, 0, 0], [2.5e-3, W, 3e-3], boundary="ff pp ff"),
                      ContactModel(Material(1e6, 0.3, 8000.0)), n_threads=1, seed=3)
    sim2.insert_raindrop(100, r[:100], region=((0, 0.1e-3, 0), (2.5e-3, 0.5e-3, 0.85e-3)))
    assert (sim2.x[:, 1] - sim2.rad >= 0.1e-3 - 1e-12).all()
    assert (sim2.x[:, 1] + sim2.rad <= 0.5e-3 + 1e-12).all()


def test_insert_radii_says_which_were_placed_and_carrying_keeps_the_distribution():
    from bedstruct.core import Box
    from bedstruct.dem import ContactModel, Material, Simulation
    from bedstruct.workflows._common import insert_carrying

    def psd(n, rng):   # half of the spheres large, half small, by number
        return np.where(rng.random(n) < 0.5, 100e-6, 30e-6)

    def fill(carry):
        sim = Simulation(Box([0, 0, 0], [1e-3, 1e-3, 3e-3], boundary="ff ff ff"), ContactModel(Material(1e6, 0.3, 8000.0)),
                         seed=1)
        carried, z = [], 0.0
        for _ in range(20):
            need = 400 - sim.n_particles
            if need <= 0:
                break
            region = ((0.0, 0.0, z), (1e-3, 1e-3, z + 0.4e-3))
            if carry:
                carried = insert_carrying(sim, need, carried, psd, region)
            else:
                sim.insert_raindrop(need, psd, region=region)
            z += 0.4e-3
        return sim
    kept, dropped = fill(True), fill(False)
    assert kept.n_particles == dropped.n_particles == 400
    # carried over, the spheres placed are those drawn: half large (binomial sd 0.025)
    assert abs(np.mean(kept.rad == 100e-6) - 0.5) < 0.08
    # dropped and drawn anew, the slabs keep the small ones
    assert np.mean(dropped.rad == 100e-6) < 0.35
    sim = Simulation(Box([0, 0, 0], [1e-3, 1e-3, 1e-3], boundary="ff ff ff"), ContactModel(Material(1e6, 0.3, 8000.0)), seed=2)
    ok = sim.insert_radii(np.full(300, 100e-6), region=((0, 0, 0), (1e-3, 1e-3, 0.3e-3)))
    assert ok.dtype == bool and ok.shape == (300,) and 0 < ok.sum() < 300 == ok.size
    np.testing.assert_array_equal(sim.rad, np.full(ok.sum(), 100e-6))
    with pytest.raises(ValueError, match="positive"):
        sim.insert_radii([1e-4, -1e-4])
