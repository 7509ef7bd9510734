"""Run any per-frame analysis over a trajectory and collect the results.

The per-frame step is kept apart from the reduction (MDAnalysis-style
``_prepare`` / ``_single_frame`` / ``_conclude`` hooks), so frames could be
processed in parallel later.
"""

from __future__ import annotations

import dataclasses
import logging
import numbers
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

__all__ = ["TimeSeries", "TimeSeriesResults"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TimeSeriesResults:
    """Per-frame values of an analysis.

    Attributes
    ----------
    frames : (F,) ndarray of int
        Indices of the analysed frames in the trajectory.
    timesteps : (F,) ndarray of int
    values : list
        What the analysis returned for each frame.
    """

    frames: np.ndarray
    timesteps: np.ndarray
    values: list

    def __len__(self) -> int:
        return len(self.values)

    def field(self, name: str | None = None) -> np.ndarray:
        """Stack one scalar attribute of every value (or the values themselves) into an array.

        Examples
        --------
        >>> r = TimeSeriesResults(np.arange(2), np.array([0, 10]), [1.5, 2.5])
        >>> r.field().tolist()
        [1.5, 2.5]
        """
        vals = self.values if name is None else [getattr(v, name) for v in self.values]
        return np.asarray([float(v) if np.ndim(v) == 0 and hasattr(v, "__float__") else v
                           for v in vals])

    def table(self) -> dict[str, np.ndarray]:
        """Columns ``frame``, ``timestep`` and every scalar field of the values.

        Examples
        --------
        >>> r = TimeSeriesResults(np.arange(0), np.zeros(0, int), [])
        >>> sorted(r.table())
        ['frame', 'timestep']
        """
        out: dict[str, np.ndarray] = {"frame": self.frames, "timestep": self.timesteps}
        if not self.values:
            return out
        first = self.values[0]
        if dataclasses.is_dataclass(first):
            for f in dataclasses.fields(first):
                v = getattr(first, f.name)
                if isinstance(v, (numbers.Real, np.number)) and not isinstance(v, bool):
                    out[f.name] = self.field(f.name).astype(np.float64)
        elif isinstance(first, (numbers.Real, np.number)) or hasattr(first, "__float__"):
            out["value"] = np.asarray([float(v) for v in self.values])
        return out


def _requires_run(prop):
    def getter(self):
        if not self._done:
            raise AttributeError(f"{type(self).__name__}.{prop.__name__} is not available yet; "
                                 "call run() first")
        return prop(self)
    getter.__name__ = prop.__name__
    getter.__doc__ = prop.__doc__
    return property(getter)


class TimeSeries:
    """Apply ``func(frame, **kwargs)`` to frames of a trajectory.

    Parameters
    ----------
    func : callable
        A per-frame analysis, e.g. :func:`~bedstruct.analysis.coordination`
        or :func:`~bedstruct.analysis.packing_fraction`.
    **kwargs
        Options passed to ``func`` on every frame.

    Examples
    --------
    >>> from bedstruct import Frame, FrameList
    >>> from bedstruct.analysis import packing_fraction
    >>> traj = FrameList([Frame([[1, 1, 1]], [r], box=([0, 0, 0], [2, 2, 2]), timestep=t)
    ...                   for t, r in enumerate((0.5, 1.0))])
    >>> ts = TimeSeries(packing_fraction, window=([0, 0, 0], [2, 2, 2])).run(traj)
    >>> ts.results.timesteps.tolist(), ts.results.field("fraction").round(4).tolist()
    ([0, 1], [0.0654, 0.5236])
    """

    def __init__(self, func: Callable[..., Any], **kwargs):
        if not callable(func):
            raise TypeError(f"`func` must be callable; got {type(func).__name__}")
        self.func = func
        self.kwargs = kwargs
        self._done = False
        self._results: TimeSeriesResults | None = None

    # --------------------------------------------------------------- hooks
    def _prepare(self) -> None:
        self._frames: list[int] = []
        self._timesteps: list[int] = []
        self._values: list[Any] = []

    def _single_frame(self, frame) -> Any:
        return self.func(frame, **self.kwargs)

    def _conclude(self) -> None:
        self._results = TimeSeriesResults(np.asarray(self._frames, dtype=np.int64),
                                          np.asarray(self._timesteps, dtype=np.int64),
                                          list(self._values))

    # ----------------------------------------------------------------- run
    def run(self, trajectory, *, start: int | None = None, stop: int | None = None,
            step: int | None = None, progress: bool = False) -> "TimeSeries":
        """Analyse frames ``start:stop:step`` of ``trajectory`` (a Trajectory or sequence).

        Returns ``self``; read :attr:`results`.
        """
        n = len(trajectory)
        idx = range(*slice(start, stop, step).indices(n))
        it = idx
        if progress:
            from tqdm.auto import tqdm
            it = tqdm(idx, desc=getattr(self.func, "__name__", "analysis"))
        self._prepare()
        for k in it:
            frame = trajectory[k]
            self._frames.append(k)
            self._timesteps.append(int(frame.timestep))
            self._values.append(self._single_frame(frame))
        self._conclude()
        self._done = True
        log.debug("TimeSeries(%s): %d frames", getattr(self.func, "__name__", "?"), len(idx))
        return self

    @_requires_run
    def results(self) -> TimeSeriesResults:
        """Per-frame values (after :meth:`run`)."""
        return self._results
