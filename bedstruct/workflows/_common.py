"""Shared pieces of the workflows: model from config, size distribution, run layout, JSON."""

from __future__ import annotations

import json
import logging
import math
import os
import tempfile
from dataclasses import asdict, is_dataclass
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from .config import config_to_toml

log = logging.getLogger(__name__)

__all__ = ["RunLayout", "write_json_atomic", "contact_model", "psd_sampler", "check_engine",
           "to_jsonable", "CONTACT_KEYWORDS"]

#: LIGGGHTS ``compute pair/gran/local`` keywords of the contact dumps written by the workflows.
CONTACT_KEYWORDS = ("pos", "id", "force", "force_normal", "force_tangential", "contactArea")


def check_engine(cfg: dict) -> None:
    """Raise ConfigError for engines the workflows cannot drive yet."""
    eng = cfg.get("engine", "embedded")
    if eng != "embedded":
        raise ConfigError(f"engine {eng!r} is not yet supported by the workflows (only the embedded "
                          "engine runs repose/spread/calibrate; see bedstruct.dem.backends for "
                          "LIGGGHTS/LAMMPS decks)")


def contact_model(cfg: dict, *, cohesion: float | None = None):
    """The :class:`~bedstruct.dem.ContactModel` of a configuration (SI)."""
    from ..dem import ContactModel, Material
    m, c = cfg["material"], cfg["contact"]
    mat = Material(m["youngs_modulus"], m["poisson_ratio"], m["density"])
    k = float(c["cohesion"] if cohesion is None else cohesion)
    if k < 0:
        raise ConfigError(f"config key `contact.cohesion` must be >= 0; got {k}")
    kw = {}
    if c["wall_friction"] >= 0:
        kw["wall_friction"] = c["wall_friction"]
    if c["wall_cohesion"] >= 0:
        kw["wall_cohesion"] = c["wall_cohesion"]
    return ContactModel(mat, restitution=c["restitution"], friction=c["friction"],
                        rolling_friction=c["rolling_friction"], cohesion=k,
                        rolling_model=c["rolling_model"], **kw)


def psd_sampler(cfg: dict):
    """A callable ``(n, rng) -> radii`` (m) drawing from the fitted, scaled size distribution.

    The volume-weighted D10/D50/D90 are fitted with
    :func:`bedstruct.analysis.psd_from_percentiles` (truncated to
    ``[d_min, d_max]``) and every drawn diameter is multiplied by
    ``psd.scale``.
    """
    from ..analysis import psd_from_percentiles
    p = cfg["psd"]
    fit = psd_from_percentiles(p["d10"], p["d50"], p["d90"], (p["d_min"], p["d_max"]),
                               weighting="volume")
    scale = float(p["scale"])

    def draw(n, rng):
        return scale * fit.sample_radii(int(n), seed=rng)
    draw.r_min = 0.5 * scale * p["d_min"]
    draw.r_max = 0.5 * scale * p["d_max"]
    draw.fit = fit
    return draw


def to_jsonable(obj):
    """Convert dataclasses, arrays and numpy scalars to JSON-ready data (NaN -> None)."""
    if is_dataclass(obj) and not isinstance(obj, type):
        return {k: to_jsonable(v) for k, v in asdict(obj).items()}
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return to_jsonable(obj.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    return obj


def write_json_atomic(path, data) -> Path:
    """Write JSON to ``path`` atomically (temporary file in the same folder, then rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as fh:
            json.dump(to_jsonable(data), fh, indent=2)
            fh.write("\n")
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


class RunLayout:
    """The folder of one workflow run.

    Layout::

        OUT/config.toml            the resolved configuration
        OUT/results.json           results (written atomically, last)
        OUT/<stage>/frames.dump.gz LIGGGHTS dump custom frames (SI)
        OUT/<stage>/contacts.dump.gz  pair/gran/local dump local of the same timesteps
        OUT/<stage>/walls.jsonl    wall (plate, blade, roller) position/velocity/force per frame
        OUT/<stage>/final.dump.gz, final_contacts.dump.gz  the state at the end of the stage
        OUT/<stage>/checkpoint.npz engine checkpoint (output.checkpoint = true)

    ``<stage>`` is ``rep00``, ``rep01``... for repose replicates,
    ``pile`` and ``layer01``... for spreading, ``k<value>/rep00`` for
    calibration points.
    """

    def __init__(self, path, cfg: dict | None = None):
        self.path = Path(path)
        self.path.mkdir(parents=True, exist_ok=True)
        self.cfg = cfg
        if cfg is not None:
            (self.path / "config.toml").write_text(config_to_toml(cfg))

    def stage(self, name: str) -> "StageWriter":
        out = self.cfg["output"] if self.cfg else {"frames": True, "contacts": True,
                                                    "compress": True, "checkpoint": False}
        return StageWriter(self.path / name, out)

    def write_results(self, data) -> Path:
        return write_json_atomic(self.path / "results.json", data)


class StageWriter:
    """Writes frames, contacts and wall states of one stage (see :class:`RunLayout`)."""

    def __init__(self, path: Path, out: dict):
        self.path = Path(path)
        self.path.mkdir(parents=True, exist_ok=True)
        self.out = out
        ext = ".dump.gz" if out.get("compress", True) else ".dump"
        self.frames_path = self.path / f"frames{ext}"
        self.contacts_path = self.path / f"contacts{ext}"
        self.walls_path = self.path / "walls.jsonl"
        self._ext = ext
        for p in (self.frames_path, self.contacts_path, self.walls_path):
            if p.exists():
                p.unlink()

    def record(self, sim, *, frame=None) -> None:
        """Append the current frame, contacts and wall states of ``sim``."""
        from ..io import write_dump, write_dump_local
        frame = sim.frame() if frame is None else frame
        if self.out.get("frames", True):
            write_dump(self.frames_path, frame, append=self.frames_path.exists())
        if self.out.get("contacts", True):
            write_dump_local(self.contacts_path, frame, sim.contacts(),
                             append=self.contacts_path.exists())
        with open(self.walls_path, "a") as fh:
            for ws in sim.wall_states():
                fh.write(json.dumps({"step": sim.step, "time": sim.time, "name": ws.name,
                                     "origin": ws.origin.tolist(), "velocity": ws.velocity.tolist(),
                                     "force": ws.force.tolist(), "n_contacts": ws.n_contacts}) + "\n")

    def final(self, sim, name: str = "final"):
        """Write the final state (atoms and contacts) and a checkpoint when configured."""
        from ..io import write_dump, write_dump_local
        frame = sim.frame()
        write_dump(self.path / f"{name}{self._ext}", frame)
        write_dump_local(self.path / f"{name}_contacts{self._ext}", frame, sim.contacts())
        if self.out.get("checkpoint", False):
            sim.save_checkpoint(self.path / "checkpoint.npz")
        return frame
