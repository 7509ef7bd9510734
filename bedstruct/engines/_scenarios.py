"""Scenario descriptions that every dialect writes decks from (SI units): the repose box
(:class:`ReposeGeometry`, :class:`ReposeSchedule`) and a multi-layer spreading run
(:class:`SpreadLayersPlan` and each layer's :class:`LayerSteps`).

The tools (:class:`~bedstruct.engines.BladeGeometry`,
:class:`~bedstruct.engines.RollerGeometry`) are described with their meshes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ._stl import BladeGeometry, RollerGeometry

__all__ = ["ReposeGeometry", "ReposeSchedule", "LayerSteps", "SpreadLayersPlan", "tool_top"]


@dataclass(frozen=True)
class ReposeGeometry:
    """The repose box (SI): ``[0, L] x [0, W] x [0, H]`` with a sliding plate.

    Parameters
    ----------
    length, width, height : float, m
        L, W, H of the box.
    periodic_width : bool
        y periodic over ``[0, W]`` (no y side plates).
    ledge_fraction : float
        Fixed ledge of ``ledge_fraction * L`` centred under the box (0: none).
    plate_speed : float, m/s
        Speed of the plate towards ``-x``.
    slide : float, m
        How far the plate slides.
    wall_thickness : float, m
        LAMMPS only: thickness of the block regions behind each wall face.

    Examples
    --------
    >>> g = ReposeGeometry(2.5e-3, 0.7e-3, 0.85e-3, periodic_width=True, ledge_fraction=0.6,
    ...                    plate_speed=0.5, slide=2.5e-3)
    >>> [round(v * 1e3, 3) for v in g.ledge]
    [0.5, 2.0]
    """

    length: float
    width: float
    height: float
    periodic_width: bool = True
    ledge_fraction: float = 0.0
    plate_speed: float = 0.05
    slide: float = 0.0
    wall_thickness: float = 1e-4

    def __post_init__(self):
        if not (self.length > 0 and self.width > 0 and self.height > 0):
            raise ValueError("`length`, `width` and `height` must be positive lengths (m)")
        if not 0 <= self.ledge_fraction < 1:
            raise ValueError(f"`ledge_fraction` must lie in [0, 1); got {self.ledge_fraction}")
        if not (self.plate_speed > 0 and self.slide >= 0 and self.wall_thickness > 0):
            raise ValueError("`plate_speed` and `wall_thickness` must be positive, `slide` >= 0")

    @property
    def ledge(self) -> tuple[float, float] | None:
        """x range of the ledge (m), or None."""
        if self.ledge_fraction <= 0:
            return None
        half = 0.5 * self.ledge_fraction * self.length
        return 0.5 * self.length - half, 0.5 * self.length + half


@dataclass(frozen=True)
class ReposeSchedule:
    """Steps of the three stages and the output interval.

    ``fill_steps`` settle the inserted spheres, ``slide_steps`` move the plate,
    ``drain_steps`` let the pile come to rest. ``every`` is the dump interval;
    :meth:`from_times` chooses it so that ``n_frames`` frames cover slide and
    drain and the last frame falls on the final step.

    Examples
    --------
    >>> s = ReposeSchedule.from_times(1e-6, fill=1e-4, slide=5e-5, drain=1e-4, n_frames=4)
    >>> (s.fill_steps + s.slide_steps + s.drain_steps) % s.every
    0
    """

    dt: float
    fill_steps: int
    slide_steps: int
    drain_steps: int
    every: int

    @classmethod
    def from_times(cls, dt: float, *, fill: float, slide: float, drain: float,
                   n_frames: int) -> "ReposeSchedule":
        if not (dt > 0 and math.isfinite(dt)):
            raise ValueError(f"`dt` must be a positive number of seconds; got {dt!r}")

        def steps(t):
            return max(1, int(math.ceil(t / dt - 1e-9)))
        f, s, d = steps(fill), steps(slide), steps(drain)
        every = max(1, int(math.ceil((s + d) / max(1, int(n_frames)))))
        total = f + s + d
        d += (-total) % every
        return cls(float(dt), f, s, d, every)


@dataclass(frozen=True)
class LayerSteps:
    """Global time steps of one layer's events in a :func:`spread_layers_deck` run.

    ``start``: the layer begins (before the platform is lowered); ``spread``:
    the tool starts moving (first frame); ``stop``: the tool stops; ``end``: the
    final frame of the layer (after settling).
    """

    start: int
    spread: int
    stop: int
    end: int


@dataclass(frozen=True)
class SpreadLayersPlan:
    """Everything :func:`spread_layers_deck` needs besides the data file (SI).

    Parameters
    ----------
    plate_length, width : float, m
        Platform length (x from 0) and y period (or distance between the side walls).
    gaps : tuple of float, m
        Layer thicknesses; before layer k the platform sits at ``-sum(gaps[:k+1])``
        below the tool's lowest point (z = 0).
    tool : BladeGeometry or RollerGeometry
        The tool at t = 0, its lowest point at z = 0.
    pile_ids : tuple of (int, int)
        Inclusive id range of the pile reinserted before each layer (one per gap).
    pile_parked_z : tuple of float, m
        z offset by which each pile was parked in the data file (0 for pile 1,
        which lies in place); ``displace_atoms`` moves pile k down by this much
        and up onto whatever lies in its footprint.
    pile_bottom : float, m
        Lowest sphere bottom of the pile as written for the first layer
        relative to its placement base (the pile's own z = 0).
    footprint : (float, float), m
        x range where the pile is placed (the highest sphere top there is its base).
    pile_lift : float, m
        Gap left between that base and the pile's z = 0.
    dt : float, s
    lower_speed, speed, return_speed : float, m/s
    settle_time : float, s
        Settling after the pile is placed and after the tool stops.
    clear : float, m
        How far the tool rises above the bed to return.
    x_end : float, m
        x of the tool's reference point (blade trailing face or roller axis)
        when it stops.
    chamber_depth : float, m
        Front wall at x = L from ``-chamber_depth`` up to 0 (0: none).
    n_frames : int
        Frames over the tool's travel.
    wall_thickness : float, m
        LAMMPS block regions' thickness.
    landing_intervals : int
        Before layers 2, 3...: at most this many intervals of ``settle_time`` are
        waited for spheres in flight over the footprint to land (0: never wait).
    landing_margin : float, m
        Spheres in flight count only when their top is more than this above the
        highest top of what rests in the footprint (the embedded run uses the
        largest radius).
    side_walls : bool
        Fixed plane walls at y = 0 and y = ``width`` (y not periodic; the data file's
        box must reach them) instead of a strip periodic over ``width``.
    """

    plate_length: float
    width: float
    gaps: tuple
    tool: object
    pile_ids: tuple
    pile_parked_z: tuple
    footprint: tuple
    dt: float
    lower_speed: float = 0.05
    speed: float = 0.1
    return_speed: float = 0.5
    settle_time: float = 0.005
    pile_lift: float = 0.0
    clear: float = 1e-4
    x_end: float = 0.0
    chamber_depth: float = 0.0
    n_frames: int = 8
    wall_thickness: float = 1e-4
    landing_intervals: int = 0
    landing_margin: float = 0.0
    side_walls: bool = False
    layers: tuple = field(default=(), init=False)
    every: int = field(default=0, init=False)

    def __post_init__(self):
        if not (self.dt > 0 and math.isfinite(self.dt)):
            raise ValueError(f"`dt` must be a positive number of seconds; got {self.dt!r}")
        n = len(self.gaps)
        if n < 1 or len(self.pile_ids) != n or len(self.pile_parked_z) != n:
            raise ValueError("`gaps`, `pile_ids` and `pile_parked_z` need one entry per layer")
        if not isinstance(self.tool, (BladeGeometry, RollerGeometry)):
            raise TypeError("`tool` must be a BladeGeometry or RollerGeometry")
        if int(self.landing_intervals) < 0 or not self.landing_margin >= 0:
            raise ValueError("`landing_intervals` and `landing_margin` must not be negative")
        spread = self._steps((self.x_end - self._tool_x()) / self.speed)
        every = max(1, int(math.ceil(spread / max(1, int(self.n_frames)))))
        s = 0
        layers = []
        for k in range(n):
            start = s
            s += self._lower_steps(k)
            s += self._steps(self.settle_time)
            s += (-s) % every                  # the first frame falls on a dump step
            end = s + spread + self._steps(self.settle_time)
            end += (-end) % every              # ... and so does the last
            layers.append(LayerSteps(start, s, s + spread, end))
            s = end + (self._return_steps() if k + 1 < n else 0)
        object.__setattr__(self, "layers", tuple(layers))
        object.__setattr__(self, "every", every)

    def _steps(self, t: float) -> int:
        return max(1, int(math.ceil(t / self.dt - 1e-9)))

    def _tool_x(self) -> float:
        return self.tool.x0

    def _lower_steps(self, k: int) -> int:
        """Lowering (platform, then settling) before layer k (none before layer 1)."""
        if k == 0:
            return 0
        g = float(self.gaps[k])
        return self._steps(g / self.lower_speed) + self._steps(
            min(self.settle_time, 2 * g / self.lower_speed))

    def _return_steps(self) -> int:
        return 2 * self._steps(self.clear / self.return_speed) + self._steps(
            self.travel / self.return_speed)

    @property
    def travel(self) -> float:
        """How far the tool moves in a layer (m): ``speed`` times the spreading steps."""
        return self.speed * self.dt * self._steps((self.x_end - self._tool_x()) / self.speed)

    @property
    def total_steps(self) -> int:
        """Steps of the whole run."""
        return self.layers[-1].end

    def shifted(self, offsets) -> tuple:
        """The layers' :class:`LayerSteps` of a run whose landing waits took ``offsets``.

        ``offsets[k]`` is the number of steps waited before layer ``k + 1``'s tool
        motion, in all (:func:`~bedstruct.engines.landing_offsets`); the layer's
        start shifts by the previous layer's offset.
        """
        off = [int(o) for o in offsets]
        if len(off) != len(self.layers) or any(b < a for a, b in zip(off, off[1:])) or (
                off and off[0] < 0):
            raise ValueError(f"need {len(self.layers)} non-decreasing offsets; got {offsets!r}")
        prev = [0] + off[:-1]
        return tuple(LayerSteps(ls.start + p, ls.spread + o, ls.stop + o, ls.end + o)
                     for ls, p, o in zip(self.layers, prev, off))


def tool_top(plan: SpreadLayersPlan) -> float:
    """Highest point of the tool at rest (m): parked piles must stay above it plus ``clear``."""
    t = plan.tool
    return t.top if isinstance(t, RollerGeometry) else t.z_bottom + t.height
