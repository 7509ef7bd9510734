"""Resuming a workflow stage: a killed run restarts from its latest checkpoint, bit for bit.

:class:`Resumable` runs a stage script (its steps, reads and changes of the simulation,
each a numbered segment) so that a run restarted from a checkpoint replays the script
up to it and continues exactly; :func:`resumable_simulation` makes a stage's
:class:`~bedstruct.dem.Simulation` behind one, :func:`run_in_frames` runs a duration
in even chunks, and :func:`as_resumable` wraps a plain simulation. The run folders the
checkpoints live in are :mod:`bedstruct.workflows._rundir`.
"""

from __future__ import annotations

import logging
from pathlib import Path

from .._json import plain

log = logging.getLogger("bedstruct.workflows._common")

__all__ = ["Resumable", "run_in_frames", "as_resumable", "resumable_simulation"]


def run_in_frames(sim, duration: float, n_frames: int, on_frame) -> None:
    """Run ``duration`` seconds in ``n_frames`` even chunks, calling ``on_frame()`` after each.

    ``sim`` is a :class:`~bedstruct.dem.Simulation` or a :class:`Resumable`.
    """
    ctl = as_resumable(sim)
    steps = max(1, ctl.sim.steps_for(duration))
    k = max(1, int(n_frames))
    done = 0
    for i in range(k):
        nxt = int(round(steps * (i + 1) / k))
        if nxt > done:
            ctl.run(nxt - done)
            done = nxt
        on_frame()


_APPENDED = ("frames.dump", "frames.dump.gz", "contacts.dump", "contacts.dump.gz", "walls.jsonl")


def _appended_files(root: Path) -> list[Path]:
    """The appended outputs (frames, contacts, wall states) in ``root`` and its sub-folders."""
    out = [root / n for n in _APPENDED if (root / n).is_file()]
    if root.is_dir():
        for d in sorted(root.iterdir()):
            if d.is_dir():
                out += [d / n for n in _APPENDED if (d / n).is_file()]
    return out


