"""
The compensation of a driver with a cycle: whole-tick pulses and the motion still in flight.

``jog_units`` 'fraction_of_max' (the Mover6's vendor driver): the driver moves each joint by
whole encoder ticks per cycle (``driver_tick_size``, ``driver_cycle``), so a joint commanded
under one tick per cycle does not move at all (J5/J6: about 7 deg/s), and its position is only
known to a tick. Three things make the arm arrive anyway (``DriverCompensation``, used by
``controller_core.ControllerCore`` for 'fraction_of_max' and for a ``cycle_driver``, whose
readings are whole ticks too and which integrates a command held over one cycle boundary into
exactly that many ticks, since it keeps a resting set-point on the whole tick it sends):

- dead-zone compensation (``commands.dead_zone_command``): a joint whose command is below
  ``min_jog_speed`` gets exactly that speed towards its error while the error exceeds half a
  tick, zero inside. Its readings lag the driver by ``reading_lag`` cycles (the vendor's: two;
  a ``cycle_driver``: three, as it reads each reply at the cycle after the set-point it
  answers), so such a joint moves in pulses: one driver cycle long (one tick), started on a
  fresh reading, then no new pulse until a reading that shows the pulse (``reading_lag``
  readings later; one more after the law itself moved the joint). It never overshoots by what
  is still in flight, so it settles instead of oscillating.
- the goal tolerance of each joint is ``max(goal_tolerance, one tick)`` (reported in the
  status as ``goal_tolerance``), and the arm has arrived only when both the reading and the
  reading minus what was commanded since (from ``reading_lag`` cycles before it came: maybe in
  flight) are
  within it, so a joint still moving does not arrive on a stale reading and then drift out.
- after arrival (settling to one tick) each joint more than half a tick off gets one pulse of
  the whole number of ticks nearest its error (``commands.tick_pulse_command``: the
  driver truncates the speed to exactly that), then none until a reading shows it landed
  (``reading_lag`` + 1 readings later); so
  every joint ends on the tick nearest its goal (a closed loop on the lagging readings crept:
  4-10 ticks off a second after arrival).

This assumes the readings come once per driver cycle (or less often) and that two and a half
control periods plus the delays of a reading and of a command stay under one driver cycle (at
100 Hz and 20 Hz: delays under 12 ms each). Beyond that (a reading 40 ms late) a pulse may
move two ticks, a wrist goal between two ticks may not settle, and the motion then ends
'aborted' after ``settle_timeout`` rather than 'arrived' out of tolerance.
"""

from __future__ import annotations

from collections import deque

from mover6_control.control.commands import dead_zone_command, tick_pulse_command
from mover6_control.control.controller_config import DerivedConfig
from mover6_control.control.robot import Robot
import numpy as np


