"""Wall control of a :class:`~bedstruct.dem.Simulation`: motion, programs, loads.

The :class:`_WallControl` mixin holds the public wall methods of
:class:`~bedstruct.dem.Simulation` (:meth:`set_wall_motion`,
:meth:`set_wall_program`, :meth:`wall_states`). Walls are rows of the table
``self._W`` (see :mod:`bedstruct.dem.walls`); a row stores the origin at the
reference time ``W[13]`` and the translation velocity, so the kernels place
the wall at any time without Python work each step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from . import _kernels as K

__all__ = ["WallState"]

_WALL_SLOTS = 3  # wall-contact history slots per particle


def _program_rows(programs) -> np.ndarray:
    """``(wall index, program)`` pairs as rows of the kernels' wall-program table."""
    return np.array([[w, p["t0"], *p["origin"], *p["velocity"], p["ramp_time"], p["amplitude"],
                      p["frequency"], *p["direction"]] for w, p in programs],
                    dtype=np.float64).reshape(-1, K.PROGRAM_NCOL)


@dataclass(frozen=True)
class WallState:
    """Position and load of one wall at the current time.

    ``origin`` (m) is the wall's reference point (plane point, plate or
    prism origin, roller axis point), ``velocity`` (m/s), ``force`` (N) the
    total force the particles exert on the wall, ``n_contacts`` the number
    of particles touching it.
    """

    name: str
    origin: np.ndarray
    velocity: np.ndarray
    force: np.ndarray
    n_contacts: int


def _vec3(name, v):
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ConfigError(f"`{name}` must be a finite 3-vector; got {v!r}")
    return a


