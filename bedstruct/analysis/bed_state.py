"""What a frame shows: a settled bed, a pile, a moving bed or a dilute flow.

Bed metrics (German's law, surface roughness, angle of repose, heat
conduction through contacts) describe particles at rest in a contact
network. On a dilute flow or a bed still settling they return numbers that
mean nothing. :func:`bed_state` tells the cases apart from the contact
network, the packing and, when the dump has velocities, the kinetic energy,
and says which analyses are meaningful for what it found.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.contacts import Contacts
from ..core.frame import UNIT_STYLES, _as_frame
from .dimension import AXIS_NAMES, flat_axis

__all__ = ["BedState", "bed_state", "BED_KINDS", "MIN_PARTICLES"]

#: The kinds of input :func:`bed_state` distinguishes.
BED_KINDS = ("settled bed", "pile", "moving bed", "dilute flow", "empty")

_G_SI = 9.81                      # m/s^2
_MIN_NETWORK_FRACTION = 0.5       # a bed: most particles held by the contact network
_MIN_MOVING_FRACTION = 0.5        # moving: most particles faster than the threshold below
_MOVING_FROUDE = 0.1              # speed / sqrt(g d50) above which a particle is moving
_MIN_SETTLING_COORDINATION = 1.0  # not held, but touching enough to be a bed still settling
_PILE_PEAK = 0.17                 # peak of the top surface above its mean, over the height
_PILE_BINS = 8
#: Fewer particles than this make no packing: fractions, g(r), cells, fits and surfaces of them
#: describe the particles' own shape, not a bed.
MIN_PARTICLES = 10

# analyses of spheres in space, each with what it needs that a 2-D run (discs in a plane) lacks
_THREE_D = {
    "german": "German's law CN = 2 + 11 phi^2 relates the coordination and packing of spheres in 3-D",
    "rdf": "g(r) is counted in spherical shells; the particles of a 2-D run lie in one plane",
    "voronoi": "the radical Voronoi cells are 3-D; the particles of a 2-D run lie in one plane",
    "surface": "the surface height map is taken along z, across which a 2-D run has no extent",
    "fabric": "the fabric tensors and roses are those of 3-D contact normals; every normal of a 2-D "
              "run lies in its plane",
    "harmonics": "the spherical-harmonic spectrum is that of 3-D contact normals; every normal of a 2-D "
                 "run lies in its plane",
    "repose": "the angle of repose is measured on heights along z, across which a 2-D run has no extent",
    "heat": "contact conduction is modelled between spheres in 3-D",
}
# analyses that need more than a handful of particles (MIN_PARTICLES)
_FEW = ("packing", "rdf", "voronoi", "german", "surface", "fabric", "harmonics", "repose", "heat")
_ALL = ("packing", "coordination", "german", "rdf", "voronoi", "psd", "surface", "fabric", "harmonics",
        "repose", "heat")


@dataclass(frozen=True)
class BedState:
    """What a frame shows, the evidence, and which analyses it supports.

    Attributes
    ----------
    kind : str
        One of :data:`BED_KINDS`: ``"settled bed"``, ``"pile"``,
        ``"moving bed"``, ``"dilute flow"`` or ``"empty"`` (a frame with no
        particles).
    reason : str
        One sentence giving the evidence for ``kind``.
    n_particles : int
        Number of particles.
    packing_fraction : float
        Particle volume over the volume of the box enclosing all particles
        (dimensionless); for a 2-D run, the disc area over the area of the
        rectangle enclosing all discs. NaN where the enclosing box is not
        defined (a box tilted along a bounded axis).
    mean_coordination : float
        Mean number of contacts per particle (dimensionless).
    network_fraction : float
        Fraction of particles held by the contact network: those left after
        iterative removal of particles with fewer than ``min_contacts``
        contacts (dimensionless).
    min_contacts : int
        The rattler threshold used for ``network_fraction``.
    median_speed, rms_speed : float
        Median and mass-weighted root-mean-square particle speed
        (length/time; NaN without velocities). ``rms_speed`` is
        ``sqrt(2 KE / M)``, the speed of the kinetic energy.
    moving_fraction : float
        Fraction of particles faster than ``0.1 sqrt(g d50)``
        (dimensionless; NaN without velocities or a known unit system).
    peak : float
        How far the top surface of the largest cluster (the highest particle
        top in each of 8 bins along ``axis``) rises above its mean, over the
        cluster's height (dimensionless: 0 for a flat layer, 1/2 for a
        triangular heap; NaN unless the frame is held and at rest).
    velocities_used : bool
        Whether the kinetic energy entered the decision.
    not_meaningful : dict of str to str
        Analyses (``"packing"``, ``"coordination"``, ``"german"``, ``"rdf"``,
        ``"voronoi"``, ``"psd"``, ``"surface"``, ``"fabric"``,
        ``"harmonics"``, ``"repose"``, ``"heat"``) that are not meaningful for
        this input, each with the reason.
    dimension : int
        3, or 2 for a 2-D run (discs in a plane; see
        :func:`bedstruct.analysis.flat_axis`).
    flat_axis : int or None
        The axis a 2-D run lies flat along (None in 3-D).
    """

    kind: str
    reason: str
    n_particles: int
    packing_fraction: float
    mean_coordination: float
    network_fraction: float
    min_contacts: int
    median_speed: float
    rms_speed: float
    moving_fraction: float
    peak: float
    velocities_used: bool
    not_meaningful: dict = field(default_factory=dict)
    dimension: int = 3
    flat_axis: int | None = None

    @property
    def is_bed(self) -> bool:
        """True for a settled bed or a pile: particles at rest in a contact network."""
        return self.kind in ("settled bed", "pile")

    @property
    def label(self) -> str:
        """The kind with its article, for a sentence: ``"a settled bed"``, ``"a 2-D dilute
        flow"``, ``"an empty frame"``."""
        if self.kind == "empty":
            return "an empty frame"
        return f"a {'2-D ' if self.dimension == 2 else ''}{self.kind}"

    def meaningful(self, analysis: str) -> bool:
        """Whether ``analysis`` (e.g. ``"german"``) is meaningful for this input."""
        return analysis not in self.not_meaningful