class Resumable:
    """Runs a stage script so that a killed run restarts from its latest checkpoint.

    The script drives the simulation only through this object: :meth:`run` (advance
    steps), :meth:`value` (anything read from the simulation, with its side effects on
    output files: memoised) and :meth:`do` (a change of the simulation that is not a step:
    inserting particles, moving walls; or a write). Each call is a numbered segment.
    Checkpoints (:meth:`checkpoint` at the script's stage boundaries, and every ``every``
    steps strictly inside a :meth:`run`) store the engine state with the number of finished
    segments, the steps done of the current one and the memoised values. Restarted from a
    checkpoint, the script runs again from its start: finished segments are skipped (values
    come back from the checkpoint), the interrupted run finishes its steps, and the
    appended outputs are cut back to their size at the checkpoint. The result is the
    uninterrupted run's, bit for bit (tested).

    With ``path=None`` nothing is saved: the calls pass straight through.

    Parameters
    ----------
    path : path or None
        The checkpoint file (``progress.npz``).
    every : int
        Steps between checkpoints inside runs (0: only at :meth:`checkpoint`).
    root : path, optional
        Folder whose appended outputs (and those of its sub-folders) are cut back on resume.
    """

    def __init__(self, path=None, *, every: int = 0, root=None):
        self.path = None if path is None else Path(path)
        self.every = max(0, int(every))
        self.root = None if root is None else Path(root)
        self.sim = None
        self.seg = 0          # segments entered so far in this pass over the script
        self.done = 0         # segments finished at the checkpoint resumed from
        self.partial = 0      # steps of segment `done` run before that checkpoint
        self.values: dict[int, object] = {}
        self.resumed_at = None

    @classmethod
    def passthrough(cls, sim) -> "Resumable":
        """A :class:`Resumable` that saves nothing, around ``sim``."""
        ctl = cls(None)
        ctl.sim = sim
        return ctl

    def start(self, make, restore):
        """The simulation: ``restore(path)`` from the checkpoint when there is one (then
        the script replays up to it), else ``make()``."""
        if self.path is not None and self.path.is_file():
            sim = restore(self.path)
            st = getattr(sim, "checkpoint_extra", {}).get("stage")
            if st is not None:
                self.sim = sim
                self.done, self.partial = int(st["seg"]), int(st["partial"])
                self.values = {int(k): v for k, v in st["values"].items()}
                self.resumed_at = sim.step
                if self.root is not None:
                    from ..dem.output import truncate_outputs
                    sizes = {str(self.root / k): v
                             for k, v in sim.checkpoint_extra.get("stage_outputs", {}).items()}
                    truncate_outputs(sizes, _appended_files(self.root))
                log.info("%s: resuming from the checkpoint at step %d", self.path.parent,
                         sim.step)
                return sim
            log.warning("%s is not a stage checkpoint; starting the stage over", self.path)
        self.sim = make()
        return self.sim

    @property
    def replaying(self) -> bool:
        """The script is still before the checkpoint it was resumed from."""
        return self.seg < self.done

    def _enter(self) -> int:
        i = self.seg
        self.seg += 1
        return i

    def run(self, steps: int) -> None:
        """Advance ``steps`` steps (checkpoints every ``every`` steps inside)."""
        i = self._enter()
        if i < self.done:
            return
        first = self.partial if i == self.done else 0
        self.partial = 0
        left = int(steps) - first
        if first and left <= 0:
            return
        sim = self.sim
        while True:
            if self.path is not None and self.every > 0 and left > 0:
                to_next = self.every - sim.step % self.every
                if to_next < left:  # a checkpoint strictly inside the run
                    sim.run(to_next)
                    left -= to_next
                    first += to_next
                    self._save(i, first)
                    continue
            sim.run(max(left, 0))
            return

    def run_time(self, seconds: float) -> None:
        """Advance ``seconds`` (rounded up to whole steps, as ``Simulation.run(time=)``)."""
        self.run(self.sim.steps_for(seconds))

    def value(self, fn):
        """``fn()`` (a read of the simulation), as :func:`plain` data; on a replay the value
        the interrupted run got."""
        i = self._enter()
        if i < self.done:
            return self.values[i]
        v = plain(fn())
        if self.path is not None:
            self.values[i] = v
        return v

    def do(self, fn) -> None:
        """``fn()`` (a change of the simulation or a write), skipped on a replay."""
        i = self._enter()
        if i >= self.done:
            fn()

    def checkpoint(self) -> None:
        """Save a checkpoint here (a stage boundary)."""
        if self.path is None or self.seg <= self.done:
            return  # nothing to save, or the checkpoint resumed from is this one
        self._save(self.seg, 0)

    def _save(self, seg: int, partial: int) -> None:
        extra = {"stage": {"seg": seg, "partial": partial,
                           "values": {str(k): v for k, v in self.values.items()}}}
        if self.root is not None:
            from ..dem.output import output_sizes
            extra["stage_outputs"] = {str(Path(k).relative_to(self.root)): v for k, v in
                                      output_sizes(_appended_files(self.root)).items()}
        self.sim.save_checkpoint(self.path, extra=extra)

    def finish(self) -> None:
        """The stage is done: remove its checkpoint."""
        if self.path is not None:
            self.path.unlink(missing_ok=True)


def resumable_simulation(cfg, checkpoint, box, model, walls, *, min_radius: float, seed,
                         root=None):
    """A workflow stage's :class:`~bedstruct.dem.Simulation` behind a :class:`Resumable`.

    The controller checkpoints into ``checkpoint`` (a path, or None to save nothing)
    every ``output.checkpoint_every`` steps, and cuts the appended outputs under ``root``
    back on a restart; the simulation is restored from the checkpoint when there is one,
    else made from the configuration's time-step settings. Returns
    ``(controller, simulation)``.
    """
    from ..dem import Simulation
    from ._common import typed
    cfg = typed(cfg)
    ctl = Resumable(checkpoint, every=int(cfg.output.checkpoint_every), root=root)
    sim = ctl.start(lambda: Simulation(box, model, walls=walls, safety=cfg.time.safety,
                                       v_max=cfg.time.v_max, min_radius=min_radius,
                                       n_threads=cfg.n_threads, seed=seed),
                    lambda path: Simulation.from_checkpoint(path, model, walls=walls))
    return ctl, sim


def as_resumable(obj) -> Resumable:
    """``obj`` if it is a :class:`Resumable`, else a pass-through one around the simulation."""
    return obj if isinstance(obj, Resumable) else Resumable.passthrough(obj)
