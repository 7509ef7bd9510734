"""Build a report on one or more dumps: every analysis, section by section.

Each section runs on its own: one that fails is marked failed (with the
reason) and the rest of the report still renders.
"""

from __future__ import annotations

import gc
import logging
import dataclasses
from typing import Sequence

import numpy as np

from .._version import __version__
from ..core import Contacts, Frame
from ._model import Quantity, Report, Section, Table, not_meaningful_section, run_section, skip
from .options import ReportOptions

__all__ = ["build_report"]

log = logging.getLogger(__name__)

DOCS = "docs/"  # definitions live in the project docs (docs/*.md)


def _figure_of(obj):
    """The Figure behind what a plot function returned (Figure, Axes, (fig, ax) or axes)."""
    from matplotlib.figure import Figure
    if isinstance(obj, Figure):
        return obj
    if isinstance(obj, tuple) and obj and isinstance(obj[0], Figure):
        return obj[0]
    if isinstance(obj, (list, tuple, np.ndarray)):
        return _figure_of(np.ravel(obj)[0])
    return obj.figure


class _Context:
    """What the sections share: the frames, contacts and derived regions."""

    def __init__(self, frames: list[Frame], contacts: Contacts | None, options: ReportOptions,
                 frame_indices: list[int]):
        self.frames = frames
        self.frame = frames[-1]
        self.options = options
        self.frame_indices = frame_indices
        #: The gaps of the supplied contacts (:func:`contact_gaps`), None without a contact file.
        self.contact_check = None if contacts is None else contact_gaps(self.frame, contacts)
        # contacts that are mostly apart are not used: geometric detection stands in for them
        # where the input is judged, and the sections built on contacts say why they are absent
        self._contacts = None if self.contact_check and self.contact_check["apart"] else contacts
        self._windows = None
        self._region_fractions = None
        self._coordination = None
        self.state = None
        from ..analysis import flat_axis
        self.flat_axis = flat_axis(self.frame)

    @property
    def length_unit(self) -> str:
        return self.frame.units.length_unit

    def plot_unit(self, values) -> tuple[float, str]:
        """(factor, unit) to plot lengths of these magnitudes in um or mm (as the page shows them)."""
        from ._render import _display_unit
        if self.length_unit == "unknown":
            return 1.0, "length unit of the dump"
        return _display_unit(list(np.ravel(values)), self.length_unit)

    @property
    def contacts(self) -> Contacts:
        if self._contacts is None:
            from ..analysis import find_contacts
            self._contacts = find_contacts(self.frame, self.options.tolerance)
        return self._contacts

    def coordination(self):
        """The frame's coordination (:func:`bedstruct.analysis.coordination`), computed once."""
        if self._coordination is None:
            from ..analysis import coordination
            self._coordination = coordination(self.frame, self.contacts,
                                              min_contacts=self.options.min_contacts)
        return self._coordination

    def region_fractions(self):
        """Area fractions of the regions of a 2-D run (a PackingProfile)."""
        if self._region_fractions is None:
            from ..analysis import area_fractions
            self._region_fractions = area_fractions(self.frame, *self.windows())
        return self._region_fractions

    def windows(self):
        if self._windows is None:
            from ..analysis import bed_windows
            self._windows = bed_windows(self.frame, self.options.regions, axis=self.options.axis_index)
        return self._windows


# ---------------------------------------------------------------- sections
def _summary(ctx: _Context, s: Section) -> None:
    f = ctx.frame
    s.add_number("n_frames_selected", len(ctx.frames), "1",
                 "number of frames selected; the detailed sections describe the last of them, the "
                 "others contribute only their timestep and particle count to the table of frames")
    s.add_number("frame_index", ctx.frame_indices[-1], "1",
                 "index (over the frames read) of the frame the detailed sections describe")
    s.add_number("timestep", f.timestep, "steps", "timestep of the frame the detailed sections describe")
    s.add_number("n_particles", f.n_particles, "1", "number of spheres in the frame")
    s.add_number("box_lo", f.box.lo, ctx.length_unit, "lower box bounds (x, y, z)")
    s.add_number("box_hi", f.box.hi, ctx.length_unit, "upper box bounds (x, y, z)")
    s.add_number("boundary", " ".join(f.box.boundary), "-", "LAMMPS boundary flags per axis")
    s.add_number("units", f.units.style or "unknown", "-", "unit system of the dump")
    s.add_number("radius_range", [float(f.radii.min()), float(f.radii.max())] if f.n_particles else None,
                 ctx.length_unit, "smallest and largest sphere radius")
    s.tables.append(Table(["frame index", "timestep", "n_particles"],
                          [[k, fr.timestep, fr.n_particles] for k, fr in zip(ctx.frame_indices, ctx.frames)],
                          caption="frames selected (the last one is described by the sections below)"))
    notes = list(f.provenance.notes) + list(f.units.conversions)
    text = [_described_frame(ctx)]
    text.append(f"Source: {f.provenance.source or 'in memory'}." + (" Notes: " + "; ".join(notes) if notes else ""))
    s.text = " ".join(text)


def _described_frame(ctx: _Context) -> str:
    """Which frame the detailed sections describe, and what the other frames selected add."""
    f, n = ctx.frame, len(ctx.frames)
    if n == 1:
        return f"Every section describes the one frame selected (timestep {f.timestep})."
    return (f"The sections below describe one frame: the last of the {n} selected (timestep "
            f"{f.timestep}, frame index {ctx.frame_indices[-1]}). The other {n - 1} frames add only "
            f"their timestep and particle count to the table of frames; no number is averaged over them.")


