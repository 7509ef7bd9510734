"""Run directories: configuration, LIGGGHTS-style dumps, contact dumps, wall states.

Frames are written with :func:`bedstruct.io.write_dump` and contacts with
:func:`bedstruct.io.write_dump_local` when bedstruct.io provides them; otherwise
a minimal private writer produces the same LIGGGHTS ``dump custom`` text
(readable by OVITO and by bedstruct's readers).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

__all__ = ["RunDirectory", "write_dump_text", "write_contacts_text"]

_ATOM_COLS = ("id", "type", "x", "y", "z", "ix", "iy", "iz", "vx", "vy", "vz", "fx", "fy", "fz",
              "omegax", "omegay", "omegaz", "radius", "mass")
_PAIR_COLS = ("x1", "y1", "z1", "x2", "y2", "z2", "id1", "id2", "periodic", "fx", "fy", "fz",
              "fnx", "fny", "fnz", "ftx", "fty", "ftz", "contactArea", "delta")


def _box_header(box) -> str:
    b = " ".join(box.boundary)
    lines = [f"ITEM: BOX BOUNDS {b}"]
    for a in range(3):
        lines.append(f"{box.lo[a]:.16e} {box.hi[a]:.16e}")
    return "\n".join(lines) + "\n"


def write_dump_text(fh, frame) -> None:
    """Append one LIGGGHTS ``dump custom`` frame (SI) to an open text file."""
    n = frame.n_particles
    fh.write(f"ITEM: TIMESTEP\n{frame.timestep}\nITEM: NUMBER OF ATOMS\n{n}\n")
    fh.write(_box_header(frame.box))
    fh.write("ITEM: ATOMS " + " ".join(_ATOM_COLS) + "\n")
    img = frame.images if frame.images is not None else np.zeros((n, 3), dtype=np.int64)
    cols = [frame.ids, frame.types, *frame.positions.T, *img.T, *frame.velocities.T,
            *frame.forces.T, *frame.omegas.T, frame.radii, frame.columns["mass"]]
    arr = np.column_stack([np.asarray(c, dtype=np.float64) for c in cols]) if n else np.zeros((0, 19))
    fmt = ["%d", "%d"] + ["%.10e"] * 3 + ["%d"] * 3 + ["%.8e"] * 11
    np.savetxt(fh, arr, fmt=fmt)


def write_contacts_text(fh, frame, contacts, timestep: int) -> None:
    """Append one ``dump local`` frame in the column layout of LIGGGHTS ``pair/gran/local``."""
    m = contacts.n_contacts
    fh.write(f"ITEM: TIMESTEP\n{timestep}\nITEM: NUMBER OF ENTRIES\n{m}\n")
    fh.write(_box_header(frame.box))
    fh.write("ITEM: ENTRIES " + " ".join(_PAIR_COLS) + "\n")
    if m == 0:
        return
    xi = frame.positions[contacts.i]
    xj = xi + contacts.branch
    fnv = contacts.force_normal
    ftv = contacts.force_tangential
    arr = np.column_stack([xi, xj, contacts.ids_i, contacts.ids_j, contacts.periodic.astype(int),
                           fnv + ftv, fnv, ftv, contacts.area, contacts.overlap])
    fmt = ["%.10e"] * 6 + ["%d"] * 3 + ["%.8e"] * 11
    np.savetxt(fh, arr, fmt=fmt)


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
        try:  # prefer the shared writers of bedstruct.io
            from .. import io as bio
            dump_writer = getattr(bio, "write_dump", None)
            local_writer = getattr(bio, "write_dump_local", None)
        except ImportError:  # pragma: no cover - io always present in a full install
            dump_writer = local_writer = None
        if dump_writer is not None:
            dump_writer(self.dump_path, frame, append=self.dump_path.exists())
        else:  # pragma: no cover
            with open(self.dump_path, "a") as fh:
                write_dump_text(fh, frame)
        if local_writer is not None:
            local_writer(self.contacts_path, frame, contacts, append=self.contacts_path.exists())
        else:  # pragma: no cover
            with open(self.contacts_path, "a") as fh:
                write_contacts_text(fh, frame, contacts, sim.step)
        with open(self.walls_path, "a") as fh:
            for ws in sim.wall_states():
                fh.write(json.dumps({"step": sim.step, "time": sim.time, "name": ws.name,
                                     "origin": ws.origin.tolist(), "velocity": ws.velocity.tolist(),
                                     "force": ws.force.tolist(), "n_contacts": ws.n_contacts}) + "\n")
