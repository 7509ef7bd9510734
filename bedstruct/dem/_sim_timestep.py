"""The time step of a :class:`~bedstruct.dem.Simulation`: its choice and its safety checks.

A mixin of :class:`~bedstruct.dem.Simulation` (like ``_sim_walls`` and
``_sim_particles``). Without a given ``dt`` the step is ``min(safety t_R, t_H / 10)``
(:meth:`_TimeStep.default_time_step`: the Rayleigh time of the smallest sphere and
the Hertz impact time at ``v_max``); a given step, or a ``safety`` above
``max_rayleigh_fraction``, beyond those limits raises
:class:`~bedstruct.UnsafeTimestepError` unless ``force=True``. The neighbour-list skin
is chosen with the step (0.15 of the smallest diameter unless given).
"""

from __future__ import annotations

import logging
import math

from ..errors import ConfigError, UnsafeTimestepError
from .params import ContactModel

log = logging.getLogger("bedstruct.dem.simulation")


class _TimeStep:
    """Time-step methods of :class:`~bedstruct.dem.Simulation` (see the module docstring)."""

    def rayleigh_time(self) -> float:
        """Rayleigh time (s) of the smallest particle (or ``min_radius``)."""
        return self.model.rayleigh_time(self._rmin())

    def _rmin(self) -> float:
        if self.min_radius is not None:
            return float(self.min_radius)
        if self.n_particles == 0:
            raise ConfigError("no particles: give `min_radius` or add particles before running")
        return float(self.rad.min())

    def _check_time_settings(self):
        """``safety``, ``max_rayleigh_fraction``, ``v_max``, ``min_radius`` and ``skin`` are
        usable (see the class)."""
        if self.min_radius is not None and not _finite_at_least(self.min_radius, 0.0, strict=True):
            raise ConfigError("`min_radius` (the smallest radius to plan the time step for) must "
                              f"be a positive radius in m; got {self.min_radius!r}")
        if self._skin_user is not None and not _finite_at_least(self._skin_user, 0.0):
            raise ConfigError("`skin` (the neighbour-list skin) must be a finite distance >= 0 "
                              f"in m; got {self._skin_user!r}")
        if not (math.isfinite(self.max_rayleigh_fraction) and self.max_rayleigh_fraction > 0):
            raise ConfigError("`max_rayleigh_fraction` must be a positive fraction of the "
                              f"Rayleigh time; got {self.max_rayleigh_fraction!r}")
        if not (math.isfinite(self.v_max) and self.v_max > 0):
            raise ConfigError("`v_max` (the largest expected impact speed, for the Hertz-time "
                              f"limit) must be a positive speed in m/s; got {self.v_max!r}")
        if not (math.isfinite(self.safety) and self.safety > 0):
            raise ConfigError("`safety` (the default time step as a fraction of the Rayleigh "
                              f"time) must be positive; got {self.safety!r}")
        if self.safety > self.max_rayleigh_fraction:
            msg = (f"unsafe time step: `safety` = {self.safety:g} would step at {self.safety:.0%} "
                   f"of the Rayleigh time; the stable limit is max_rayleigh_fraction = "
                   f"{self.max_rayleigh_fraction:g}. Use a smaller safety or force=True.")
            if not self.force:
                raise UnsafeTimestepError(msg)
            log.warning("%s (accepted because force=True)", msg)

    @staticmethod
    def default_time_step(model: ContactModel, min_radius: float, v_max: float,
                          safety: float = 0.15) -> float:
        """The time step a simulation chooses without ``dt``: ``min(safety t_R, t_H / 10)``.

        ``t_R`` is the Rayleigh time of a sphere of ``min_radius`` and ``t_H`` the
        Hertz impact time of two such spheres at ``v_max`` (s).

        Examples
        --------
        >>> from bedstruct.dem import ContactModel, Material, Simulation
        >>> model = ContactModel(Material(1e7, 0.3, 2500.0))
        >>> dt = Simulation.default_time_step(model, 1e-4, 1.0)
        >>> dt == min(0.15 * model.rayleigh_time(1e-4), 0.1 * model.hertz_time(1e-4, 1.0))
        True
        """
        if not (math.isfinite(float(v_max)) and float(v_max) > 0):
            raise ConfigError(f"`v_max` must be a positive speed in m/s; got {v_max!r}")
        if not (math.isfinite(float(safety)) and float(safety) > 0):
            raise ConfigError(f"`safety` must be positive; got {safety!r}")
        return min(float(safety) * model.rayleigh_time(min_radius),
                   0.1 * model.hertz_time(min_radius, v_max))

    def _choose_dt(self):
        rmin = self._rmin()
        t_r = self.model.rayleigh_time(rmin)
        t_h = self.model.hertz_time(rmin, self.v_max)
        if self._dt_user is None:
            dt = self.default_time_step(self.model, rmin, self.v_max, self.safety)
        else:
            dt = float(self._dt_user)
            if not dt > 0:
                raise ConfigError(f"`dt` must be positive; got {dt}")
            self._refuse_unsafe(self._step_limits(dt, rmin, "smallest sphere"),
                                "Use a smaller dt, a softer Young's modulus, or force=True.")
        self.dt = dt
        self._dt_radius = rmin
        if self._skin_user is not None:
            self.skin = float(self._skin_user)
        else:
            self.skin = 0.15 * 2.0 * rmin
        self.t_rayleigh = t_r
        self.t_hertz = t_h

    def _check_dt_present(self):
        """The step stays within its limits for the smallest sphere present.

        The step is planned at the first run for the smallest sphere then present (or
        ``min_radius``); a smaller sphere added later, or present below ``min_radius``, is
        checked against the same limits as a given ``dt`` (:meth:`_choose_dt`): beyond
        them :class:`~bedstruct.UnsafeTimestepError` unless ``force=True`` (then a warning,
        once per new smallest radius).
        """
        if self.n_particles == 0:
            return
        r = float(self.rad.min())
        planned = getattr(self, "_dt_radius", None)
        if planned is not None and r >= planned:
            return
        reasons = self._step_limits(self.dt, r, "smallest sphere present")
        if reasons and planned is not None:
            reasons[-1] += f" (the step was planned for r = {planned:.3g} m)"
        self._refuse_unsafe(reasons, "Give `min_radius` = the smallest radius the simulation "
                                     "will hold, a smaller dt, or force=True.")
        self._dt_radius = r

    def _check_wall_speed(self):
        """The step stays within a tenth of the Hertz impact time at the fastest wall's speed.

        ``v_max`` is the largest impact speed the step is planned for; a wall moving faster
        (its translation, or the bound of its program's ramp and vibration) hits spheres at
        its own speed. Where the step exceeds a tenth of the Hertz time of the smallest
        sphere present at that speed, :class:`~bedstruct.UnsafeTimestepError` unless
        ``force=True`` (then a warning, once per new top speed). Checked at each run start.
        """
        v = float(getattr(self, "_wall_speed", 0.0))
        if v <= self.v_max or self.n_particles == 0 or v <= getattr(self, "_wall_speed_ok", 0.0):
            return
        r = float(self.rad.min())
        t_h = self.model.hertz_time(r, v)
        if self.dt > 0.1 * t_h:
            self._refuse_unsafe(
                [f"a wall moves at {v:.3g} m/s, faster than v_max = {self.v_max:g} m/s: dt = "
                 f"{self.dt:.3g} s exceeds 10% of the Hertz impact time {t_h:.3g} s of the "
                 f"smallest sphere present (r = {r:.3g} m) at that speed"],
                "Give v_max >= the fastest wall speed (the step is then chosen for it), a "
                "smaller dt, or force=True.")
        self._wall_speed_ok = v

    def _step_limits(self, dt: float, r: float, which: str) -> list[str]:
        """Why ``dt`` is unsafe for spheres of radius ``r`` (empty when it is not): above
        ``max_rayleigh_fraction`` of their Rayleigh time, or a tenth of their Hertz impact
        time at ``v_max``."""
        t_r = self.model.rayleigh_time(r)
        t_h = self.model.hertz_time(r, self.v_max)
        reasons = []
        if dt > self.max_rayleigh_fraction * t_r:
            reasons.append(f"dt = {dt:.3g} s is {dt / t_r:.0%} of the Rayleigh time {t_r:.3g} s "
                           f"of the {which} (r = {r:.3g} m); the limit is "
                           f"{self.max_rayleigh_fraction:.0%}")
        if dt > 0.1 * t_h:
            reasons.append(f"dt = {dt:.3g} s exceeds 10% of the Hertz impact time {t_h:.3g} s of "
                           f"the {which} (r = {r:.3g} m) at v_max = {self.v_max} m/s (a "
                           f"collision would span fewer than 10 steps)")
        return reasons

    def _refuse_unsafe(self, reasons: list[str], advice: str) -> None:
        """:class:`~bedstruct.UnsafeTimestepError` for ``reasons``, or with ``force`` a
        warning."""
        if not reasons:
            return
        msg = "unsafe time step: " + "; ".join(reasons) + ". " + advice
        if not self.force:
            raise UnsafeTimestepError(msg)
        log.warning("%s (accepted because force=True)", msg)


def _finite_at_least(value, lo: float, strict: bool = False) -> bool:
    """True when ``value`` is a real number, finite and ``>= lo`` (``> lo`` if ``strict``)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        return False
    return math.isfinite(v) and (v > lo if strict else v >= lo)