def _packing(ctx: _Context, s: Section) -> None:
    from ..analysis import packing_along, packing_fraction
    f, opt = ctx.frame, ctx.options
    if ctx.flat_axis is not None:
        return _area_packing(ctx, s)
    seed_def = packing_fraction(f)
    apart = _apart(ctx)
    if apart:
        s.text = (f"{apart} particle{'s lie' if apart != 1 else ' lies'} apart from the bed (more "
                  f"than two diameters beyond its contact network): the enclosing box, and with it "
                  f"these fractions, reaches out to {'them' if apart != 1 else 'it'}. The German's-law "
                  f"windows leave {'them' if apart != 1 else 'it'} out.")
    s.add_number("bounding_box_fraction", seed_def.fraction, "1",
                 "total particle volume over the volume of the box enclosing all particles "
                 "(the seed report's definition)", DOCS + "analysis.md, Packing fraction")
    prof = packing_along(f, opt.regions, axis=opt.axis_index)
    for name, value in zip(opt.region_names, prof.fractions):
        s.add_number(f"fraction_{name.replace(' ', '_')}", value, "1",
                     f"exact sphere-cuboid packing fraction of the {name} region of the bed")
    from ..plot import plot_packing_profile
    fine = packing_along(f, max(12, 4 * opt.regions), axis=opt.axis_index)
    factor, unit = ctx.plot_unit(np.asarray(fine.upper)[:, opt.axis_index])
    fig = _figure_of(plot_packing_profile(fine, axis=opt.axis_index, unit=unit, scale=factor))
    s.add_figure(fig, f"Packing fraction in {len(fine.fractions)} windows along the bed")


def _apart(ctx: _Context) -> int:
    """Particles apart from the bed (:func:`bedstruct.analysis.apart_from_bed`)."""
    from ..analysis import apart_from_bed
    network = ~np.asarray(ctx.coordination().rattlers, dtype=bool)
    return int(apart_from_bed(ctx.frame, network).sum())


def _area_packing(ctx: _Context, s: Section) -> None:
    """The packing section of a 2-D run: area fractions of the discs in their plane."""
    from ..analysis import area_fraction, area_fractions, bed_windows
    from ..plot import plot_packing_profile
    f, opt = ctx.frame, ctx.options
    plane = "-".join("xyz"[a] for a in range(3) if a != ctx.flat_axis)
    s.text = (f"A 2-D run: the particles are discs in the {plane} plane, and the packing is their "
              f"area fraction.")
    whole = area_fraction(f)
    s.add_number("bounding_box_area_fraction", whole.fraction, "1",
                 "total disc area over the area of the rectangle enclosing all discs in their plane "
                 "(the box along periodic axes)", DOCS + "analysis.md, Packing fraction")
    if opt.axis_index == ctx.flat_axis:
        return
    prof = ctx.region_fractions()
    for name, value in zip(opt.region_names, prof.fractions):
        s.add_number(f"area_fraction_{name.replace(' ', '_')}", value, "1",
                     f"exact disc-rectangle area fraction of the {name} region of the bed")
    fine = area_fractions(f, *bed_windows(f, max(12, 4 * opt.regions), axis=opt.axis_index))
    factor, unit = ctx.plot_unit(np.asarray(fine.upper)[:, opt.axis_index])
    fig = _figure_of(plot_packing_profile(fine, axis=opt.axis_index, unit=unit, scale=factor))
    s.add_figure(fig, f"Area fraction of the discs in {len(fine.fractions)} windows along the bed")


def _coordination(ctx: _Context, s: Section) -> None:
    from ..analysis import coordination_by_window, german_law_along, packing_along
    f, opt = ctx.frame, ctx.options
    res = ctx.coordination()
    s.add_number("mean", res.mean, "1", "mean number of contacts per particle",
                 DOCS + "analysis.md, Coordination number")
    s.add_number("mean_excluding_rattlers", res.mean_excluding_rattlers, "1",
                 f"mean coordination over particles that are not rattlers (all their contacts "
                 f"counted); rattlers: fewer than {res.min_contacts} contacts after iterative removal")
    s.add_number("mechanical", res.mechanical, "1",
                 "mechanical coordination number: mean contacts after iterative rattler removal")
    s.add_number("rattler_fraction", res.rattler_fraction, "1", "fraction of particles that are rattlers")
    s.add_number("n_contacts", ctx.contacts.n_contacts, "1", f"particle-particle contacts ({ctx.contacts.source})")
    region = packing_along(f, opt.regions, axis=opt.axis_index) if ctx.flat_axis is None \
        else ctx.region_fractions()
    per_region = coordination_by_window(f, region.lower, region.upper, result=res)
    rows = []
    for k, name in enumerate(opt.region_names):
        mean_k = float(np.asarray(per_region.mean)[k])
        rows.append([name, region.fractions[k], mean_k, float(np.asarray(per_region.mechanical)[k]),
                     int(np.asarray(per_region.n_particles)[k])])
        s.add_number(f"mean_{name.replace(' ', '_')}", mean_k, "1", f"mean coordination in the {name} region")
    s.tables.append(Table(["region", "packing fraction" if ctx.flat_axis is None else "area fraction",
                           "mean CN", "mechanical CN", "particles"], rows,
                          caption=f"coordination and packing per region ({_regions_text(region, opt, ctx)})",
                          units=["", "1", "1", "1", "1"]))
    if ctx.state is not None and not ctx.state.meaningful("german"):
        s.text = f"No German's-law fit: {ctx.state.not_meaningful['german']}."
        return
    # German's law: the library's one definition (german_law_along, its default windows)
    german = german_law_along(f, n_windows=opt.german_windows, axis=opt.axis_index, coordination_result=res,
                              check_state=False)   # judged above, as for every section
    s.add_number("german_windows", german.n_used, "1", "windows fitted: " + german.definition,
                 DOCS + "analysis.md, German's law")
    fit = german.fit
    if fit is None:
        s.text = (f"Too few populated windows for a German's-law fit ({german.n_used} of "
                  f"{german.n_windows} with at least {german.min_particles} particles; need 3).")
        return
    where = f"over {german.n_used} windows along {opt.axis}"
    s.add_number("german_a", fit.a, "1", f"fitted a in CN = 2a + 11 b f^2, {where}", DOCS + "analysis.md, German's law")
    s.add_number("german_b", fit.b, "1", f"fitted b in CN = 2a + 11 b f^2, {where}")
    s.add_number("german_a_ci", list(fit.a_ci), "1", f"{fit.confidence:.0%} confidence interval of a")
    s.add_number("german_b_ci", list(fit.b_ci), "1", f"{fit.confidence:.0%} confidence interval of b")
    s.add_number("german_unfitted_deviation", fit.unfitted_deviation, "1",
                 "mean absolute difference between CN = 2 + 11 f^2 and the measured CN")
    s.add_number("german_determined", fit.determined, "1",
                 "whether the windows determine a and b separately (the interval of b excludes 0 "
                 "and that of a does not lie below 0)")
    if not fit.determined:
        s.text = (f"German's law over {german.n_used} windows along {opt.axis}: "
                  f"{fit.undetermined_reason}; a and b are listed with their intervals, but "
                  f"describe only the windows' mean coordination ({float(np.mean(fit.cn)):.2f}). "
                  f"The original law's deviation keeps its meaning.")
    from ..plot import plot_german
    fig = _figure_of(plot_german(fit, label=f"{german.n_used} windows along {opt.axis}"))
    s.add_figure(fig, f"Coordination number against packing fraction with German's law ({german.definition})")