class DriverCompensation:
    """
    The pulses and the log of commands sent, for a driver with a cycle (module docstring).

    Every tick ends with ``end_tick`` (what was sent, and which reading it was sent on); the
    pulse commands (``whole_ticks``, ``tick_pulses``) and ``in_flight`` read from that.
    """

    def __init__(self, n: int):
        """Start with no pulse and nothing sent, for ``n`` joints."""
        self.n_states_seen = 0           # the robot's n_states as of the previous tick
        self._pulse_until = np.full(n, -np.inf)  # [s] end of each joint's one-tick pulse
        self._pulse_after = np.zeros(n, dtype=int)  # no new pulse before this many readings
        self._pulse_speed = np.zeros(n)  # [rad/s] the command of each joint's running pulse
        self._travel = np.zeros(n)       # [rad] integral of the commands sent
        self._travel_log = deque(maxlen=1)
        self.active = False
        self._min_speed = None
        self._cycle = self._dt = 0.0
        self._lag = 0                    # driver cycles until a move shows in the readings

    def configure(self, derived: DerivedConfig) -> None:
        """Take the driver's cycle, ticks and control period of ``derived`` (the log stays)."""
        self.active = derived.whole_tick_driver
        self._min_speed = derived.min_speed
        self._cycle, self._dt = derived.config.driver_cycle, derived.dt
        self._lag = derived.reading_lag
        self._travel_log = deque(self._travel_log, maxlen=derived.log_length)

    def end_tick(self, now: float, qd: np.ndarray, n_states: int) -> None:
        """Note the command ``qd`` (n,) [rad/s] sent at ``now`` [s] on reading ``n_states``."""
        self.n_states_seen = n_states
        if self.active:
            self._travel_log.append((now, self._travel.copy()))
            self._travel = self._travel + qd * self._dt

    def whole_ticks(self, now: float, qd: np.ndarray, robot: Robot) -> np.ndarray:
        """
        Return the command with the dead zone of a whole-tick driver compensated (pulses).

        A pulse starts on the first tick after a fresh reading, lasts one driver cycle (plus
        half a control period, so it surely spans one cycle boundary and not two) and moves its
        joint one tick; the next may start only on a reading that shows it.
        """
        pulsing = now < self._pulse_until
        fresh = robot.n_states > self.n_states_seen
        may_start = fresh & (robot.n_states >= self._pulse_after)
        qd, dead = dead_zone_command(qd, robot.error, robot.encoder_ticks,
                                     self._min_speed, pulsing | may_start)
        started = dead & ~pulsing & may_start & (qd != 0.0)
        self._pulse_speed[started] = qd[started]
        self._pulse_until[started] = now + self._cycle + 0.5 * self._dt
        self._pulse_after[started] = robot.n_states + self._lag
        law = ~dead & (qd != 0.0)          # moved by the law: in flight one reading longer
        self._pulse_until[law] = -np.inf
        self._pulse_after[law] = robot.n_states + self._lag + 1
        return qd

    def in_flight(self, t_states: float) -> np.ndarray:
        """
        Return the motion (n,) [rad] commanded that the reading at ``t_states`` cannot show yet.

        The vendor's driver applies the command it holds at its cycle and the reading of that
        cycle is taken before the move, so what was commanded from one cycle before that cycle
        may still be on its way; counting from ``reading_lag`` cycles before the reading came
        (two; three for a ``cycle_driver``, whose reading of a cycle is the reply to the
        set-point of the cycle before) also covers delays of up to a cycle (erring towards 'in
        flight' only delays the arrival).
        """
        since = t_states - self._lag * self._cycle
        start = self._travel
        for t, travel in reversed(self._travel_log):
            start = travel
            if t <= since:
                break
        return self._travel - start

    def tick_pulses(self, now: float, robot: Robot, vlim: np.ndarray) -> np.ndarray:
        """
        Return the command that moves each joint onto the tick nearest its goal (n,) [rad/s].

        The readings lag the driver by ``reading_lag`` cycles, so a closed loop on them either
        creeps (a low gain: 4-10 ticks off a second after arrival) or oscillates. The driver is
        exact instead: a command held over one cycle boundary moves ``trunc(speed * cycle /
        tick)`` ticks (a ``cycle_driver``: that many and the margin's fraction, which it rounds
        away as it sends whole ticks). So a joint whose reading is more than half a tick off
        gets one pulse of the whole number of ticks nearest its error
        (``commands.tick_pulse_command``), lasting one driver cycle (as ``whole_ticks``), and no
        new one until a reading shows it landed (``reading_lag`` + 1 readings later; the law's
        last moves too). Each pulse closes the error to the nearest tick, up to the servo's lag
        in the reading it was computed from.
        """
        ticks, cycle = robot.encoder_ticks, self._cycle
        error = robot.error
        pulsing = now < self._pulse_until
        fresh = robot.n_states > self.n_states_seen
        start = (fresh & ~pulsing & (robot.n_states >= self._pulse_after)
                 & (np.abs(error) > 0.5 * ticks))
        speed = tick_pulse_command(error, ticks, cycle, vlim)
        self._pulse_speed[start] = speed[start]
        self._pulse_until[start] = now + cycle + 0.5 * self._dt
        self._pulse_after[start] = robot.n_states + self._lag + 1
        return np.where(pulsing | start, self._pulse_speed, 0.0)
