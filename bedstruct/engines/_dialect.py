"""What every external engine's dialect provides: :class:`Dialect`.

A dialect spells bedstruct's scenarios (a settled bed, a head-on impact, the
angle-of-repose box, multi-layer spreading) in one engine's commands. The scenario
writers (:func:`~bedstruct.engines.bed_deck`, :func:`~bedstruct.engines.repose_deck`,
:func:`~bedstruct.engines.spread_layers_deck` ...) hold the sequence of a scenario,
the same for every engine, and ask the dialect for each engine-specific piece: the
set-up lines, the contact model, walls, moving meshes or regions, contact dumps.

A piece that an engine cannot realise is refused by name (:meth:`Dialect.refuse`,
a :class:`~bedstruct.errors.ConfigError`), never replaced by another model.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import ClassVar

from ..errors import ConfigError
from ._datafile import data_file_radii, read_data_header
from ._launch import run_deck
from ._logs import parse_log

__all__ = ["Dialect", "DUMP_COLUMNS", "path_word"]

#: Per-particle dump columns written by every deck.
DUMP_COLUMNS = "id type x y z vx vy vz fx fy fz omegax omegay omegaz radius"

#: Diagnosis extensions (config section ``effects``) that no deck writes: the
#: embedded engine's own; a deck without them would be the base model under their name.
_EMBEDDED_ONLY = ("capillary", "contact_ageing")
_EMBEDDED_ONLY_SPREADING = ("blade_ramp_time", "blade_vibration_amplitude")
#: Options of how one engine maps the seed's contact model; meaningless (ignored) elsewhere.
_MAPPING_OPTIONS = ("cohesion_model", "reference_radius", "reference_overlap")


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
    """

    name: ClassVar[str] = ""
    executable_name: ClassVar[str] = ""
    atom_style: ClassVar[str] = ""
    comm_vel: ClassVar[str] = ""
    contact_dump_columns: ClassVar[str] = ""
    tool_load: ClassVar[tuple] = ("", "")
    impact_thermo_modify: ClassVar[str] = "thermo_modify norm no"

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

    def check_effects(self, effects, *, spreading: bool = False) -> None:
        """Refuse the diagnosis extensions (config section ``effects``) no deck writes.

        Wall friction, missing fines and rolling friction are ordinary deck
        parameters; capillary bridges, contact ageing and the blade's start-up ramp
        and vibration exist in the embedded engine only.

        Raises
        ------
        bedstruct.errors.ConfigError
            Naming the keys.
        """
        fx = effects or {}
        found = [k for k in _EMBEDDED_ONLY if fx.get(k)]
        if spreading:
            found += [k for k in _EMBEDDED_ONLY_SPREADING if float(fx.get(k, 0.0)) > 0.0]
        if found:
            raise ConfigError(
                f"engine {self.name!r}: config key(s) {', '.join('effects.' + k for k in found)} "
                "are extensions of the embedded engine, not written to the "
                f"{self.name} decks; run them with --engine embedded (for LIGGGHTS-made "
                "twins with liquid bridges see bedstruct.diagnose.external_twins)")

    def cohesion_options(self, p, choice: str):
        """How this engine writes the cohesion of ``p``: ``(params, cohesion_model)``.

        ``choice`` is the config's ``external.cohesion_model`` (``dmt``, ``jkr`` or
        ``none``); engines with SJKR cohesion ignore it (``cohesion_model`` None).
        """
        return p, None

    def approximations(self, *, tool=None) -> list[str]:
        """Notes on what this engine's decks write differently from the embedded run."""
        return []

    def header(self, title: str) -> str:
        """The first line of a deck."""
        return f"# bedstruct deck for {self.name}: {title}"

    def setup_lines(self, boundary: str, processors: str | None) -> list[str]:
        """Atom style, boundary, communication and units (SI) lines."""
        lines = [f"atom_style {self.atom_style}", "atom_modify map array", f"boundary {boundary}",
                 "newton off", self.comm_vel, "units si"]
        if processors:
            lines.append(f"processors {processors}")
        return lines

    def workflow_head(self, data_file, p, *, title: str, boundary: str, dt: float, skin):
        """Deck lines up to gravity of the workflow decks (set-up, data file, neighbours,
        contact model, time step); returns ``(lines, wall_type)``."""
        head = read_data_header(data_file)
        if head["atom types"] < 2:
            raise ValueError("the data file must declare 2 atom types (walls use type 2); write "
                             "it with write_sphere_data(..., n_types=2)")
        if skin is None:
            r = data_file_radii(data_file)
            skin = 0.2 * float(r.min()) if r.size else 1e-6
        lines = [self.header(title), *self.setup_lines(boundary, "* 1 1"),
                 f"read_data {path_word(data_file)}",
                 f"neighbor {skin:.10g} bin", "neigh_modify delay 0"]
        model, wt = self.model_lines(p, n_types=head["atom types"], soft=True)
        lines += model
        lines.append(f"timestep {dt:.10g}")
        if p.gravity > 0:
            lines.append(f"fix gravi all gravity {p.gravity:.10g} vector 0.0 0.0 -1.0")
        return lines, wt

    # ------------------------------------------------------------------ hooks
    def model_lines(self, p, *, n_types: int, soft: bool = False) -> tuple[list[str], int]:
        """Contact model lines for ``n_types`` atom types and the walls' atom type.

        ``soft``: allow Young's moduli that an engine refuses by default."""
        raise NotImplementedError

    def plane_wall(self, p, wall_type: int, *, zlo: float) -> list[str]:
        """A fixed bottom plane at ``zlo`` (fix id ``wbottom``)."""
        raise NotImplementedError

    def moving_blade(self, p, wall_type: int, blade, *, stl_path) -> list[str]:
        """A blade (:class:`~bedstruct.engines.BladeGeometry`) moving along +x."""
        raise NotImplementedError

    def fabric_lines(self, p) -> list[str]:
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

    def repose_walls(self, geometry, schedule, p, wall_type, *, stl_folder) -> list[str]:
        """Walls of the repose box (:class:`~bedstruct.engines.ReposeGeometry`)."""
        raise NotImplementedError

    def spread_walls(self, plan, p, wall_type, *, stl_folder) -> list[str]:
        """Platform, back and front walls and the tool of a spreading plan."""
        raise NotImplementedError