def _rdf(ctx: _Context, s: Section) -> None:
    from ..analysis import radial_distribution
    from ..plot import plot_rdf
    f = ctx.frame
    if f.n_particles < 2:
        skip(f"{f.n_particles} particles: no pairs")
    if np.any(np.asarray(f.box.tilt) != 0):
        skip("the box is tilted: g(r) is computed for orthogonal boxes only")
    flat = [k for k in range(3) if not f.box.periodic[k] and np.ptp(f.positions[:, k]) == 0]
    if flat:
        skip(f"every particle centre has the same {' and '.join('xyz'[k] for k in flat)} along a bounded "
             f"axis: the centres span no volume, and g(r) is undefined")
    d50 = float(np.median(2 * f.radii))
    res = radial_distribution(f)
    if res.first_peak is None:
        skip(f"no pair of particle centres within the cutoff ({res.cutoff:.4g} {ctx.length_unit})")
    r_peak, g_peak = res.first_peak
    unit = ctx.length_unit
    s.text = ("Pairs of particle centres by distance, over those of an ideal gas of the same density in the "
              "same region (the box along periodic axes, the extent of the particle centres along bounded "
              "ones), so walls and the free surface do not pull g(r) below 1.")
    s.add_number("peak_r", r_peak, unit, "distance of the highest g(r) bin (the first neighbour shell)",
                 DOCS + "analysis.md, Radial distribution function")
    s.add_number("peak_r_over_d50", r_peak / d50, "1", "that distance over the median diameter")
    s.add_number("peak_g", g_peak, "1", "g(r) at the highest bin")
    s.add_number("cutoff", res.cutoff, unit, f"largest distance ({len(res.r)} bins)")
    s.add_number("density", res.density, f"1/{unit}^3" if unit != "unknown" else "1/length^3",
                 "number density of the region")
    s.add_figure(_figure_of(plot_rdf(res, diameter=d50)),
                 "Radial distribution function against distance over the median diameter d50")


def _voronoi(ctx: _Context, s: Section) -> None:
    from ..analysis import local_packing
    from ..plot import plot_local_packing
    f, opt = ctx.frame, ctx.options
    if np.any(np.asarray(f.box.tilt) != 0):
        skip("the box is tilted: the tessellation is computed for orthogonal boxes only")
    try:
        lp = local_packing(f)
    except ImportError as exc:
        skip(str(exc))
    inside = ~lp.at_wall
    s.text = ("Each particle's volume over that of its radical (Laguerre) Voronoi cell, from voro++ "
              "(pyvoro2), periodic along periodic axes; along bounded ones the region ends at the "
              "particles' extent, and cells closed by it (at a wall or the free surface) are shown apart.")
    s.add_number("mean_inside", lp.mean(), "1", "particle volume over cell volume of the cells not at a wall "
                 "or the free surface", DOCS + "analysis.md, Local packing (radical Voronoi)")
    s.add_number("mean_all", lp.mean(np.ones(lp.n_particles, bool)), "1",
                 "particle volume over cell volume of all cells (the region's packing fraction)")
    s.add_number("median_inside", float(np.median(lp.fractions[inside])) if inside.any() else None, "1",
                 "median local packing fraction of the cells inside")
    s.add_number("std_inside", float(np.std(lp.fractions[inside])) if inside.any() else None, "1",
                 "standard deviation of the local packing fraction of the cells inside")
    s.add_number("wall_cell_fraction", float(lp.at_wall.mean()), "1",
                 "fraction of cells at a wall or the free surface")
    factor, unit = ctx.plot_unit(f.positions[:, opt.axis_index])
    s.add_figure(plot_local_packing(lp, f.positions, axis=opt.axis_index, unit=unit, scale=factor),
                 f"Local packing fraction per particle: histogram, and along {opt.axis} with the value "
                 f"of 24 windows")


