"""Atomic file writes: finished work is never left half-written.

A result is written to a temporary file in the target's folder and moved into
place with :func:`os.replace` (atomic on POSIX and Windows), so an interrupted
write leaves either the old file or the new one, never a truncated one.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

__all__ = ["atomic_path"]


@contextlib.contextmanager
def atomic_path(path, *, suffix: str = ".tmp"):
    """Yield a temporary path beside ``path``; on success it replaces ``path``.

    Any exception removes the temporary file and leaves ``path`` untouched.

    Examples
    --------
    >>> import os, tempfile
    >>> target = os.path.join(tempfile.mkdtemp(), "out.txt")
    >>> with atomic_path(target) as tmp:
    ...     _ = open(tmp, "w").write("done")
    >>> open(target).read()
    'done'
    >>> try:
    ...     with atomic_path(target) as tmp:
    ...         _ = open(tmp, "w").write("half")
    ...         raise RuntimeError("interrupted")
    ... except RuntimeError:
    ...     pass
    >>> open(target).read(), sorted(os.listdir(os.path.dirname(target)))
    ('done', ['out.txt'])
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=suffix)
    os.close(fd)
    # mkstemp makes the file private (0600); the result gets the mode a plain open() would give
    os.chmod(tmp, _default_mode(path))
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _default_mode(path: Path) -> int:
    """The existing file's permissions, else 0666 less the process umask."""
    try:
        return path.stat().st_mode & 0o7777
    except OSError:
        return 0o666 & ~_UMASK


def _process_umask() -> int:
    # read once at import: os.umask can only be read by setting it, which would race with
    # files created meanwhile by other threads
    umask = os.umask(0o022)
    os.umask(umask)
    return umask


_UMASK = _process_umask()
