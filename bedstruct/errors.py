"""Exceptions and warnings raised by bedstruct.

Every error that comes from bad input says where the input is (file and line
where there is one), what was found and what was expected, so that a user can
fix the file rather than debug the library.
"""

from __future__ import annotations

__all__ = [
    "BedstructError",
    "DumpFormatError",
    "ConfigError",
    "UnsafeTimestepError",
    "RunFolderInUseError",
    "BedstructWarning",
]


class BedstructError(Exception):
    """Base class of all bedstruct errors."""


class DumpFormatError(BedstructError, ValueError):
    """A dump, data or contact file does not follow the format it claims.

    Parameters
    ----------
    message : str
        What was expected and what was found.
    path : str, optional
        The file being read.
    line : int, optional
        1-based line number (text files) or byte offset (binary files, with
        ``line`` then counting records) where the problem was found.
    text : str, optional
        The offending text, shortened to 80 characters.

    Examples
    --------
    >>> err = DumpFormatError("expected 3 values, got 2", path="a.dump", line=12,
    ...                       text="1 2")
    >>> print(err)
    a.dump, line 12: expected 3 values, got 2 (found: '1 2')
    >>> isinstance(err, ValueError)
    True
    """

    def __init__(self, message: str, *, path: str | None = None,
                 line: int | None = None, text: str | None = None):
        self.message = message
        self.path = None if path is None else str(path)
        self.line = line
        self.text = text
        super().__init__(self._format())

    def _format(self) -> str:
        where = []
        if self.path is not None:
            where.append(self.path)
        if self.line is not None:
            where.append(f"line {self.line}")
        out = ", ".join(where)
        out = f"{out}: {self.message}" if out else self.message
        if self.text is not None:
            shown = self.text if len(self.text) <= 80 else self.text[:77] + "..."
            out += f" (found: {shown!r})"
        return out

    def __reduce__(self):  # keep keyword arguments through pickling
        return (_rebuild_dump_error, (self.message, self.path, self.line, self.text))


def _rebuild_dump_error(message, path, line, text):
    return DumpFormatError(message, path=path, line=line, text=text)


class ConfigError(BedstructError, ValueError):
    """A workflow or measurement configuration is invalid (names the key)."""


class UnsafeTimestepError(BedstructError, ValueError):
    """The requested DEM time step exceeds the stable limit (see message)."""


class RunFolderInUseError(BedstructError, RuntimeError):
    """Another process is writing a workflow run in the same output folder (it holds the
    folder's lock until its run ends, fails or is killed)."""


class BedstructWarning(UserWarning):
    """Suspicious but legal input (large overlaps, skipped truncated frame, ...)."""
