"""What a report analyses: :class:`ReportOptions` (its settings, checked when made) and the
frame selection (:func:`select_frames`)."""

from __future__ import annotations

from dataclasses import dataclass

from ..analysis.german import GERMAN_WINDOWS

__all__ = ["ReportOptions", "select_frames"]

_REGION_NAMES = {1: ["bed"], 2: ["start", "end"], 3: ["start", "centre", "end"]}
_AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class ReportOptions:
    """Settings of a report.

    Parameters
    ----------
    regions : int
        Number of regions along the bed (default 3: start, centre, end).
    axis : str
        Spreading direction, ``"x"``, ``"y"`` or ``"z"``.
    frames : str
        Which frames to analyse: ``"-1"`` (last, default), ``"all"``, an
        index, or a slice ``"start:stop:step"``. Per-frame series use all
        selected frames; the detailed sections use the last selected one.
    heat : bool
        Run the heat-conduction section (needs SI or a known unit system).
    heat_length_unit : float or None
        Metres per length unit of the dump when its unit system is unknown.
    heat_stop_fraction : float
        The heat runs end when the hottest particle has cooled to this fraction
        of the pulse excess temperature (default 0.25; see
        :func:`bedstruct.analysis.heat_study.heat_regions`).
    tolerance : float
        Contact detection tolerance (length) for geometric contacts.
    l_max : int
        Highest degree of the spherical-harmonic expansion.
    repose_base : float or None
        Height (length) of the plate the pile stands on; particles below it
        are ignored by the angle of repose. Default: found from the profile.
    german_windows : int
        Windows along the bed for German's-law fit (default 12, the library
        default of :func:`bedstruct.analysis.german_law_along`).
    min_contacts : int
        Rattler threshold of the mechanical coordination number (default 2:
        with friction and cohesion a particle needs two contacts to be held
        in a spread bed; use 4 for frictionless packings).
    view_3d : bool
        Draw the 3-D picture of the bed at the top of the report (default
        True; needs pyvista, the ``interop`` extra, and an off-screen
        renderer; the report says why when it is not drawn). The side view
        is always drawn.
    """

    regions: int = 3
    axis: str = "x"
    frames: str = "-1"
    heat: bool = False
    heat_length_unit: float | None = None
    heat_stop_fraction: float = 0.25
    tolerance: float = 0.0
    l_max: int = 8
    min_contacts: int = 2
    repose_base: float | None = None
    german_windows: int = GERMAN_WINDOWS
    view_3d: bool = True

    def __post_init__(self):
        if self.axis not in _AXES:
            raise ValueError(f"`axis` must be one of 'x', 'y', 'z'; got {self.axis!r}")
        if int(self.regions) < 1:
            raise ValueError(f"`regions` must be at least 1; got {self.regions}")
        if self.l_max < 2 or self.l_max % 2:
            raise ValueError(f"`l_max` must be an even number >= 2; got {self.l_max}")
        _parse_frame_selection(self.frames)
        if int(self.german_windows) < 3:
            raise ValueError(f"`german_windows` must be at least 3; got {self.german_windows}")

    @property
    def axis_index(self) -> int:
        return _AXES[self.axis]

    @property
    def region_names(self) -> list[str]:
        return _REGION_NAMES.get(self.regions, [f"region {k + 1}" for k in range(self.regions)])


def select_frames(n_frames: int, selection: str) -> list[int]:
    """Frame indices for a selection string (``-1``, ``all``, ``3``, ``0:10:2``).

    Examples
    --------
    >>> select_frames(5, "-1"), select_frames(5, "all"), select_frames(5, "1:4:2")
    ([4], [0, 1, 2, 3, 4], [1, 3])
    """
    parsed = _parse_frame_selection(selection)
    if n_frames == 0:
        raise ValueError("the input has no frames")
    if parsed is None:
        return list(range(n_frames))
    if isinstance(parsed, slice):
        idx = list(range(n_frames))[parsed]
    else:
        k = parsed
        if not -n_frames <= k < n_frames:
            raise ValueError(f"frame {k} out of range: the input has {n_frames} frames")
        idx = [k % n_frames]
    if not idx:
        raise ValueError(f"frame selection {selection!r} selects no frame of {n_frames}")
    return idx


def _parse_frame_selection(selection: str):
    """None for all frames, a slice, or an index; ValueError naming the expected forms."""
    sel = str(selection).strip()
    if sel in ("all", ":"):
        return None
    expected = f"frame selection {selection!r}: expected 'all', an index or start:stop:step"
    try:
        if ":" in sel:
            parts = [int(p) if p.strip() else None for p in sel.split(":")]
            if len(parts) > 3:
                raise ValueError
            return slice(*parts)
        return int(sel)
    except ValueError:
        raise ValueError(expected) from None
