import numpy as np
import pytest

import bedstruct
from bedstruct import Box, Frame
from bedstruct.analysis import bed_state
from lattices import cubic_lattice


def _slab(velocity=None, units="si"):
    """A 24 x 6 x 4 simple cubic bed of slightly overlapping 100 um spheres (CN 6 inside)."""
    bed = cubic_lattice((24, 6, 4), spacing=100e-6, radius=51e-6, boundary=("ff", "pp", "ff"))
    v = None if velocity is None else np.tile(velocity, (bed.n_particles, 1))
    return Frame(bed.positions, bed.radii, box=bed.box, velocities=v).with_units(units)


def _gas(n=100, spacing_d=4.0, speed=0.5, seed=0):
    """Spheres of 50 um on a loose jittered lattice, far apart, falling at `speed` m/s."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(n ** (1 / 3)))
    g = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), -1).reshape(-1, 3)[:n]
    pos = (g + 0.5) * spacing_d * 50e-6 + rng.normal(0, 2e-6, (n, 3))
    v = np.zeros((n, 3))
    v[:, 2] = -speed * rng.uniform(0.8, 1.2, n)
    return Frame(pos, np.full(n, 25e-6), box=Box([0, 0, 0], [side * spacing_d * 50e-6] * 3, boundary="ff ff ff"),
                 velocities=v).with_units("si")


def _settling(speed=0.13, seed=2):
    """A loose random cloud (packing ~0.15): a third of the particles touch one or two others."""
    rng = np.random.default_rng(seed)
    n, r = 1500, 50e-6
    side = (n * 4 / 3 * np.pi * r ** 3 / 0.15) ** (1 / 3)
    pos = rng.uniform(0, side, (n, 3))
    v = rng.normal(0, speed / 3, (n, 3))
    v[:, 2] -= speed
    return Frame(pos, np.full(n, r), box=Box([0, 0, 0], [side] * 3, boundary="ff ff ff"),
                 velocities=v).with_units("si")


def test_a_settled_bed_at_rest_is_a_bed_and_supports_every_analysis():
    s = bed_state(_slab(velocity=[1e-5, 0, 0]))
    assert s.kind == "settled bed" and s.is_bed
    assert s.network_fraction == 1.0 and s.velocities_used and s.moving_fraction == 0.0
    assert s.not_meaningful == {}
    assert s.peak < 0.05                        # a flat top
    # without velocities rest is assumed, and the reason says so
    s = bed_state(_slab())
    assert s.kind == "settled bed" and "rest assumed" in s.reason and not s.velocities_used


def test_the_same_bed_moving_is_a_moving_bed_without_static_analyses():
    # 0.13 m/s is 4 sqrt(g d) for 100 um spheres: flowing, not at rest
    s = bed_state(_slab(velocity=[0.13, 0, 0]))
    assert s.kind == "moving bed" and not s.is_bed
    assert s.moving_fraction == 1.0
    assert set(s.not_meaningful) == {"german", "coordination", "surface", "repose", "heat"}
    # 1 mm/s is 0.03 sqrt(g d): at rest
    assert bed_state(_slab(velocity=[1e-3, 0, 0])).kind == "settled bed"


def test_velocities_in_an_unknown_unit_system_are_not_judged():
    s = bed_state(_slab(velocity=[0.13, 0, 0], units=None))
    assert s.kind == "settled bed" and not s.velocities_used and np.isnan(s.moving_fraction)
    assert "unit system is unknown" in s.reason
    # LJ units are known but have no scale for gravity: said as such, not "give units"
    s = bed_state(_slab(velocity=[0.13, 0, 0], units="lj"))
    assert not s.velocities_used and "LJ units have no scale for gravity" in s.reason


def test_a_dilute_flow_has_no_bed_analyses():
    gas = _gas()
    s = bed_state(gas)
    assert s.kind == "dilute flow" and not s.is_bed
    assert s.mean_coordination == 0.0 and s.network_fraction == 0.0
    assert s.packing_fraction < 0.02
    for analysis in ("german", "coordination", "surface", "fabric", "harmonics", "repose", "heat"):
        assert not s.meaningful(analysis), analysis
    # still dilute when at rest in the dump or without velocities: no contact network
    assert bed_state(_gas(speed=0.0)).kind == "dilute flow"
    assert bed_state(Frame(gas.positions, gas.radii, box=gas.box)).kind == "dilute flow"


def test_a_settling_cloud_is_not_a_bed():
    f = _settling()
    s = bed_state(f)
    assert 0.1 < s.packing_fraction < 0.2 and s.network_fraction < 0.5
    assert s.kind in ("moving bed", "dilute flow") and not s.meaningful("german")
    # at rest, the same cloud is still not a bed: most particles are not held
    still = Frame(f.positions, f.radii, box=f.box).with_units("si")
    assert not bed_state(still).is_bed


def test_a_heap_is_a_pile_and_its_roughness_is_not_meaningful():
    lattice = cubic_lattice((40, 4, 20), spacing=1.0, radius=0.51, boundary=("ff", "pp", "ff"))
    x, z = lattice.positions[:, 0], lattice.positions[:, 2]
    heap = lattice.select(z <= 20.0 - np.abs(x - 20.0) * np.tan(np.radians(30)) * 1.5)
    s = bed_state(heap)
    assert s.kind == "pile" and s.is_bed and s.peak > 0.3
    assert set(s.not_meaningful) == {"surface"}


def test_a_vertical_axis_judges_the_shape_across_the_bed():
    # along z (vertical segregation, say) a flat bed is still a settled bed, and a heap a pile:
    # the top surface is judged along the horizontal axes, not in height slices
    assert bed_state(_slab(), axis=2).kind == "settled bed"
    lattice = cubic_lattice((40, 4, 20), spacing=1.0, radius=0.51, boundary=("ff", "pp", "ff"))
    x, z = lattice.positions[:, 0], lattice.positions[:, 2]
    heap = lattice.select(z <= 20.0 - np.abs(x - 20.0) * np.tan(np.radians(30)) * 1.5)
    s = bed_state(heap, axis=2)
    assert s.kind == "pile" and s.peak == pytest.approx(bed_state(heap, axis=0).peak)


def test_empty_frame_and_bad_axis():
    empty = Frame(np.zeros((0, 3)), np.zeros(0), box=Box([0, 0, 0], [1, 1, 1]))
    s = bed_state(empty)
    assert s.kind == "empty" and not s.meaningful("german")
    with pytest.raises(ValueError, match="`axis` must be 0, 1 or 2"):
        bed_state(_slab(), axis=3)


def test_third_party_dumps_dilute_and_settling_are_not_beds(realdata):
    import warnings
    cases = {"anabiman+pygran/examples/scripts/Particle-Analysis/Advanced/traj.dump": "dilute flow",
             "CFDEMproject+LIGGGHTS-PUBLIC/contactModels_v3.2.0/dump800.newModels": "dilute flow",
             "CFDEMproject+LIGGGHTS-PUBLIC/contactModels_v3.2.0/dump20000.newModels": "moving bed"}
    for rel, kind in cases.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            frame = bedstruct.read_dump(realdata / rel, units="si")[-1]
        s = bed_state(frame)
        assert s.kind == kind, (rel, s.reason)
        assert not s.meaningful("german")


def test_bundled_samples_are_a_settled_bed_and_a_pile():
    from pathlib import Path
    root = Path(__file__).parents[2] / "data" / "samples"
    bed = bedstruct.read_dump(root / "spread" / "bed.dump.gz", units="si")[-1]
    pile = bedstruct.read_dump(root / "repose" / "pile.dump.gz", units="si")[-1]
    assert bed_state(bed).kind == "settled bed"
    assert bed_state(pile).kind == "pile"