def _psd(ctx: _Context, s: Section) -> None:
    from ..analysis import particle_size_distribution, psd_by_region, segregation_index
    f, opt = ctx.frame, ctx.options
    whole = particle_size_distribution(f, weighting="volume")
    for q in ("d10", "d50", "d90"):
        s.add_number(q, getattr(whole, q), ctx.length_unit,
                     f"volume-weighted {q.upper()} diameter of the whole frame", DOCS + "analysis.md, Particle size distribution")
    lower, upper = ctx.windows()
    regions = psd_by_region(f, lower, upper, weighting="volume")
    from ..plot import plot_psd
    rows = [[name, r.n_particles, r.d10, r.d50, r.d90] for name, r in zip(opt.region_names, regions)]
    shown = [(name, r) for name, r in zip(opt.region_names, regions) if r.n_particles]
    factor, unit = ctx.plot_unit([whole.d90])
    fig = _figure_of(plot_psd([whole] + [r for _, r in shown], labels=["whole bed"] + [n for n, _ in shown],
                              cumulative=True, unit=unit, scale=factor))
    s.add_figure(fig, "Cumulative size distribution per region")
    L = ctx.length_unit
    s.tables.append(Table(["region", "particles", "D10", "D50", "D90"], rows,
                          caption="volume-weighted percentiles per region", units=["", "1", L, L, L]))
    if len(regions) >= 2:
        # the first and last regions themselves: an empty one leaves the shift undefined
        first, last = regions[0], regions[-1]
        shift = last.d50 - first.d50 if first.n_particles and last.n_particles else None
        s.add_number("d50_shift_start_to_end", shift, ctx.length_unit,
                     "D50 of the last region minus D50 of the first (none when either is empty)")
    s.add_number("segregation_index", segregation_index(f, lower, upper), "1",
                 "spread of local mean size over the mean size")


def _surface(ctx: _Context, s: Section) -> None:
    from ..analysis import surface_height_map
    f = ctx.frame
    plate = float(np.min(f.positions[:, 2] - f.radii)) if f.n_particles else 0.0
    surf = surface_height_map(f)
    r = surf.roughness
    for key, text in (("sa", "arithmetic mean height deviation Sa"), ("sq", "root-mean-square height Sq"),
                      ("sz", "maximum height Sz (peak to valley)")):
        s.add_number(key, getattr(r, key), ctx.length_unit, text, DOCS + "analysis.md, Surface and layers")
    s.add_number("ssk", r.ssk, "1", "skewness of the height distribution Ssk")
    s.add_number("mean_surface_z", r.mean_height, ctx.length_unit, "mean height (z) of the top surface")
    s.add_number("bed_thickness", r.mean_height - plate, ctx.length_unit,
                 "mean top-surface height above the lowest particle bottom (taken as the plate)")
    s.add_number("uncovered_fraction", surf.uncovered_fraction, "1", "fraction of grid cells with no particle")
    from ..plot import plot_height_map
    factor, unit = ctx.plot_unit([np.ptp(surf.x)])
    fig = _figure_of(plot_height_map(surf, unit=unit, scale=factor))
    s.add_figure(fig, "Top-surface height map (highest particle cap per cell)")


def _fabric(ctx: _Context, s: Section) -> None:
    from ..analysis import fabric_tensors, region_fabric
    from ..plot import plot_fabric_differences, plot_rose_2d, plot_rose_grid
    c, opt = ctx.contacts.touching(), ctx.options
    if c.n_contacts < 10:
        skip(f"only {c.n_contacts} touching contacts: too few for fabric tensors")
    whole = fabric_tensors(c.normals)
    s.add_number("eigenvalues_N2", whole.eigenvalues, "1", "eigenvalues of the moment tensor N_ij (sum 1)",
                 DOCS + "fabric.md")
    s.add_number("anisotropy", whole.anisotropy, "1", "rank-2 anisotropy of the contact normals")
    s.add_number("anisotropy_noise", whole.anisotropy_noise, "1",
                 "rank-2 anisotropy that as many isotropic random normals give by sampling alone "
                 "(RMS, 7.5/sqrt(contacts)): an anisotropy within about twice it says nothing")
    s.add_number("anisotropy_rank4", whole.anisotropy_rank4, "1", "rank-4 anisotropy of the contact normals")
    reg = region_fabric(c, ctx.frame, axis=opt.axis_index, n_regions=opt.regions)
    rows = []
    for name, t in zip(opt.region_names, reg.tensors):
        rows.append([name, int(t.n_contacts), *(float(v) for v in t.eigenvalues), float(t.anisotropy),
                     float(t.anisotropy_noise)])
    s.tables.append(Table(["region", "contacts", "λ1", "λ2", "λ3", "anisotropy", "isotropic noise"], rows,
                          caption=f"moment-tensor eigenvalues per region: {len(opt.region_names)} equal slabs "
                                  f"along {opt.axis} by contact point; isotropic noise: the RMS anisotropy "
                                  f"of as many isotropic random normals", units=["", "1", "1", "1", "1", "1", "1"]))
    s.add_figure(plot_rose_grid(reg.tensors, names=opt.region_names),
                 "3-D rose diagrams per region: rank 2, rank 4 and their difference")
    if opt.regions >= 2:
        s.add_figure(plot_fabric_differences(reg.tensors, names=opt.region_names),
                     "Difference of contact-normal densities between regions (red: gain, blue: loss)")
    s.add_figure(plot_rose_2d(c.normals, tensors=whole), "Planar roses of contact normals with the rank-4 approximation")


