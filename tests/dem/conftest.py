import pytest

from bedstruct.dem import Material
from dem_helpers import closed_box, two_sphere_sim  # noqa: F401


@pytest.fixture
def soft():
    """A soft glass-like material (SI)."""
    return Material(1e7, 0.3, 2500.0)

