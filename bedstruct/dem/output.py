"""Run directories: configuration, LIGGGHTS-style dumps, contact dumps, wall states.

Frames are written with :func:`bedstruct.io.write_dump` and contacts with
:func:`bedstruct.io.write_dump_local`, the one writer of LIGGGHTS ``dump custom``
and ``dump local`` text (readable by OVITO and by bedstruct's readers, floats
round-trip exactly, triclinic boxes keep their tilt).
"""

from __future__ import annotations

import json
from pathlib import Path

from ..io import write_dump, write_dump_local

__all__ = ["RunDirectory"]


class RunDirectory:
    """A folder holding ``config.json``, ``dump.liggghts``, ``contacts.local``,
    ``walls.jsonl`` and ``checkpoint.npz`` of a run.

    Parameters
    ----------
    path : str or Path
        Created if missing.
    """

    def __init__(self, path):
        self.path = Path(path)
        self.path.mkdir(parents=True, exist_ok=True)

    @property
    def dump_path(self) -> Path:
        return self.path / "dump.liggghts"

    @property
    def contacts_path(self) -> Path:
        return self.path / "contacts.local"

    @property
    def walls_path(self) -> Path:
        return self.path / "walls.jsonl"

    def write_config(self, sim) -> None:
        """Write the full configuration of ``sim`` to ``config.json``."""
        (self.path / "config.json").write_text(json.dumps(sim.config(), indent=2, default=str))

    def write_output(self, sim) -> None:
        """Append the current frame, contacts and wall states."""
        frame = sim.frame()
        contacts = sim.contacts()
        write_dump(self.dump_path, frame, append=self.dump_path.exists())
        write_dump_local(self.contacts_path, frame, contacts, append=self.contacts_path.exists())
        with open(self.walls_path, "a") as fh:
            for ws in sim.wall_states():
                fh.write(json.dumps({"step": sim.step, "time": sim.time, "name": ws.name,
                                     "origin": ws.origin.tolist(), "velocity": ws.velocity.tolist(),
                                     "force": ws.force.tolist(), "n_contacts": ws.n_contacts}) + "\n")
