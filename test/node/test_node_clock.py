"""The node clock's time and sleep (``nodes/runtime/node_clock.py``): system clock, sim time."""

import threading
import time
import types

from mover6_control.nodes.runtime import node_clock
import pytest
import rclpy
from rclpy.clock import ClockType, ROSClock
from rclpy.time import Time

MS = 1_000_000    # [ns]


@pytest.fixture
def context():
    """Yield an initialised rclpy context of its own; shut down after the test (if not yet)."""
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    yield ctx
    rclpy.try_shutdown(context=ctx)


@pytest.fixture
def napping(monkeypatch):
    """Return an event set once ``sleep_until_ns`` sleeps on the system clock (time.sleep)."""
    event = threading.Event()

    def sleep(seconds):
        event.set()
        time.sleep(seconds)
    monkeypatch.setattr(node_clock, 'time', types.SimpleNamespace(time_ns=time.time_ns,
                                                                  sleep=sleep))
    return event


def sleep_in_thread(clock, deadline, ctx):
    """Start ``sleep_until_ns`` in a thread; return it and its [(result, clock [ns] after)]."""
    out = []

    def sleep():
        done = node_clock.sleep_until_ns(clock, deadline, ctx)
        out.append((done, node_clock.now_ns(clock)))
    thread = threading.Thread(target=sleep, daemon=True)
    thread.start()
    return thread, out


def test_system_time_sleeps_to_the_deadline(context):
    """Off sim time: True, and the system clock has reached the deadline."""
    clock = ROSClock()
    deadline = node_clock.now_ns(clock) + 20 * MS
    assert node_clock.sleep_until_ns(clock, deadline, context)
    assert time.time_ns() >= deadline
    assert node_clock.sleep_until_ns(clock, deadline - 5 * MS, context)   # past: at once


def test_shutdown_ends_a_system_time_sleep(context, napping):
    """A shutdown during a long sleep: False within a nap, as Clock.sleep_until returns it."""
    clock = ROSClock()
    thread, result = sleep_in_thread(clock, node_clock.now_ns(clock) + 60_000 * MS, context)
    assert napping.wait(10.0)
    rclpy.shutdown(context=context)
    thread.join(timeout=10 * node_clock.MAX_NAP)
    assert not thread.is_alive()
    assert [done for done, _ in result] == [False]


def test_a_switch_to_sim_time_ends_a_system_time_sleep(context, napping):
    """use_sim_time switched on during a sleep on the system clock: False (the epoch changed)."""
    clock = ROSClock()
    thread, result = sleep_in_thread(clock, node_clock.now_ns(clock) + 60_000 * MS, context)
    assert napping.wait(10.0)
    clock._set_ros_time_is_active(True)           # what TimeSource does for use_sim_time
    thread.join(timeout=10 * node_clock.MAX_NAP)
    assert not thread.is_alive()
    assert [done for done, _ in result] == [False]


def test_sim_time_sleeps_until_the_clock_gets_there(context):
    """On sim time the sleep waits for the sim clock (Clock.sleep_until), not the wall clock."""
    clock = ROSClock()
    clock._set_ros_time_is_active(True)
    clock.set_ros_time_override(Time(seconds=5, clock_type=ClockType.ROS_TIME))
    assert node_clock.now_ns(clock) == 5_000 * MS
    assert node_clock.sleep_until_ns(clock, 4_000 * MS, context)     # past: at once
    thread, result = sleep_in_thread(clock, 5_010 * MS, context)
    end, now = time.monotonic() + 10.0, 5_010 * MS
    while thread.is_alive() and time.monotonic() < end:
        # As /clock does: on and on (a sleep wakes on a time jump after it began)
        clock.set_ros_time_override(Time(nanoseconds=now, clock_type=ClockType.ROS_TIME))
        now += 1
        thread.join(timeout=0.01)
    assert not thread.is_alive()
    (done, woke_at), = result
    assert done and woke_at >= 5_010 * MS     # it woke for the sim clock, not the wall clock
