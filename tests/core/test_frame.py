import numpy as np
import pytest

from bedstruct import Contacts, Frame, Units
from bedstruct.core import lens_radius
from bedstruct.core.frame import UNIT_STYLES


def test_defaults_and_volume():
    f = Frame(np.zeros((3, 3)), [1, 1, 1], box=[5, 5, 5])
    assert f.ids.tolist() == [1, 2, 3] and f.types.tolist() == [1, 1, 1]
    assert f.units.style == "si"
    assert np.isclose(f.particle_volume, 3 * 4 / 3 * np.pi)


@pytest.mark.parametrize("radii, msg", [([1, -1], "positive"), ([1, np.nan], "positive"),
                                        ([1], "shape")])
def test_bad_radii(radii, msg):
    with pytest.raises(ValueError, match=msg):
        Frame(np.zeros((2, 3)), radii, box=[1, 1, 1])


def test_nan_position_rejected():
    with pytest.raises(ValueError, match="finite"):
        Frame([[0, 0, np.inf]], [1], box=[1, 1, 1])


def test_zero_atoms():
    f = Frame(np.empty((0, 3)), np.empty(0), box=[1, 1, 1])
    assert f.n_particles == 0 and f.particle_volume == 0.0


def test_select_and_sort():
    f = Frame(np.arange(9.0).reshape(3, 3), [1, 2, 3], box=[10, 10, 10], ids=[5, 2, 9],
              columns={"mass": np.array([1.0, 2.0, 3.0])})
    s = f.sorted_by_id()
    assert s.ids.tolist() == [2, 5, 9]
    assert s.columns["mass"].tolist() == [2.0, 1.0, 3.0]
    assert np.array_equal(s.positions[0], [3, 4, 5])


def test_to_si_records_conversion():
    f = Frame([[1.0, 2.0, 3.0]], [0.5], box=[10, 10, 10], units="cgs",
              velocities=[[1.0, 0, 0]], columns={"density": np.array([8.3]), "c_x": np.array([1.0])})
    g = f.to_si()
    assert np.allclose(g.positions, [[0.01, 0.02, 0.03]])
    assert np.isclose(g.radii[0], 0.005) and np.isclose(g.box.hi[0], 0.1)
    assert np.isclose(g.columns["density"][0], 8300.0)
    assert g.units.style == "si" and "cgs -> si" in g.units.conversions[0]
    assert "c_x" in g.units.conversions[0]
    with pytest.raises(ValueError, match="SI"):
        Units("lj").to_si("length")


@pytest.mark.parametrize("style", ["si", "cgs", "micro", "nano"])
def test_unit_styles_are_dimensionally_consistent(style):
    # velocity = L/T, force = M L/T^2, density = M/L^3 in the coherent styles (real, metal
    # and electron take force from kcal/mol, eV or Hartree and density in g/cm^3: tested below)
    u = UNIT_STYLES[style]
    assert u["velocity"] == pytest.approx(u["length"] / u["time"], rel=1e-12)
    assert u["force"] == pytest.approx(u["mass"] * u["length"] / u["time"] ** 2, rel=1e-12)
    assert u["density"] == pytest.approx(u["mass"] / u["length"] ** 3, rel=1e-12)


@pytest.mark.parametrize("style, mass_kg", [("si", 1.0), ("cgs", 1e-3), ("micro", 1e-15),
                                             ("nano", 1e-21)])
def test_unit_styles_mass_is_lammps(style, mass_kg):
    # LAMMPS `units`: kilogram, gram, picogram, attogram
    assert UNIT_STYLES[style]["mass"] == mass_kg


def test_lens_radius_against_geometry():
    rng = np.random.default_rng(0)
    r1, r2 = rng.uniform(0.5, 2, 100), rng.uniform(0.5, 2, 100)
    d = rng.uniform(np.abs(r1 - r2) + 1e-3, r1 + r2 - 1e-3)
    a = lens_radius(r1, r2, d)
    x = (d**2 + r1**2 - r2**2) / (2 * d)
    # the circle lies on both spheres
    assert np.allclose(a**2 + x**2, r1**2)
    assert np.allclose(a**2 + (d - x) ** 2, r2**2)


def test_contacts_geometry_and_counts():
    c = Contacts(i=[0, 0], j=[1, 2], branch=[[1.8, 0, 0], [0, 2.5, 0]], radii_i=[1, 1],
                 radii_j=[1, 1], n_particles=4)
    assert np.allclose(c.overlap, [0.2, -0.5])
    assert c.touching().n_contacts == 1
    assert c.per_particle_count().tolist() == [2, 1, 1, 0]
    assert np.allclose(np.linalg.norm(c.normals, axis=1), 1)
    with pytest.raises(ValueError, match="indices"):
        Contacts(i=[0], j=[5], branch=[[1, 0, 0]], radii_i=[1], radii_j=[1], n_particles=2)


def test_scalar_radius_broadcasts():
    f = Frame(np.zeros((3, 3)), 0.5, box=[2, 2, 2])
    assert f.radii.tolist() == [0.5, 0.5, 0.5]


def test_every_lammps_unit_style_but_lj_has_its_si_factors():
    """The styles a reader accepts all convert: real and metal in Angstrom, electron in Bohr."""
    from bedstruct.core import UNIT_STYLES, Units
    from bedstruct.io._text import LAMMPS_UNIT_STYLES
    assert set(LAMMPS_UNIT_STYLES) - {"lj"} == set(UNIT_STYLES)
    metal, real, electron = Units("metal"), Units("real"), Units("electron")
    assert metal.length_unit == "Å" and metal.to_si("length") == 1e-10
    assert metal.velocity_unit == "Å/ps" and metal.to_si("velocity") == pytest.approx(100.0)
    assert real.to_si("time") == 1e-15 and real.to_si("velocity") == pytest.approx(1e5)
    # kcal/mol/A and eV/A in newtons; g/mol in kg
    assert real.to_si("force") == pytest.approx(6.9477e-11, rel=1e-4)
    assert metal.to_si("force") == pytest.approx(1.602176634e-9)
    assert metal.to_si("mass") == pytest.approx(1.66053907e-27, rel=1e-8)
    # velocity = length / time in every style but electron's atomic time unit
    for style in set(UNIT_STYLES) - {"electron"}:
        u = UNIT_STYLES[style]
        assert u["velocity"] == pytest.approx(u["length"] / u["time"]), style
    assert electron.length_unit == "Bohr" and electron.velocity_unit == "Bohr/atu"
    with pytest.raises(ValueError, match="define no density"):
        electron.to_si("density")
    with pytest.raises(ValueError, match="unknown quantity"):
        metal.to_si("charge")


def test_report_lengths_in_natural_units_from_nm_to_m():
    from bedstruct.report._render import _display_unit
    assert _display_unit(0.5, "nm") == (pytest.approx(1.0), "nm")
    assert _display_unit(5.0, "Å")[1] == "nm"
    assert _display_unit(2.1, "m") == (pytest.approx(1.0), "m")
    assert _display_unit(25e-6, "m")[1] == "µm" and _display_unit(2e-3, "m")[1] == "mm"
