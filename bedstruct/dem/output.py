"""Run directories: configuration, LIGGGHTS-style dumps, contact dumps, wall states.

Frames are written with :func:`bedstruct.io.write_dump` and contacts with
:func:`bedstruct.io.write_dump_local`, the one writer of LIGGGHTS ``dump custom``
and ``dump local`` text (readable by OVITO and by bedstruct's readers, floats
round-trip exactly, triclinic boxes keep their tilt). Frames carry
``ITEM: UNITS si``, so :func:`bedstruct.io.read_dump` gives them ``Units("si")``.

Appended outputs can be cut back to the sizes they had when a checkpoint was
written (:func:`output_sizes`, :func:`truncate_outputs`): a run resumed from the
checkpoint then appends exactly what the interrupted run would have.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from ..io import write_dump, write_dump_local

__all__ = ["RunDirectory", "output_sizes", "truncate_outputs"]


def output_sizes(paths) -> dict[str, int]:
    """``{path: size in bytes}`` of the files of ``paths`` that exist."""
    out = {}
    for p in paths:
        p = Path(p)
        if p.is_file():
            out[str(p)] = p.stat().st_size
    return out


def truncate_outputs(sizes: dict, paths=()) -> list[str]:
    """Cut appended files back to ``sizes`` (from :func:`output_sizes`).

    A file longer than its recorded size is truncated (every append of a ``.gz``
    dump is a complete gzip member, so the cut file stays valid); a file of
    ``paths`` that was not recorded (it was created after the record) is removed.
    Returns the paths changed.
    """
    changed = []
    for name, size in sizes.items():
        p = Path(name)
        if p.is_file() and p.stat().st_size > int(size):
            os.truncate(p, int(size))
            changed.append(str(p))
    for p in paths:
        p = Path(p)
        if str(p) not in sizes and p.is_file():
            p.unlink()
            changed.append(str(p))
    return changed


def write_walls(path, sim) -> None:
    """Append one JSON line per wall (origin, velocity, particle force, contacts) to ``path``."""
    with open(path, "a") as fh:
        for ws in sim.wall_states():
            fh.write(json.dumps({"step": sim.step, "time": sim.time, "name": ws.name,
                                 "origin": ws.origin.tolist(), "velocity": ws.velocity.tolist(),
                                 "force": ws.force.tolist(), "n_contacts": ws.n_contacts}) + "\n")


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

    @property
    def _outputs(self):
        return (self.dump_path, self.contacts_path, self.walls_path)

    def output_sizes(self) -> dict[str, int]:
        """Sizes (bytes) of the appended outputs, by file name."""
        return {Path(k).name: v for k, v in output_sizes(self._outputs).items()}

    def truncate(self, sizes: dict) -> list[str]:
        """Cut the appended outputs back to ``sizes`` (from :meth:`output_sizes`); outputs
        not in ``sizes`` are removed. Returns the paths changed."""
        return truncate_outputs({str(self.path / k): v for k, v in sizes.items()}, self._outputs)

    def write_config(self, sim) -> None:
        """Write the full configuration of ``sim`` to ``config.json``."""
        (self.path / "config.json").write_text(json.dumps(sim.config(), indent=2, default=str))

    def write_output(self, sim) -> None:
        """Append the current frame (with ``ITEM: UNITS si``), contacts and wall states."""
        frame = sim.frame()
        contacts = sim.contacts()
        write_dump(self.dump_path, frame, append=self.dump_path.exists(), units_item=True)
        write_dump_local(self.contacts_path, frame, contacts, append=self.contacts_path.exists())
        write_walls(self.walls_path, sim)