def _harmonics(ctx: _Context, s: Section) -> None:
    from ..analysis import contact_regions, harmonic_expansion
    from ..plot import plot_harmonic_power
    c, opt = ctx.contacts.touching(), ctx.options
    if c.n_contacts < 10:
        skip(f"only {c.n_contacts} touching contacts")
    whole = harmonic_expansion(c.normals, opt.l_max)
    degrees = list(range(0, opt.l_max + 1, 2))
    # P_l / P_0 throughout (numbers, table and figure): 0 for isotropic normals, the 4 pi of the
    # normalisation of the Y_lm divided out
    for l in degrees[1:]:
        s.add_number(f"power_l{l}", whole.power[l] / whole.power[0], "1",
                     f"rotation-invariant power of degree {l} over that of degree 0, P_{l}/P_0 "
                     f"(0 for isotropic contact normals; {2 * l + 1}/contacts = "
                     f"{(2 * l + 1) / c.n_contacts:.2g} from sampling {c.n_contacts} isotropic normals)",
                     DOCS + "fabric.md")
    labels, edges = contact_regions(c, ctx.frame, axis=opt.axis_index, n_regions=opt.regions)
    present = [k for k in range(opt.regions) if np.any(labels == k)]
    names = [opt.region_names[k] for k in present]
    exps = [harmonic_expansion(c.normals[labels == k], opt.l_max) for k in present]
    unit = ctx.length_unit
    counts = [int(np.count_nonzero(labels == k)) for k in present]
    rows = [[n, float(edges[k]), float(edges[k + 1]), m] + [float(e.power[l] / e.power[0]) for l in degrees[1:]]
            for k, n, e, m in zip(present, names, exps, counts)]
    s.tables.append(Table(["region", f"{opt.axis} from", f"{opt.axis} to", "contacts"]
                          + [f"P_{l}/P_0" for l in degrees[1:]],
                          rows, caption=f"rotation-invariant harmonic power per degree over P_0, per region along "
                                        f"{opt.axis} (contacts by contact point); M isotropic random normals give "
                                        f"P_l/P_0 = (2l+1)/M by sampling alone",
                          units=["", unit, unit, "1"] + ["1"] * len(degrees[1:])))
    fig = plot_harmonic_power(exps, degrees=degrees[1:], labels=names, relative=True,
                              xlabel=f"region along {opt.axis} (bounds in the table)")
    s.add_figure(_figure_of(fig), "Spherical-harmonic power P_l/P_0 per degree, per region along the bed "
                                  "(the table's numbers)")


def _repose(ctx: _Context, s: Section) -> None:
    from ..analysis import pile_angle
    f, opt = ctx.frame, ctx.options
    if opt.axis_index == 2:
        skip("the flanks of a pile are fitted along a horizontal axis, and the axis of the report "
             "is z, the vertical: give --axis x or y for the angle of repose")
    try:
        pa = pile_angle(f, axis=opt.axis_index, base=opt.repose_base)
    except ValueError as exc:
        skip(f"no pile with two flanks found ({exc})")
    res = pa.repose
    if not (np.isfinite(res.angle_deg) and res.angle_deg > 5.0
            and res.angle_deg > 2.0 * np.nan_to_num(res.angle_std_deg, nan=np.inf)):
        found = (f" ({res.angle_deg:.1f} deg, fit uncertainty {res.angle_std_deg:.1f} deg)"
                 if np.isfinite(res.angle_deg) and np.isfinite(res.angle_std_deg) else "")
        skip(f"no pile found: the free surface has no clear slope{found}")
    # A heap has two flanks, or one steep wedge against a wall; a spread layer is long and thin
    # with a sloped end, whose slope is not an angle of repose.
    h = np.asarray(res.profile_h, dtype=float)
    x = np.asarray(res.profile_x, dtype=float)
    ok = np.isfinite(h)
    aspect = float(np.ptp(h[ok]) / max(np.ptp(x[ok]), 1e-300)) if ok.sum() > 1 else 0.0
    two_flanks = np.isfinite(res.left_deg) and np.isfinite(res.right_deg)
    if not (two_flanks or aspect >= 0.2):
        skip(f"no pile found: one sloped flank on a layer {aspect:.2f} times as high as long "
             f"(a spread layer, not a heap)")
    unit = ctx.length_unit
    surface = ("median free surface (a wedge)" if pa.shape == "wedge" else
               "silhouette, the highest point (a cone: the median would lie below its flanks),")
    where = ("above the plate height given (--repose-base)" if not pa.base_found else
             "on the largest cluster of touching particles, above the plate its bottom layer rests on "
             "(give --repose-base to set the plate height)")
    s.text = (f"Measured by analysis.pile_angle {where}: {pa.n_particles} of {f.n_particles} particles "
              f"({pa.n_left_out} left out: other clusters, below the plate); "
              f"{surface} across the width, flanks fitted robustly between 20 % and 80 % of the pile height. One pile: "
              f"the +- is the fit uncertainty of its mean angle, not a scatter between piles "
              f"(that needs replicates, as bedstruct run repose makes).")
    s.add_number("angle_deg", res.angle_deg, "deg", "static angle of repose: mean of the fitted flank angles",
                 DOCS + "analysis.md, Angle of repose")
    s.add_number("angle_std_deg", res.angle_std_deg, "deg",
                 "fit uncertainty (1 sigma, Theil-Sen) of this pile's mean angle; not a scatter between piles")
    s.add_number("left_deg", res.left_deg, "deg", f"angle of the flank at lower {opt.axis}")
    s.add_number("right_deg", res.right_deg, "deg", f"angle of the flank at higher {opt.axis}")
    s.add_number("flank_difference_deg", res.flank_difference_deg, "deg",
                 "difference between the two flank angles, |left - right| (none with one flank)")
    s.add_number("base", pa.base, unit, "plate level the pile stands on" +
                 (" (found from the pile)" if pa.base_found else " (given)"))
    from ..plot import plot_repose
    factor, shown = ctx.plot_unit([np.nanmax(np.abs(res.profile_x))])
    fig = _figure_of(plot_repose(res, unit=shown, scale=factor))
    s.add_figure(fig, "Free-surface profile of the pile")


