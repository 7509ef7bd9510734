"""Sequences of frames: in memory or read lazily from files."""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np

from .frame import Frame

__all__ = ["Trajectory", "FrameList"]


class Trajectory(Sequence):
    """Read-only sequence of :class:`Frame` objects.

    Subclasses implement ``__len__`` and ``_read_frame(index)``; iteration
    reads one frame at a time, so a lazy subclass never holds more than the
    frame being used. Frames may differ in N and in their columns.

    Supports ``len()``, indexing (negative too), slicing (returning a list),
    iteration, ``timesteps``, and use as a context manager (``close()``).
    """

    def __len__(self) -> int:  # pragma: no cover - abstract
        raise NotImplementedError

    def _read_frame(self, index: int) -> Frame:  # pragma: no cover - abstract
        raise NotImplementedError

    @property
    def n_frames(self) -> int:
        """Number of frames."""
        return len(self)

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self._read_frame(k) for k in range(*index.indices(len(self)))]
        if isinstance(index, (int, np.integer)):
            n = len(self)
            k = int(index)
            if k < 0:
                k += n
            if not 0 <= k < n:
                raise IndexError(f"frame index {index} out of range for {n} frames")
            return self._read_frame(k)
        if np.ndim(index) == 1:
            return [self[int(k)] for k in index]
        raise TypeError(f"frame indices must be int or slice; got {type(index).__name__}")

    def __iter__(self) -> Iterator[Frame]:
        for k in range(len(self)):
            yield self._read_frame(k)

    @property
    def timesteps(self) -> np.ndarray:
        """Timestep of every frame (int64)."""
        return np.array([f.timestep for f in self], dtype=np.int64)

    def close(self) -> None:
        """Release open files (no-op for in-memory trajectories)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def __repr__(self) -> str:
        return f"{type(self).__name__}(n_frames={len(self)})"


class FrameList(Trajectory):
    """A trajectory held in memory.

    Examples
    --------
    >>> from bedstruct.core import Frame
    >>> t = FrameList([Frame([[0, 0, 0]], [1.0], box=[4, 4, 4], timestep=s) for s in (0, 10)])
    >>> len(t), t.timesteps.tolist()
    (2, [0, 10])
    """

    def __init__(self, frames: Sequence[Frame]):
        self._frames = list(frames)

    def __len__(self) -> int:
        return len(self._frames)

    def _read_frame(self, index: int) -> Frame:
        return self._frames[index]

    @property
    def timesteps(self) -> np.ndarray:
        return np.array([f.timestep for f in self._frames], dtype=np.int64)
