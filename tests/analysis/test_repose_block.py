"""A cohesive block that did not slump has no angle of repose (NaN), not a ~0 deg reading."""

import numpy as np

from bedstruct import Frame
from bedstruct.analysis import angle_of_repose


def _block(bump: float):
    # a flat-topped slab of spheres with vertical sides and one sphere sticking up at the centre
    x = np.arange(0.25, 20, 0.5)
    cols = [np.c_[x, np.zeros_like(x), np.full_like(x, z)] for z in np.arange(0.25, 6, 0.5)]
    pts = np.concatenate(cols + [np.array([[10.25, 0.0, 5.75 + bump]])])
    return Frame(pts, np.full(len(pts), 0.25), box=([-5, -1, -1], [25, 1, 12]))


def test_a_flat_topped_block_has_no_flank():
    for bump in (1.0, 2.0):
        res = angle_of_repose(_block(bump), spacing=0.1, base=0.0)
        assert np.isnan(res.angle_deg), (bump, res.left_deg, res.right_deg)


def test_a_wedge_is_still_fitted():
    x = np.arange(0.25, 40, 0.5)
    z = np.clip(10 - np.tan(np.radians(35)) * abs(x - 20), 0, None)
    f = Frame(np.c_[x, np.zeros_like(x), z], np.full(x.size, 0.25), box=([0, -1, -1], [40, 1, 12]))
    assert abs(angle_of_repose(f, spacing=0.1).angle_deg - 35.0) < 0.5