def _heat(ctx: _Context, s: Section) -> None:
    from ..analysis import heat_regions, heat_regions_table
    from ..plot import plot_temperature_map
    f, opt = ctx.frame, ctx.options
    if f.units.style not in ("si", "cgs", "micro", "nano") and opt.heat_length_unit is None:
        skip("the dump's unit system is unknown: give --units or --heat-length-unit (metres per length unit)")
    res = heat_regions(f, ctx.contacts, n_regions=opt.regions, axis=opt.axis_index,
                       names=opt.region_names, length_unit=opt.heat_length_unit,
                       n_sources=1, stop_fraction=opt.heat_stop_fraction)
    table = heat_regions_table(res)
    columns = list(table)
    units = [_HEAT_UNITS.get(c, "1") for c in columns]
    s.tables.append(Table(columns, [[v.item() if isinstance(v, np.generic) else v for v in row]
                                    for row in zip(*table.values())], units=units,
                          caption=(f"500 um hemispherical pulse at {res.source_temperature - 273.15:.0f} C on the "
                                   f"bed surface at each region's centre; all regions reported at "
                                   f"t = {res.time * 1e3:.3g} ms, when the hottest particle has cooled to "
                                   f"{res.stop_fraction:.0%} of the pulse excess (median over regions); "
                                   f"HAZ outline at {res.threshold_fraction:.0%} between the initial and the "
                                   f"hottest temperature")))
    for k, name in enumerate(res.names):
        s.add_number(f"peak_temperature_{name}", float(res.peak_temperature[k][0]) - 273.15, "degC",
                     f"hottest particle at the common end time, {name} region", DOCS + "heat.md")
        s.add_number(f"roundness_{name}", res.haz[k][0].roundness, "1",
                     f"heat-affected-zone roundness 4A/(pi L_major^2), {name} region", DOCS + "heat.md")
        s.add_figure(_figure_of(plot_temperature_map(res.maps[k][0], haz=res.haz[k][0])),
                     f"Top-view temperature at the end, {name} region")
    s.add_number("end_time", res.time, "s", "common end time of the conduction runs")


# units of heat_regions_table's columns (bedstruct.analysis.heat_study), SI
_HEAT_UNITS = {"region": "", "peak_temperature_C": "degC", "peak_temperature_std": "K", "crossing_time": "s",
               "threshold_C": "degC", "orientation_deg": "deg", "major_axis": "m", "minor_axis": "m",
               "k_max": "W/(m K)", "k_min": "W/(m K)", "k_orientation_deg": "deg",
               "fabric_orientation_deg": "deg"}


#: A supplied contact is apart when the gap between the two surfaces exceeds this fraction of
#: the sum of their radii (1 %: well beyond the overlaps and rounding of a dump)...
CONTACT_GAP_TOLERANCE = 0.01
#: ...and the contact file is not trusted when more than this share of its contacts is apart
#: (5 %: a few near contacts kept by a simulator's skin distance pass, a neighbour list does not).
CONTACT_APART_SHARE = 0.05
#: Radii whose spread (largest minus smallest, over the largest) is below this are one size.
MONODISPERSE_SPREAD = 1e-9
#: Sections built on the contacts: not reported when the supplied contacts do not touch.
_CONTACT_SECTIONS = ("coordination", "fabric", "harmonics", "heat")


def contact_gaps(frame: Frame, contacts: Contacts) -> dict:
    """Measure how far apart the surfaces of supplied contacts are.

    Each pair's centre distance is taken by the minimum image of the frame's
    box (periodic axes respected) and compared with the sum of the two radii.

    Parameters
    ----------
    frame : Frame
        The frame the contacts belong to (``contacts.i`` and ``contacts.j``
        are its rows).
    contacts : Contacts
        The contacts to check, e.g. read from a ``dump local`` file.

    Returns
    -------
    dict
        ``n_contacts``; ``n_apart``, the pairs whose gap exceeds
        :data:`CONTACT_GAP_TOLERANCE` of their radii sum; ``share_apart``
        (None without contacts); ``median_distance_over_radii_sum``; and
        ``apart``, True when the share exceeds :data:`CONTACT_APART_SHARE`.
    """
    i, j = np.asarray(contacts.i), np.asarray(contacts.j)
    n = int(i.size)
    if n == 0:
        return {"n_contacts": 0, "n_apart": 0, "share_apart": None,
                "median_distance_over_radii_sum": None, "apart": False}
    d = frame.box.minimum_image(frame.positions[j] - frame.positions[i])
    dist = np.sqrt(np.einsum("ij,ij->i", d, d))
    rsum = frame.radii[i] + frame.radii[j]
    ratio = dist / rsum
    n_apart = int(np.count_nonzero(ratio - 1.0 > CONTACT_GAP_TOLERANCE))
    share = n_apart / n
    return {"n_contacts": n, "n_apart": n_apart, "share_apart": share,
            "median_distance_over_radii_sum": float(np.median(ratio)),
            "apart": share > CONTACT_APART_SHARE}


def _contacts_apart_text(check: dict, source: str) -> str:
    """The warning about a contact file whose pairs do not touch."""
    return (f"{source}: {check['n_apart']} of {check['n_contacts']} contacts "
            f"({check['share_apart']:.0%}) join particles whose surfaces are apart (gap above "
            f"{CONTACT_GAP_TOLERANCE:.0%} of the radii sum; median centre distance "
            f"{check['median_distance_over_radii_sum']:.3g} times the radii sum): its pairs do not touch. "
            f"Coordination, fabric, harmonics and heat from it are not "
            f"reported; the input is judged from contacts detected geometrically")


def _monodisperse(frame: Frame) -> str | None:
    """Why size statistics mean nothing for this frame (one radius for all), or None."""
    r = np.asarray(frame.radii, dtype=float)
    if r.size == 0 or not np.all(np.isfinite(r)):
        return None
    top = float(np.max(np.abs(r)))
    if top == 0 or (float(np.max(r)) - float(np.min(r))) / top >= MONODISPERSE_SPREAD:
        return None
    from ._render import _display_unit, _number
    unit = frame.units.length_unit
    if unit == "unknown":
        size = f"{_number(top)} in the length unit of the dump"
    else:
        factor, shown = _display_unit([top], unit)
        size = f"{_number(top * factor)} {shown}"
    return (f"all {r.size} particles have the same radius, {size} (monodisperse): size percentiles, "
            f"their change along the bed and the segregation index describe a spread of sizes, and "
            f"there is none")


def units_note(frame: Frame) -> str | None:
    """What an unknown unit system leaves unjudged, naming the file; None when it is known."""
    if frame.units.style is not None:
        return None
    where = frame.provenance.source or "the input"
    what = ("velocities are not judged (whether the bed moves)"
            if getattr(frame, "velocities", None) is not None else
            "lengths are shown in the file's own unit and heat is not computed")
    return f"units not stated in {where}: {what}; pass --units STYLE"


