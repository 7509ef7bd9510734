"""What every external engine's dialect provides: :class:`Dialect`.

A dialect spells bedstruct's scenarios (a settled bed, a head-on impact, the
angle-of-repose box, multi-layer spreading) in one engine's commands. The scenario
writers (:func:`~bedstruct.engines.bed_deck`, :func:`~bedstruct.engines.repose_deck`,
:func:`~bedstruct.engines.spread_layers_deck` ...) hold the sequence of a scenario,
the same for every engine, and ask the dialect for each engine-specific piece: the
set-up lines, the contact model, walls, moving meshes or regions, contact dumps.

A piece that an engine cannot realise is refused by name (:meth:`Dialect.refuse`,
a :class:`~bedstruct.errors.ConfigError`), never replaced by another model.

The diagnosis' effects are ordinary options of a workflow configuration's sections
(:data:`EFFECT_KEYS`: liquid bridges and contact ageing in ``contact``, a fines tail in
``psd``, the tool's start-up in ``spread``): each dialect states, per catalogue effect,
how it realises the effect or why it refuses it (:attr:`Dialect.realisations`,
:class:`Realisation`); :meth:`Dialect.check_effects` refuses by that table and
:meth:`Dialect.with_effects` returns the dialect that writes them.
:data:`EMBEDDED_REALISATIONS` states the embedded engine's, for the same table.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import ClassVar, Mapping

from ..errors import ConfigError
from ._datafile import data_file_radii, read_data_header
from ._launch import run_deck
from ._logs import parse_log
from ._params import check_gravity, one_type_model

__all__ = ["Dialect", "DUMP_COLUMNS", "path_word", "Realisation", "EFFECT_KEYS",
           "EMBEDDED_REALISATIONS", "effects_on", "option"]

#: Per-particle dump columns written by every deck.
DUMP_COLUMNS = "id type x y z vx vy vz fx fy fz omegax omegay omegaz radius"

#: The configuration options (``section.option``) that carry each catalogue effect. An
#: effect with a switch is on when one of its options is (true, or non-zero); rolling and
#: wall friction are coefficients of every contact model, written by every deck.
EFFECT_KEYS = {"capillary_bridges": ("contact.capillary",),
               "contact_ageing": ("contact.ageing",),
               "non_sphericity": ("contact.rolling_friction", "contact.rolling_model",
                                  "contact.rolling_stiffness_factor"),
               "missing_fines": ("psd.fines_mass_fraction",),
               "wall_friction": ("contact.wall_friction",),
               "blade_startup": ("spread.ramp_time", "spread.vibration_amplitude")}
#: Effects that are coefficients of every contact model: never switched on or off.
_COEFFICIENTS = ("non_sphericity", "wall_friction")
#: Effects of the spreading tool: a deck without a tool (repose, bed) has nothing to realise.
_SPREADING_ONLY = ("blade_startup",)


def option(cfg, dotted: str, default=None):
    """The value of option ``section.option`` in the configuration ``cfg`` (``default``
    when it has no such section or option).

    Examples
    --------
    >>> option({"contact": {"capillary": True}}, "contact.capillary")
    True
    """
    section, _, key = dotted.partition(".")
    return ((cfg or {}).get(section) or {}).get(key, default)


@dataclasses.dataclass(frozen=True)
class Realisation:
    """How one engine realises one catalogue effect, or why it cannot.

    Attributes
    ----------
    how : str
        The engine's model of the effect, in words (empty when refused).
    refused : str
        Why the engine cannot realise it, and the alternative (empty when realised).

    Examples
    --------
    >>> Realisation(refused="no such model; run it with --engine embedded").realised
    False
    """

    how: str = ""
    refused: str = ""

    @property
    def realised(self) -> bool:
        """Whether the engine writes the effect."""
        return not self.refused


#: The embedded engine's realisation of every catalogue effect (each a kernel option).
EMBEDDED_REALISATIONS: Mapping[str, Realisation] = {
    "capillary_bridges": Realisation(
        "Willett closed-form liquid bridges between particles (asperity bridges: effective "
        "surface tension and film thickness from the catalogue), added to SJKR cohesion; "
        "bridge volume 2 pi R*^2 t, rupture (1 + theta/2) V^(1/3)"),
    "contact_ageing": Realisation(
        "a bond at resting contacts growing as ln(1 + t_w / tau), broken by tangential slip"),
    "non_sphericity": Realisation(
        "EPSD rolling resistance (Ai et al. 2011) with mu_r + mu_r,shape, stiffness "
        "f k_n mu_r^2 R*^2 (f = contact.rolling_stiffness_factor), damping ratio 0.3"),
    "missing_fines": Realisation("fines inserted with the PSD (log-normal tail below psd.d_min)"),
    "wall_friction": Realisation("particle-wall sliding friction contact.wall_friction"),
    "blade_startup": Realisation(
        "tool speed v (1 - exp(-t/tau)) plus a vertical sinusoidal vibration (wall program)"),
}


def effects_on(cfg, *, spreading: bool = False) -> list[str]:
    """The catalogue effects with a switch that the configuration ``cfg`` switches on.

    ``cfg`` holds the sections of options (a workflow configuration); ``spreading``:
    include the tool's effects (``blade_startup``); other runs have no tool.

    Examples
    --------
    >>> effects_on({"contact": {"capillary": True}, "psd": {"fines_mass_fraction": 0.05},
    ...             "spread": {"ramp_time": 0.1}})
    ['capillary_bridges', 'missing_fines']
    """
    out = []
    for name, keys in EFFECT_KEYS.items():
        if name in _COEFFICIENTS or (name in _SPREADING_ONLY and not spreading):
            continue
        vals = [option(cfg, k, False) for k in keys]
        if any(bool(v) if isinstance(v, bool) else float(v) != 0.0 for v in vals):
            out.append(name)
    return out


#: Options of how one engine maps the seed's contact model; meaningless (ignored) elsewhere.
_MAPPING_OPTIONS = ("cohesion_model", "reference_radius", "reference_overlap")


def _ranks(np) -> int:
    """``np`` as a number of MPI ranks (an int >= 1)."""
    if isinstance(np, bool) or int(np) != np or int(np) < 1:
        raise ValueError(f"np must be a whole number of MPI ranks >= 1, not {np!r}")
    return int(np)


def path_word(path) -> str:
    """``path`` made absolute, as one word of a deck (engines cannot read paths with spaces)."""
    s = str(Path(path).resolve())
    if any(c.isspace() for c in s):
        raise ValueError(f"LIGGGHTS/LAMMPS cannot read paths with spaces: {s!r}")
    return s


@dataclasses.dataclass(frozen=True)
class Dialect:
    """One external engine's spelling of bedstruct's decks (base of the dialects).

    Subclasses set the class attributes and implement the hooks; the scenario
    writers call them. A hook the engine cannot realise calls :meth:`refuse`.

    Attributes
    ----------
    name : str
        Engine name (``"liggghts"``, ``"lammps"``), the first line of every deck
        (``# bedstruct deck for <name>: ...``) and :attr:`EngineInfo.name`.
    executable_name : str
        The usual name of the engine's binary (``liggghts``, ``lmp``).
    atom_style : str
        ``atom_style`` of sphere decks.
    contact_dump_columns : str
        What the contact dump's columns hold (``dump local``).
    tool_load : (str, str)
        The thermo source of the tool's load (three components) and the sign
        that turns it into the load of the particles on the tool.
    impact_thermo_modify : str
        The ``thermo_modify`` line of impact decks.
    realisations : mapping of str to Realisation
        Per catalogue effect (:data:`EFFECT_KEYS`), how this engine's decks realise it or
        why they cannot.
    """

    name: ClassVar[str] = ""
    executable_name: ClassVar[str] = ""
    atom_style: ClassVar[str] = ""
    comm_vel: ClassVar[str] = ""
    contact_dump_columns: ClassVar[str] = ""
    tool_load: ClassVar[tuple] = ("", "")
    impact_thermo_modify: ClassVar[str] = "thermo_modify norm no"
    realisations: ClassVar[Mapping[str, Realisation]] = {}

    # ------------------------------------------------------------------ generic
    def with_options(self, **options) -> "Dialect":
        """A copy with ``options`` set.

        An option given as None keeps this dialect's value. Options of how another
        engine maps the contact model (LAMMPS' ``cohesion_model``, ``reference_radius``,
        ``reference_overlap``) are ignored; any other option this dialect does not have (an
        effect, e.g. ``liquid_bridges`` on LAMMPS) is refused by name.
        """
        options = {k: v for k, v in options.items() if v is not None}
        own = {f.name for f in dataclasses.fields(self)}
        for key, value in options.items():
            if key not in own and key not in _MAPPING_OPTIONS:
                self.refuse(f"`{key}`", "this engine's decks have no such model; run it on "
                            "an engine that has it, or without it")
        return dataclasses.replace(self, **{k: v for k, v in options.items() if k in own})

    def refuse(self, what: str, hint: str = "") -> None:
        """Raise :class:`~bedstruct.errors.ConfigError`: this engine cannot realise ``what``."""
        raise ConfigError(f"{self.name} cannot realise {what}" + (f": {hint}" if hint else ""))

    def find(self, executable: str | None = None):
        """The :class:`~bedstruct.engines.EngineInfo` of this engine on this machine, or None."""
        raise NotImplementedError

    def run(self, deck_path, *, exe: str | None = None, **kwargs):
        """Run ``deck_path`` with this engine (:func:`~bedstruct.engines.run_deck`)."""
        info = self.find(exe)
        if info is None:
            raise FileNotFoundError(f"{self.name} is not installed (run .ci/install-engines.sh)")
        return run_deck(deck_path, engine=info, **kwargs)

    @staticmethod
    def parse_log(source):
        """The parsed log (:func:`~bedstruct.engines.parse_log`; the same for both engines)."""
        return parse_log(source)

    def check_effects(self, cfg, *, spreading: bool = False) -> None:
        """Refuse the diagnosis' effects that the configuration ``cfg`` switches on and this
        engine cannot realise.

        Each effect switched on (:func:`effects_on`) is looked up in
        :attr:`realisations`; a refused one raises, and so do options of a realised one
        that the engine's model lacks (:meth:`check_effect_options`).

        Raises
        ------
        bedstruct.errors.ConfigError
            Naming the effect, its config options, the engine and the alternative.
        """
        for name in effects_on(cfg, spreading=spreading):
            r = self.realisations.get(name)
            if r is None or not r.realised:
                keys = ", ".join(EFFECT_KEYS[name])
                why = r.refused if r is not None else "no realisation is stated for it"
                raise ConfigError(f"engine {self.name!r} cannot realise the effect {name!r} "
                                  f"({keys}): {why}")
        self.check_effect_options(cfg or {}, spreading=spreading)

    def check_effect_options(self, cfg, *, spreading: bool = False) -> None:
        """Refuse options of a realised effect that this engine's model lacks (none here)."""

    def deck_model(self, model):
        """``model`` (a one-type :class:`~bedstruct.dem.ContactModel`; None: the seed's,
        :func:`~bedstruct.dem.seed_contact_model`) checked for this engine's decks.

        The embedded engine's effect models that ``model`` switches on (``capillary``,
        ``contact_ageing``) are refused as :attr:`realisations` states; options of a
        realised one that this engine lacks are refused by :meth:`check_model_options`.

        Raises
        ------
        bedstruct.errors.ConfigError
            Naming what this engine's decks cannot write (more than one particle type
            among them).
        TypeError
            For a model of another kind.

        Examples
        --------
        >>> from bedstruct.dem import seed_contact_model
        >>> from bedstruct.engines import dialect
        >>> dialect("lammps").deck_model(seed_contact_model(capillary=True,
        ...                              capillary_film_thickness=1e-9))
        Traceback (most recent call last):
        ...
        bedstruct.errors.ConfigError: engine 'lammps' cannot realise the ContactModel's `capillary` (effect 'capillary_bridges'): pair_style granular has no liquid-bridge model; run it with --engine liggghts (easo/capillary/viscous bridges) or --engine embedded (Willett bridges)
        """
        m = one_type_model(model, self.name)
        for key, effect in (("capillary", "capillary_bridges"), ("contact_ageing", "contact_ageing")):
            r = self.realisations.get(effect)
            if getattr(m, key) and (r is None or not r.realised):
                why = r.refused if r is not None else "no realisation is stated for it"
                raise ConfigError(f"engine {self.name!r} cannot realise the ContactModel's "
                                  f"`{key}` (effect {effect!r}): {why}")
        self.check_model_options(m)
        return m

    def check_model_options(self, model) -> None:
        """Refuse what a one-type ContactModel states and this engine's decks cannot write
        (none here)."""

    def with_effects(self, cfg, *, reference_radius: float | None = None,
                     spreading: bool = False) -> "Dialect":
        """The dialect that writes the effects the configuration ``cfg`` switches on.

        Refuses what this engine cannot realise (:meth:`check_effects`). Effects that are
        ordinary contact coefficients (wall friction, rolling friction) or inputs (fines) are
        already in the deck's contact model and particles; a dialect with its own model of an
        effect (LIGGGHTS' liquid bridges) returns a copy with it set.

        Parameters
        ----------
        cfg : mapping
            A workflow configuration (its sections of options).
        reference_radius : float, m, optional
            The particle radius an engine's per-particle quantity is set for (LIGGGHTS'
            liquid content from the film thickness); needed only by such a model.
        spreading : bool
            A spreading deck (the tool's effects apply).
        """
        self.check_effects(cfg, spreading=spreading)
        return self

    def effect_notes(self) -> list[str]:
        """What this dialect's effect models write differently from the embedded engine's."""
        return []

    def cohesion_options(self, model, choice: str):
        """How this engine writes the cohesion of ``model``: ``(model, cohesion_model)``.

        ``choice`` is the config's ``external.cohesion_model`` (``dmt``, ``jkr`` or
        ``none``); engines with SJKR cohesion ignore it (``cohesion_model`` None).
        """
        return model, None

    def approximations(self, *, tool=None) -> list[str]:
        """Notes on what this engine's decks write differently from the embedded run."""
        return self.effect_notes()

    def header(self, title: str) -> str:
        """The first line of a deck, followed by a comment line per :meth:`effect_notes`."""
        return "\n".join([f"# bedstruct deck for {self.name}: {title}",
                          *(f"# effect realised differently: {n}" for n in self.effect_notes())])

    def setup_lines(self, boundary: str, processors: str | None) -> list[str]:
        """Atom style, boundary, communication and units (SI) lines."""
        lines = [f"atom_style {self.atom_style}", "atom_modify map array", f"boundary {boundary}",
                 "newton off", self.comm_vel, "units si"]
        if processors:
            lines.append(f"processors {processors}")
        return lines

    def workflow_head(self, data_file, model, *, title: str, boundary: str, dt: float, skin,
                      gravity: float, np: int = 1, span: tuple[float, float] | None = None):
        """Deck lines up to gravity of the workflow decks (set-up, data file, neighbours,
        contact model, time step, ``gravity`` in m/s^2 along -z); returns
        ``(lines, wall_type)``.

        ``np``: the MPI ranks the deck is written for. On more than one, the processor grid
        is :meth:`processors_grid`'s, :meth:`box_lines` follow ``read_data`` (``span`` =
        ``(x0, x1)``: where along x the powder lies when it is far off the box's middle;
        None: it is not) and :meth:`balance_lines` follow gravity: they share the powder
        among the ranks. One rank's deck has none of them.
        """
        np_ = _ranks(np)
        span = None if span is None else (float(span[0]), float(span[1]))
        head = read_data_header(data_file)
        if head["atom types"] < 2:
            raise ValueError("the data file must declare 2 atom types (walls use type 2); write "
                             "it with write_sphere_data(..., n_types=2)")
        if skin is None:
            r = data_file_radii(data_file)
            skin = 0.2 * float(r.min()) if r.size else 1e-6
        lines = [self.header(title),
                 *self.setup_lines(boundary, self.processors_grid(np_, span=span)),
                 f"read_data {path_word(data_file)}"]
        if np_ > 1:
            lines += self.box_lines(np_, box=(float(head["lo"][0]), float(head["hi"][0])),
                                    span=span)
        lines += [f"neighbor {skin:.10g} bin", "neigh_modify delay 0"]
        model_lines, wt = self.model_lines(model, n_types=head["atom types"], soft=True)
        lines += model_lines
        lines.append(f"timestep {dt:.10g}")
        lines += self.gravity_lines(gravity)
        if np_ > 1:
            lines += self.balance_lines(np_)
        return lines, wt

    def processors_grid(self, np: int, *, span: tuple[float, float] | None = None) -> str:
        """The ``processors`` grid of the workflow decks on ``np`` ranks: slabs along x, the
        long side of the repose box and of the spreading platform (the powder is thin in y
        and lies low in z). ``span``: as :meth:`workflow_head`'s."""
        return "* 1 1"

    def box_lines(self, np: int, *, box: tuple[float, float],
                  span: tuple[float, float] | None) -> list[str]:
        """Lines just after ``read_data`` of a deck on ``np`` > 1 ranks (none here).

        ``box``: the data file's x range; ``span``: the x range of the powder, when it lies
        far off the box's middle (None: it does not)."""
        return []

    def balance_lines(self, np: int) -> list[str]:
        """Load balancing of a deck on ``np`` > 1 ranks, after the contact model (none here)."""
        return []

    @staticmethod
    def gravity_lines(gravity: float) -> list[str]:
        """``fix gravi``: gravity of magnitude ``gravity`` (m/s^2) along -z (none for 0)."""
        g = check_gravity(gravity)
        return [f"fix gravi all gravity {g:.10g} vector 0.0 0.0 -1.0"] if g > 0 else []

    # ------------------------------------------------------------------ hooks
    def model_lines(self, model, *, n_types: int,
                    soft: bool = False) -> tuple[list[str], int]:
        """Contact model lines of ``model`` (checked by :meth:`deck_model`) for ``n_types``
        atom types and the walls' atom type.

        ``soft``: allow Young's moduli that an engine refuses by default."""
        raise NotImplementedError

    def plane_wall(self, model, wall_type: int, *, zlo: float) -> list[str]:
        """A fixed bottom plane at ``zlo`` (fix id ``wbottom``)."""
        raise NotImplementedError

    def moving_blade(self, model, wall_type: int, blade, *, stl_path) -> list[str]:
        """A blade (:class:`~bedstruct.engines.BladeGeometry`) moving along +x."""
        raise NotImplementedError

    def fabric_lines(self, model) -> list[str]:
        """``compute fab``: the contact and normal-force fabric tensors as thermo columns."""
        self.refuse("`fabric` (compute fabric)",
                    "`fabric` needs LAMMPS without DMT/JKR cohesion (compute fabric)")

    def contact_computes(self, *, tangential: bool = False) -> list[str]:
        """Computes behind a contact ``dump local`` (defined before the first run)."""
        raise NotImplementedError

    def contact_columns(self, *, tangential: bool = False) -> str:
        """The ``dump local`` columns of :meth:`contact_computes`."""
        raise NotImplementedError

    def write_data_line(self, name: str) -> str:
        """``write_data`` of the final state."""
        return f"write_data {name}"

    def moving_run(self, fix: str, mesh: str, velocity: str, steps: int, *,
                   rotate: str | None = None) -> list[str]:
        """Run ``steps`` while wall ``mesh`` moves at ``velocity`` ("vx vy vz", and turns
        as ``rotate`` says: ``origin x y z axis ax ay az period T``)."""
        raise NotImplementedError

    def repose_walls(self, geometry, schedule, model, wall_type, *, stl_folder) -> list[str]:
        """Walls of the repose box (:class:`~bedstruct.engines.ReposeGeometry`)."""
        raise NotImplementedError

    def spread_walls(self, plan, model, wall_type, *, stl_folder) -> list[str]:
        """Platform, back and front walls, the side walls (``plan.side_walls``) and the
        tool of a spreading plan."""
        raise NotImplementedError
