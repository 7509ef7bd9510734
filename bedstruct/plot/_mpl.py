"""The one place where the figure modules import matplotlib (with the install hint)."""

from __future__ import annotations

__all__: list[str] = []


def figure_class(*, three_d: bool = False):
    """:class:`matplotlib.figure.Figure`, importing matplotlib on first use.

    With ``three_d=True`` the 3-D projection is registered as well. A missing
    matplotlib raises :class:`ImportError` naming the package to install.
    """
    try:
        from matplotlib.figure import Figure
        if three_d:
            import mpl_toolkits.mplot3d  # noqa: F401  (registers the 3-D projection)
    except ImportError as exc:  # pragma: no cover - matplotlib is a dependency
        raise ImportError("plotting needs matplotlib: pip install matplotlib") from exc
    return Figure