def file_sequence_warnings(paths: Sequence[str], *, radius=None, units=None) -> list[str]:
    """Warnings when several input files do not follow one another as one run.

    Each file's frames are indexed (headers only for dumps) and compared with
    those of the file before it: the first timestep of a file should exceed the
    last of the one before, and the particle count and box should not change.

    Parameters
    ----------
    paths : sequence of str
        The input files (or globs) in the order given.
    radius, units : optional
        As given for reading them (:func:`bedstruct.io.read`).

    Returns
    -------
    list of str
        One warning per pair of files that do not follow; empty for one file.
    """
    if len(paths) < 2:
        return []
    from ..io import read
    spans = []
    for p in paths:
        try:
            t = read(p, radius=radius, units=units)
            spans.append((str(p), _file_end(t, 0), _file_end(t, -1)))
        except Exception:   # already read for the report: a failure here only skips the check
            log.debug("could not index %s for the sequence check", p, exc_info=True)
            return []
    out = []
    for (pa, _, last), (pb, first, _) in zip(spans, spans[1:]):
        what = []
        if first[0] <= last[0]:
            what.append(f"its first timestep ({first[0]}) does not follow the last of {pa} ({last[0]})")
        if first[1] != last[1]:
            what.append(f"its particle count changes from {last[1]} to {first[1]}")
        if not (np.allclose(first[2], last[2], rtol=1e-9, atol=0.0)
                and np.allclose(first[3], last[3], rtol=1e-9, atol=0.0)):
            what.append(f"its box changes from {_bounds(last)} to {_bounds(first)}")
        if what:
            out.append(f"{pb} does not continue {pa}: " + "; ".join(what)
                       + " (the files may be of unrelated runs)")
    return out


def _file_end(t, k: int) -> tuple:
    """(timestep, particle count, box lo, box hi) of frame ``k`` of a trajectory."""
    if hasattr(t, "header"):   # a dump read lazily: the header holds it all
        h = t.header(k)
        b = np.asarray(h.bounds, dtype=float)
        return int(h.timestep), int(h.n), b[:, 0], b[:, 1]
    f = t[k]
    return int(f.timestep), int(f.n_particles), np.asarray(f.box.lo, float), np.asarray(f.box.hi, float)


def _bounds(end: tuple) -> str:
    lo, hi = end[2], end[3]
    return "[" + ", ".join(f"{a:.4g} to {b:.4g}" for a, b in zip(lo, hi)) + "]"


def _regions_text(profile, opt: ReportOptions, ctx: _Context) -> str:
    """'3 equal regions along x: start 0-1.2, ... (mm)' from a packing profile's windows."""
    lo, hi = np.asarray(profile.lower)[:, opt.axis_index], np.asarray(profile.upper)[:, opt.axis_index]
    from ._render import _display_unit, _number
    factor, unit = _display_unit(list(hi), ctx.length_unit)
    # bounds within rounding of zero (a sum of region widths) are shown as 0
    tiny = 1e-9 * float(np.max(np.abs(np.concatenate([lo, hi])))) if len(lo) else 0.0
    lo, hi = np.where(np.abs(lo) <= tiny, 0.0, lo), np.where(np.abs(hi) <= tiny, 0.0, hi)
    spans = ", ".join(f"{n} {_number(a * factor)} to {_number(b * factor)}"
                      for n, a, b in zip(opt.region_names, lo, hi))
    return f"{len(lo)} equal regions along {opt.axis}: {spans}{f' {unit}' if unit else ''}"


SECTIONS = [
    ("summary", "Data summary", _summary),
    ("packing", "Packing fraction", _packing),
    ("coordination", "Coordination number and German's law", _coordination),
    ("rdf", "Radial distribution function", _rdf),
    ("voronoi", "Local packing (radical Voronoi)", _voronoi),
    ("psd", "Particle size distribution and segregation", _psd),
    ("surface", "Surface height and roughness", _surface),
    ("fabric", "Fabric tensors and rose diagrams", _fabric),
    ("harmonics", "Spherical-harmonic spectrum", _harmonics),
    ("repose", "Angle of repose", _repose),
    ("heat", "Heat conduction and heat-affected zone", _heat),
]


