"""
A node clock's time and sleep without rclpy's ``Time`` objects (100 times a second in a node).

``Clock.now()`` builds a ``Time`` (a Python object with its checks) each call, about 15 us of CPU
on a loaded machine; a ROS clock that is not on sim time reads the system clock, which
``time.time_ns()`` reads for a fraction of that. On sim time (``use_sim_time``, /clock), or any
other clock, it is ``clock.now()``.

``Clock.sleep_until`` creates a jump callback, a ``ClockEvent``, a shutdown callback on the
context and ``Time`` objects per call: measured on the loaded 2-core machine, 160 us of CPU per
1 ms sleep against 60 us for ``time.sleep`` (the controller's tick sleeps 100 times a second).
``sleep_until_ns`` sleeps with ``time.sleep`` instead while the clock reads the system clock,
at most ``MAX_NAP`` at a time so that a shutdown is seen; on sim time it is
``Clock.sleep_until``.
"""

import time

from rclpy.clock import Clock, ClockType
from rclpy.context import Context
from rclpy.time import Time

MAX_NAP = 0.1                # [s] longest sleep between looks at the context and the clock


def on_system_time(clock: Clock) -> bool:
    """Return True when ``clock`` reads the system clock now (a ROS clock off sim time)."""
    kind = clock.clock_type
    return kind == ClockType.SYSTEM_TIME or (kind == ClockType.ROS_TIME
                                             and not clock.ros_time_is_active)


def now_ns(clock: Clock) -> int:
    """Return ``clock``'s time [ns] (the same as ``clock.now().nanoseconds``)."""
    if clock.clock_type == ClockType.ROS_TIME and not clock.ros_time_is_active:
        return time.time_ns()
    return clock.now().nanoseconds


def sleep_until_ns(clock: Clock, deadline: int, context: Context) -> bool:
    """
    Sleep until ``clock`` reads ``deadline`` [ns]; return whether it did (``Clock.sleep_until``).

    False, as ``Clock.sleep_until`` returns it, when the wait ended for another reason: the
    context shut down, or the clock changed between system and sim time. On the system clock
    both are seen within ``MAX_NAP`` (a sleep until the next tick is one nap at 100 Hz); a ROS
    clock on sim time sleeps in ``Clock.sleep_until``, unless the deadline has passed already
    (``Clock.sleep_until`` would wait for the next /clock even then).
    """
    if not on_system_time(clock):
        if not context.ok():
            return False
        if clock.now().nanoseconds >= deadline:     # Clock.sleep_until waits for a /clock
            return True
        return clock.sleep_until(Time(nanoseconds=deadline, clock_type=clock.clock_type),
                                 context)
    while True:
        left = deadline - time.time_ns()
        if left <= 0:
            return True
        time.sleep(min(left * 1e-9, MAX_NAP))
        if not (context.ok() and on_system_time(clock)):
            return False
