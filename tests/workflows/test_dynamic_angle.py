"""The spreading workflow's dynamic angle on synthetic heaps of known front angle.

A heap ahead of a blade on a bare platform (layer 1: nothing ahead of the heap),
with a flat top, a rounded shoulder and a straight front flank, is drawn as a row
of spheres whose caps follow the profile. The measured angle must be the flank's;
a heap that runs into the end of the platform (front wall) has no free toe and
must give NaN, not the angle of its crest.
"""

import math

import numpy as np
import pytest

from bedstruct import Frame
from bedstruct.analysis import dynamic_angle_of_repose, find_contacts
from bedstruct.workflows.spread_measure import frame_metrics
from lattices import cubic_lattice

R = 25e-6              # sphere radius (m)
Z_PLAT = -400e-6       # platform level (the tool's lowest point is z = 0)
BLADE = 0.5e-3         # blade front face
HEIGHT = 1.0e-3        # heap height above the platform
FLAT = 4.0e-3          # length of the flat top, from the blade (a broad mound)
PLATE = 10e-3


def heap_profile(x, angle_deg, *, shoulder=1.0e-3):
    """Flat top, circular shoulder of radius ``shoulder`` tangent to both, straight flank."""
    t = math.tan(math.radians(angle_deg))
    a = math.radians(angle_deg)
    x1 = BLADE + FLAT                                   # shoulder starts (tangent to the top)
    x2 = x1 + shoulder * math.sin(a)                    # shoulder ends (tangent to the flank)
    h2 = HEIGHT - shoulder * (1 - math.cos(a))
    h = np.where(x <= x1, HEIGHT, np.nan)
    arc = (x > x1) & (x <= x2)
    h = np.where(arc, HEIGHT - shoulder + np.sqrt(np.clip(shoulder ** 2 - (x - x1) ** 2, 0, None)), h)
    flank = x > x2
    h = np.where(flank, h2 - t * (x - x2), h)
    return np.clip(h, 0.0, None)


def heap_frame(angle_deg, *, shoulder=1.0e-3):
    x = np.arange(BLADE + R, BLADE + FLAT + shoulder + HEIGHT / math.tan(math.radians(angle_deg)),
                  0.5 * R)
    h = heap_profile(x, angle_deg, shoulder=shoulder)
    keep = h > 0
    x, h = x[keep], h[keep]
    z = Z_PLAT + np.maximum(h, 2 * R) - R               # caps follow the profile, on the platform
    pos = np.c_[x, np.full(x.size, 0.3e-3), z]
    return Frame(pos, np.full(x.size, R), box=([0, 0, -1e-3], [12e-3, 0.6e-3, 3e-3]))


def toe_x(fr):
    return float(fr.positions[:, 0].max())


@pytest.mark.parametrize("angle", [25.0, 35.0, 45.0])
def test_front_flank_angle_of_a_shouldered_heap(angle):
    fr = heap_frame(angle)
    dyn, cn = frame_metrics(fr, find_contacts(fr), BLADE, plate_length=PLATE, z_plat=Z_PLAT,
                            r_max=R)
    assert dyn == pytest.approx(angle, abs=1.0)
    assert cn == pytest.approx(2 * find_contacts(fr).n_contacts / fr.n_particles, rel=1e-12)


def test_frame_coordination_of_a_lattice_is_six():
    # every sphere of a periodic simple-cubic lattice touches six others (the diagonal ones lie
    # 2.8 R apart): 2 N_c / N = 6
    fr = cubic_lattice((6, 5, 4), spacing=1.98 * R, radius=R)   # overlapping by 1 %
    _, cn = frame_metrics(fr, find_contacts(fr), 0.0, plate_length=PLATE, z_plat=Z_PLAT, r_max=R)
    assert cn == pytest.approx(6.0, rel=1e-12)


@pytest.mark.parametrize("angle, shoulder", [(35.0, 2.0e-3), (45.0, 1.0e-3)])
def test_band_measured_from_the_toe_not_from_the_profile_percentile(angle, shoulder):
    """The previous rule (bed level = 10th percentile of a profile that holds only the heap,
    as in layer 1) put the fitted band on the rounded shoulder of a broad heap: 29.4 and
    36.9 deg here. Measured from the toe, the band lies on the flank."""
    fr = heap_frame(angle, shoulder=shoulder)
    old = dynamic_angle_of_repose(fr, BLADE, spacing=0.5 * R).angle_deg
    assert old < angle - 5.0
    dyn, _ = frame_metrics(fr, find_contacts(fr), BLADE, plate_length=PLATE, z_plat=Z_PLAT,
                           r_max=R)
    assert dyn == pytest.approx(angle, abs=1.0)


def test_heap_at_the_front_wall_gives_nan():
    fr = heap_frame(35.0)
    # the platform ends halfway down the front flank: the toe is over the wall
    end = BLADE + FLAT + 1.0e-3 * math.sin(math.radians(35)) + 0.4 * HEIGHT / math.tan(math.radians(35))
    assert end < toe_x(fr)
    dyn, _ = frame_metrics(fr, find_contacts(fr), BLADE, plate_length=end, z_plat=Z_PLAT, r_max=R)
    assert math.isnan(dyn)


def test_low_heap_gives_nan():
    fr = heap_frame(35.0)
    flat = fr.select(fr.positions[:, 2] < Z_PLAT + 3 * R)   # only the toe: below two diameters
    dyn, _ = frame_metrics(flat, find_contacts(flat), BLADE, plate_length=PLATE, z_plat=Z_PLAT,
                           r_max=R)
    assert math.isnan(dyn)


def test_inserted_block_with_a_vertical_front_gives_nan():
    """A cohesive block as inserted (flat top sloping 10 deg, vertical front face on the
    platform) is not a heap: its silhouette ends one radius below its top edge, far above the
    bed, and the fitted band would be its top (10 deg)."""
    xs = np.arange(BLADE + R, BLADE + 2.0e-3, 2 * R)
    cols = []
    for x in xs:
        top = Z_PLAT + HEIGHT - math.tan(math.radians(10.0)) * (x - BLADE)
        zs = np.arange(Z_PLAT + R, top, 2 * R)
        cols.append(np.c_[np.full(zs.size, x), np.full(zs.size, 0.3e-3), zs])
    pos = np.concatenate(cols)
    fr = Frame(pos, np.full(len(pos), R), box=([0, 0, -1e-3], [12e-3, 0.6e-3, 3e-3]))
    old = dynamic_angle_of_repose(fr, BLADE, spacing=0.5 * R).angle_deg
    assert old < 20.0                       # what the previous rule reported
    dyn, _ = frame_metrics(fr, find_contacts(fr), BLADE, plate_length=PLATE, z_plat=Z_PLAT,
                           r_max=R)
    assert math.isnan(dyn)