class _WallControl:
    """Wall motion, wall programs and wall loads (mixed into Simulation)."""

    def set_wall_motion(self, name: str, *, velocity=None, omega=None) -> None:
        """Change a wall's translation velocity (m/s) or a roller's spin (rad/s) from now on."""
        try:
            w = self.wall_names.index(name)
        except ValueError:
            raise ConfigError(f"no wall named {name!r}; walls: {self.wall_names}") from None
        self._programs.pop(name, None)
        row = self._W[w]
        dt0 = self.time - row[13]
        row[1:4] = row[1:4] + row[10:13] * dt0
        row[13] = self.time
        if velocity is not None:
            row[10:13] = _vec3("velocity", velocity)
        if omega is not None:
            if int(row[0]) != K.WALL_CYLINDER:
                raise ConfigError(f"wall {name!r} is not a Cylinder; only rollers spin")
            row[16] = float(omega)
        if self._ready:
            self._build_wall_list()

    def set_wall_program(self, name: str, *, velocity, ramp_time: float = 0.0,
                         vibration_amplitude: float = 0.0, vibration_frequency: float = 0.0,
                         vibration_direction=(0.0, 0.0, 1.0)) -> None:
        """Prescribe a wall's translation from now on: start-up ramp plus vibration.

        With ``s`` the time since this call, ``tau`` the ramp time, ``A`` the
        amplitude, ``f`` the frequency and **d** the unit vibration direction::

            x(s) = x(0) + v [s - tau (1 - exp(-s/tau))] + A sin(2 pi f s) d
            u(s) = v (1 - exp(-s/tau)) + 2 pi f A cos(2 pi f s) d

        (``tau = 0``: ``x = x(0) + v s``). The wall row is updated every step
        (position and velocity exact at the time the walls are evaluated).
        :meth:`set_wall_motion` on the same wall ends the program.

        Parameters
        ----------
        name : str
            Wall name.
        velocity : (3,) float, m/s
            Steady translation velocity v.
        ramp_time : float, s
            Start-up time constant tau (>= 0).
        vibration_amplitude : float, m
            Vibration amplitude A (>= 0).
        vibration_frequency : float, Hz
            Vibration frequency f (>= 0).
        vibration_direction : (3,) float
            Direction of the vibration (normalised here).
        """
        try:
            w = self.wall_names.index(name)
        except ValueError:
            raise ConfigError(f"no wall named {name!r}; walls: {self.wall_names}") from None
        for key, val in (("ramp_time", ramp_time), ("vibration_amplitude", vibration_amplitude),
                         ("vibration_frequency", vibration_frequency)):
            if not (math.isfinite(float(val)) and float(val) >= 0.0):
                raise ConfigError(f"`{key}` must be a number >= 0; got {val!r}")
        d = _vec3("vibration_direction", vibration_direction)
        nd = float(np.linalg.norm(d))
        if nd == 0.0:
            raise ConfigError("`vibration_direction` must be a non-zero vector")
        row = self._W[w]
        origin = row[1:4] + row[10:13] * (self.time - row[13])
        self._programs[name] = dict(t0=float(self.time), origin=origin.tolist(),
                                    velocity=_vec3("velocity", velocity).tolist(),
                                    ramp_time=float(ramp_time),
                                    amplitude=float(vibration_amplitude),
                                    frequency=float(vibration_frequency),
                                    direction=(d / nd).tolist())
        self._apply_programs(self.time)
        if self._ready:
            self._build_wall_list()

    @staticmethod
    def wall_program_state(program: dict, time: float):
        """Position and velocity of a programmed wall at ``time`` (see :meth:`set_wall_program`)."""
        W = np.zeros((1, K.WALL_NCOL))
        K.apply_wall_programs(_program_rows([(0, program)]), W, float(time))
        return W[0, 1:4].copy(), W[0, 10:13].copy()

    def _program_table(self) -> np.ndarray:
        """The wall programs as the kernels' table (``PROGRAM_NCOL`` columns, a row each)."""
        return _program_rows([(self.wall_names.index(name), prog)
                              for name, prog in self._programs.items()])

    def _apply_programs(self, time):
        if self._programs:
            K.apply_wall_programs(self._program_table(), self._W, time)

    def start_wall_load_average(self) -> None:
        """Average the particles' load on every wall over the steps that follow.

        A single frame's wall force is one instant of a fluctuating granular load
        (contacts open and close every few steps); a recoater's load cell reports
        its time average. :meth:`wall_load_average` gives the mean over every step
        run since this call.
        """
        self._wload = np.zeros((len(self.wall_names), 3))
        self._wload_steps = 0

    def _accumulate_wall_loads(self) -> None:
        wb = getattr(self, "_wbuf", None)
        if wb is not None and wb.shape[1] == len(self.wall_names):
            K.add_wall_loads(wb, self._wload)
        self._wload_steps += 1

    def wall_load_average(self, *, stop: bool = True) -> dict[str, np.ndarray]:
        """Mean force (N) the particles exerted on each wall per step since
        :meth:`start_wall_load_average`, by wall name; ``stop`` ends the averaging.

        Raises
        ------
        RuntimeError
            When no averaging was started, or no step has run since.

        Examples
        --------
        >>> from bedstruct import Box
        >>> from bedstruct.dem import ContactModel, Material, Plane, Simulation
        >>> sim = Simulation(Box([0, 0, 0], [1e-3, 1e-3, 1e-3], boundary="pp pp ff"),
        ...                  ContactModel(Material(1e7, 0.3, 2500.0), restitution=0.5),
        ...                  walls=[Plane((0, 0, 0), (0, 0, 1), name="floor")], n_threads=1)
        >>> sim.add_particles([[5e-4, 5e-4, 1e-4]], [1e-4])
        >>> sim.run(time=0.02)  # doctest: +ELLIPSIS
        RunStats(...)
        >>> sim.start_wall_load_average()
        >>> _ = sim.run(time=0.01)
        >>> weight = 2500.0 * 4 / 3 * np.pi * 1e-4 ** 3 * 9.81
        >>> round(float(sim.wall_load_average()["floor"][2] / -weight), 3)  # it rests on the floor
        1.0
        """
        if self._wload is None:
            raise RuntimeError("wall_load_average: call start_wall_load_average() first")
        if self._wload_steps == 0:
            raise RuntimeError("wall_load_average: no step has run since "
                               "start_wall_load_average()")
        mean = self._wload / self._wload_steps
        if stop:
            self._wload = None
        return {name: mean[w].copy() for w, name in enumerate(self.wall_names)}

    def wall_states(self) -> list[WallState]:
        """Position, velocity and particle load of every wall now."""
        out = []
        wb = getattr(self, "_wbuf", None)
        for w, name in enumerate(self.wall_names):
            row = self._W[w]
            origin = row[1:4] + row[10:13] * (self.time - row[13])
            if wb is not None and wb.shape[1] == len(self.wall_names):
                tot = wb[:, w, :].sum(axis=0)
            else:
                tot = np.zeros(6)
            out.append(WallState(name, origin, row[10:13].copy(), tot[:3].copy(), int(tot[4])))
        return out