def _gravity(frame) -> float | None:
    """g in the frame's length/time^2, or None when its unit system is unknown."""
    u = UNIT_STYLES.get(frame.units.style or "")
    if u is None:
        return None
    return _G_SI * u["time"] ** 2 / u["length"]


def _peak(frame, network: np.ndarray, axis: int, vertical: int = 2) -> float:
    """How far the top surface along ``axis`` peaks above its mean, over the height along ``vertical``."""
    if network.sum() < 2 * _PILE_BINS:
        return float("nan")
    pos, r = frame.positions[network], frame.radii[network]
    x = pos[:, axis]
    top, bottom = pos[:, vertical] + r, float(np.min(pos[:, vertical] - r))
    edges = np.linspace(x.min(), x.max(), _PILE_BINS + 1)
    k = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, _PILE_BINS - 1)
    h = np.full(_PILE_BINS, np.nan)
    for b in range(_PILE_BINS):
        if np.any(k == b):
            h[b] = np.max(top[k == b])
    height = np.nanmax(h) - bottom
    return float((np.nanmax(h) - np.nanmean(h)) / height) if height > 0 else float("nan")


def bed_state(frame, contacts: Contacts | None = None, *, min_contacts: int = 2,
              axis: int = 0) -> BedState:
    """Tell a settled bed, a pile, a moving bed and a dilute flow apart.

    Parameters
    ----------
    frame : Frame
        Positions (length), radii (length) and, when the dump has them,
        velocities (length/time).
    contacts : Contacts, optional
        Contacts of the frame; detected geometrically when omitted.
    min_contacts : int, optional
        Rattler threshold: particles with fewer contacts are removed
        iteratively and do not count as held by the network (default 2).
    axis : int, optional
        Direction along the bed (0, 1 or 2; default 0), for the pile test.
        Along the vertical (z in 3-D) the pile test runs along each
        horizontal axis and takes the larger peak.

    Returns
    -------
    BedState

    Raises
    ------
    ValueError
        If ``axis`` is not 0, 1 or 2.

    Notes
    -----
    The decision, in order:

    1. No particles: ``"empty"``.
    2. Moving: with velocities and a known unit system, more than half of
       the particles move faster than :math:`0.1\\sqrt{g\\,d_{50}}` (a tenth
       of the speed gained by falling half a diameter).
    3. Held: more than half of the particles belong to the contact network
       (``network_fraction > 0.5``).
    4. Held and not moving: a ``"pile"`` when the top surface of the largest
       network cluster, along ``axis``, peaks above its mean by more than
       17 % of the cluster's height (a triangular heap: 50 %; a heap cut by
       the edges of a pedestal: about 25 %; a layer with a sloped end: about
       10 %), else a ``"settled bed"``. Without velocities rest is assumed, and the reason
       says so.
    5. Held and moving: a ``"moving bed"``. Not held and moving with at
       least one contact per particle on average: a ``"moving bed"`` still
       settling. Otherwise: a ``"dilute flow"``.

    A 2-D run (:func:`bedstruct.analysis.flat_axis`: discs in a plane) is
    judged the same way, with its contacts in the plane, its area fraction
    and, for the pile test, the in-plane axis across ``axis`` as the height;
    the analyses of spheres in 3-D (German's law, g(r), Voronoi cells, the
    surface along z, fabric, harmonics, repose, heat) are marked not
    meaningful for it. With fewer than :data:`MIN_PARTICLES` particles the
    packing, g(r), Voronoi cells, German's law, surface, fabric, harmonics,
    repose and heat are marked not meaningful; an empty frame supports
    none.

    German's law, surface roughness, angle of repose and contact heat
    conduction are static-packing relations: they are marked not meaningful
    for moving beds and dilute flows. A dilute flow has no contact network,
    so coordination, fabric and harmonics are not meaningful either; a pile's
    free surface is its shape, so roughness is not meaningful for it.

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Box, Frame
    >>> g = np.stack(np.meshgrid(*[np.arange(k) + 0.5 for k in (12, 4, 3)], indexing="ij"), -1)
    >>> bed = Frame(g.reshape(-1, 3), np.full(144, 0.5), box=Box([0, 0, 0], [12, 4, 3], boundary="pp pp ff"))
    >>> bed_state(bed).kind
    'settled bed'
    >>> gas = Frame(g.reshape(-1, 3) * 5, np.full(144, 0.5), box=Box([0, 0, 0], [60, 20, 15]))
    >>> s = bed_state(gas)
    >>> s.kind, round(s.network_fraction, 2), s.meaningful("german")
    ('dilute flow', 0.0, False)
    """
    from .coordination import coordination
    from .packing import area_fraction, packing_fraction
    from .surface import largest_cluster

    frame = _as_frame(frame)
    if axis not in (0, 1, 2):
        raise ValueError(f"`axis` must be 0, 1 or 2; got {axis!r}")
    n = frame.n_particles
    nan = float("nan")
    if n == 0:
        return BedState("empty", "the frame has no particles", 0, nan, nan, nan, int(min_contacts),
                        nan, nan, nan, nan, False, {k: "the frame has no particles" for k in _ALL})
    flat = flat_axis(frame)
    res = coordination(frame, contacts, min_contacts=min_contacts)
    network = ~np.asarray(res.rattlers, dtype=bool)
    network_fraction = float(network.mean())
    try:
        phi = float((packing_fraction(frame) if flat is None else area_fraction(frame)).fraction)
    except ValueError:      # no enclosing box (tilted along a bounded axis): evidence only
        phi = nan

    median_speed = rms_speed = moving_fraction = nan
    velocities_used = False
    speed_note = "the dump has no velocities"
    if frame.velocities is not None:
        speed = np.linalg.norm(frame.velocities, axis=1)
        mass = frame.radii ** 3
        median_speed = float(np.median(speed))
        rms_speed = float(np.sqrt(np.sum(mass * speed ** 2) / np.sum(mass)))
        g = _gravity(frame)
        if g is None:
            speed_note = ("velocities not judged: LJ units have no scale for gravity (g is a "
                          "parameter of the run)" if frame.units.style == "lj" else
                          "velocities not judged: the unit system is unknown (give units)")
        else:
            threshold = _MOVING_FROUDE * np.sqrt(g * float(np.median(2 * frame.radii)))
            moving_fraction = float(np.mean(speed > threshold))
            velocities_used = True
            speed_note = (f"{moving_fraction:.0%} of particles faster than 0.1 sqrt(g d50) "
                          f"= {threshold:.3g} {frame.units.velocity_unit}")
    moving = velocities_used and moving_fraction > _MIN_MOVING_FRACTION
    held = network_fraction > _MIN_NETWORK_FRACTION
    phi_name = "packing fraction" if flat is None else "area fraction"
    held_note = (f"{network_fraction:.0%} of particles held by the contact network "
                 f"(mean {res.mean:.2f} contacts per particle, {phi_name} "
                 f"{'not defined for this box' if np.isnan(phi) else f'{phi:.3f}'})")
    if flat is not None:
        plane = "-".join(AXIS_NAMES[a] for a in range(3) if a != flat)
        held_note = (f"a 2-D run (every centre at one {AXIS_NAMES[flat]}, periodic or thinner than a "
                     f"diameter along it): discs in the {plane} plane; {held_note}")
    if n < MIN_PARTICLES:
        held_note = f"only {n} particle{'s' if n != 1 else ''}; {held_note}"
    # height: z, or for a 2-D run flat along z the in-plane axis across the bed
    vertical = 2 if flat != 2 else (3 - axis - flat if axis != flat else 1)

    # the pile test runs along the bed: along a vertical ``axis`` (segregation with height, say)
    # the bins would be height slices, each with its own top, so it runs along each horizontal
    # axis instead and takes the larger peak
    horizontal = [a for a in range(3) if a not in (vertical, flat)]
    along = [axis] if axis in horizontal else horizontal
    peak = nan
    if held and not moving:
        cluster = largest_cluster(frame) & network
        peaks = [_peak(frame, cluster, a, vertical) for a in along]
        peak = max((p for p in peaks if np.isfinite(p)), default=nan)
        kind = "pile" if peak > _PILE_PEAK else "settled bed"
        shape = (f"its top surface peaks {peak:.0%} of its height above its mean along the bed"
                 if np.isfinite(peak) else "too few particles to judge its shape")
        rest = "" if velocities_used else " (rest assumed)"
        reason = f"{held_note}; {speed_note}{rest}; {shape}"
    elif held or (moving and res.mean >= _MIN_SETTLING_COORDINATION):
        kind = "moving bed"
        reason = f"{held_note}; {speed_note}"
    else:
        kind = "dilute flow"
        reason = f"{held_note}; {speed_note}"

    static = {"moving bed": "the particles are moving (a bed still settling or flowing); "
                            "the relation holds for packings at rest",
              "dilute flow": "the particles are not held by a contact network"}
    out: dict[str, str] = {}
    if n < MIN_PARTICLES:
        for key in _FEW:
            out[key] = (f"only {n} particle{'s' if n != 1 else ''} (fewer than {MIN_PARTICLES}): "
                        f"too few to make a packing")
    if flat is not None:
        for key, why in _THREE_D.items():
            out.setdefault(key, f"a 2-D run (discs in one plane): {why}")
    if kind in static:
        why = static[kind]
        out.setdefault("german", f"German's law relates coordination to packing at rest: {why}")
        out.setdefault("coordination", f"contacts of a {kind} are transient: {why}")
        out.setdefault("surface", f"a {kind} has no settled top surface")
        out.setdefault("repose", f"an angle of repose needs a pile at rest: {why}")
        out.setdefault("heat", f"contact conduction needs a settled contact network: {why}")
    if kind == "dilute flow":
        out.setdefault("fabric", "contact fabric needs a contact network: the particles are not held by one")
        out.setdefault("harmonics", out["fabric"])
    if kind == "pile":
        out.setdefault("surface", "the free surface of a pile is its shape, not a roughness")
    return BedState(kind, reason, n, phi, float(res.mean), network_fraction, int(min_contacts),
                    median_speed, rms_speed, moving_fraction, peak, velocities_used, out,
                    dimension=2 if flat is not None else 3, flat_axis=flat)