def build_report(frames: Sequence[Frame] | Frame, *, contacts: Contacts | None = None,
                 options: ReportOptions | None = None, frame_indices: Sequence[int] | None = None,
                 inputs: dict | None = None, progress: bool = False) -> Report:
    """Run every analysis section on the frames and collect a :class:`Report`.

    Parameters
    ----------
    frames : Frame or sequence of Frame
        The frames selected for the report. Every detailed section describes
        the last; the others add only a row (timestep, particle count) to the
        table of frames of the data summary.
    contacts : Contacts, optional
        Contacts of the last frame (from a ``dump local`` file); geometric
        contacts are detected when omitted. Their gaps are measured
        (:func:`contact_gaps`): when more than :data:`CONTACT_APART_SHARE` of
        them join surfaces apart by more than :data:`CONTACT_GAP_TOLERANCE` of
        the radii sum, the report warns, leaves out the sections built on
        contacts (saying why) and judges the input from geometric contacts.
    options : ReportOptions, optional
        Regions, axis, heat and other settings.
    frame_indices : sequence of int, optional
        Index of each frame among those read (default 0, 1, ...).
    inputs : dict, optional
        A description of the inputs (see :func:`bedstruct.report.load_report_inputs`). With
        more than one entry under ``paths``, the files are checked to follow
        one another (:func:`file_sequence_warnings`); warnings are listed under
        ``warnings`` and at the top of the data summary, and ``units`` says the
        unit system or what its absence leaves unjudged (:func:`units_note`).
    progress : bool
        Show a progress bar over the sections (stderr).

    Returns
    -------
    Report
    """
    options = options or ReportOptions()
    frames = [frames] if isinstance(frames, Frame) else list(frames)
    if not frames:
        raise ValueError("no frames to report on")
    idx = list(frame_indices) if frame_indices is not None else list(range(len(frames)))
    if frames[-1].n_particles == 0:
        where = frames[-1].provenance.source or "the frame given"
        raise ValueError(f"{where}: the frame analysed (timestep {frames[-1].timestep}) has no "
                         f"particles: nothing to report")
    ctx = _Context(frames, contacts, options, idx)
    inputs = dict(inputs or {})
    warns = list(inputs.get("warnings") or [])
    if len(inputs.get("paths") or ()) > 1:
        warns += file_sequence_warnings(inputs["paths"], radius=inputs.get("radius_given"),
                                        units=inputs.get("units_given"))
    refused = {}
    if ctx.contact_check and ctx.contact_check["apart"]:
        source = contacts.source if contacts.source != "geometric" else "the contacts given"
        warns.append(_contacts_apart_text(ctx.contact_check, source))
        for key in _CONTACT_SECTIONS:
            refused[key] = (f"the contacts given ({source}) are mostly apart: "
                            f"{ctx.contact_check['n_apart']} of {ctx.contact_check['n_contacts']} "
                            f"join surfaces more than {CONTACT_GAP_TOLERANCE:.0%} of their radii sum apart")
    one_size = _monodisperse(ctx.frame)
    if one_size:
        refused["psd"] = one_size
    if ctx.contact_check is not None:
        inputs["contact_gaps"] = ctx.contact_check
    if len(frames) > 1:
        inputs["frame_described"] = _described_frame(ctx)
    inputs["units"] = units_note(ctx.frame) or ctx.frame.units.style
    if warns:
        inputs["warnings"] = warns
    report = Report(title="bedstruct report", inputs=inputs,
                    settings=dataclasses.asdict(options),   # every option, so a rerun can match
                    version=__version__)
    report.state = _state(ctx)
    _pictures(ctx, report)
    todo = [s for s in SECTIONS if s[0] != "heat" or options.heat]
    if progress:
        from tqdm.auto import tqdm
    else:   # tqdm's notebook front end warns where ipywidgets is missing: only for a shown bar
        from tqdm import tqdm
    for key, title, func in tqdm(todo, desc="report", unit="section", disable=not progress, leave=False):
        if key in refused:   # the data do not support the section, whatever the input is
            report.sections.append(not_meaningful_section(key, title, f"Not meaningful: {refused[key]}."))
            continue
        why = report.state["not_meaningful"].get(key)
        if why is not None:
            subject = f" for {ctx.state.label}" if ctx.state is not None else ""
            report.sections.append(not_meaningful_section(key, title, f"Not meaningful{subject}: {why}."))
            continue
        report.sections.append(run_section(key, title, lambda sec, f=func: f(ctx, sec)))
        if key == "summary" and warns:
            sec = report.sections[-1]
            sec.text = " ".join(f"Warning: {w}." for w in warns) + (" " + sec.text if sec.text else "")
        if report.sections[-1].figures:   # free its figures (reference cycles) now: left to the
            gc.collect()                  # collector, 3-D roses slow the heat runs after them 30-fold
    return report


def _pictures(ctx: _Context, report: Report) -> None:
    """The side view (always) and the 3-D view (when PyVista renders here) of the bed."""
    from ._picture import bed_pictures
    report.pictures, report.picture_note = bed_pictures(ctx.frame, axis=ctx.options.axis_index,
                                                        view_3d=ctx.options.view_3d)


def _state(ctx: _Context) -> dict:
    """What the input is (:func:`bedstruct.analysis.bed_state`), for the top of the report."""
    from ..analysis import bed_state
    opt = ctx.options
    try:
        st = bed_state(ctx.frame, ctx.contacts, min_contacts=opt.min_contacts, axis=opt.axis_index)
    except Exception as exc:   # what needs the input's state is not reported without it
        log.debug("bed_state failed", exc_info=True)
        ctx.state = None
        why = (f"the input could not be judged ({type(exc).__name__}: {exc}), and this analysis "
               f"means something only for some kinds of input")
        return {"kind": "unknown", "reason": f"could not be judged ({type(exc).__name__}: {exc})",
                "evidence": {}, "not_meaningful": {k: why for k in _STATE_DEPENDENT}}
    ctx.state = st
    speed_unit = f"{ctx.length_unit}/s" if ctx.frame.units.style in ("si", "cgs") else "length/time"
    evidence = {
        "packing_fraction": Quantity(st.packing_fraction, "1", "particle volume over the volume of the "
                                     "box enclosing all particles" if st.dimension == 3 else
                                     "2-D run: disc area over the area of the rectangle enclosing all "
                                     "discs in their plane"),
        "mean_coordination": Quantity(st.mean_coordination, "1", "mean contacts per particle"),
        "network_fraction": Quantity(st.network_fraction, "1", f"fraction of particles held by the contact "
                                     f"network (not rattlers, {st.min_contacts} or more contacts)"),
        "median_speed": Quantity(st.median_speed, speed_unit, "median particle speed (none without velocities)"),
        "rms_speed": Quantity(st.rms_speed, speed_unit, "mass-weighted rms speed sqrt(2 KE / M) "
                              "(none without velocities)"),
        "moving_fraction": Quantity(st.moving_fraction, "1", "fraction of particles faster than 0.1 sqrt(g d50) "
                                    "(none without velocities or a known unit system)"),
        "peak": Quantity(st.peak, "1", "top surface peak above its mean over the height (pile test)"),
    }
    return {"kind": st.kind, "dimension": st.dimension, "reason": st.reason, "evidence": evidence,
            "not_meaningful": dict(st.not_meaningful), "doc": DOCS + "analysis.md, What the input is"}


#: Sections whose meaning depends on what the input is (see bedstruct.analysis.bed_state).
_STATE_DEPENDENT = ("coordination", "german", "surface", "fabric", "harmonics", "repose", "heat")
