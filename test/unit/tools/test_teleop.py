"""The keyboard teleop's key handling, through a pseudo-terminal (no ROS)."""

import os
import pty
import termios
import threading
import time

from mover6_control.tools.teleop import (FIRST_HOLD, HOLD, loop, MAX_JOINT, MAX_LINEAR,
                                         SPEED_STEPS, Teleop)
import pytest


class Terminal:
    """A pseudo-terminal with the teleop loop reading its slave side in a thread."""

    def __init__(self, publish=None):
        self.master, self.slave = pty.openpty()
        self.saved = termios.tcgetattr(self.slave)
        self.sent = []              # (time, command)
        self.lines = []
        self.teleop = Teleop()
        self.error = None
        self.code = None
        self.publish = publish or (lambda command: self.sent.append((time.monotonic(), command)))
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()
        time.sleep(0.1)

    def run(self):
        try:
            self.code = loop(self.slave, self.teleop, self.publish, self.lines.append,
                             lambda: 'idle: ok')
        except Exception as err:  # noqa: B902 - the test reads it
            self.error = err

    def keys(self, keys, every=0.0):
        for key in keys:
            os.write(self.master, key.encode())
            if every:
                time.sleep(every)

    def hold(self, key, seconds, every=0.03):
        """Repeat ``key`` every ``every`` s for ``seconds``, as a terminal's autorepeat."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.keys(key)
            time.sleep(every)
        return time.monotonic()

    def close(self):
        self.thread.join(timeout=5.0)
        os.close(self.master)
        os.close(self.slave)


@pytest.fixture
def terminal():
    term = Terminal()
    yield term
    if term.thread.is_alive():
        term.keys('x')
    term.close()


def test_publishes_while_held_and_nothing_otherwise(terminal):
    """A held key publishes at a steady rate, until shortly after its last repeat."""
    time.sleep(0.3)
    assert terminal.sent == []                              # nothing without a key
    start = time.monotonic()
    last = terminal.hold('w', 1.0)
    time.sleep(0.5)
    times = [t for t, _ in terminal.sent]
    assert times and times[0] - start < 0.1
    assert last < times[-1] < last + HOLD + 0.1             # released: stops within the hold
    gaps = [b - a for a, b in zip(times, times[1:])]
    assert max(gaps) < 0.1 and 30 < len(times) < 80         # ~50 Hz while held
    kind, linear, angular, frame = terminal.sent[0][1]
    assert kind == 'twist' and frame == 'base_link'
    assert linear == [MAX_LINEAR * SPEED_STEPS[1], 0.0, 0.0] and angular == [0.0] * 3
    assert any('held w' in line for line in terminal.lines)
    assert terminal.lines[-1].endswith('idle: ok')


def test_a_single_press_lasts_the_first_hold_then_stops(terminal):
    """One key press (no repeat yet) moves for the first hold only."""
    t0 = time.monotonic()
    terminal.keys('r')
    time.sleep(FIRST_HOLD + 0.4)
    times = [t for t, _ in terminal.sent]
    assert times and times[-1] - t0 < FIRST_HOLD + 0.1
    assert terminal.sent[-1][1][1] == [0.0, 0.0, MAX_LINEAR * SPEED_STEPS[1]]


def test_frame_speed_rotation_and_stop_keys(terminal):
    """t: tool frame; +: faster; o: yaw; space: one zero twist, keys released."""
    terminal.keys('t+', every=0.05)
    terminal.hold('o', 0.3)
    command = terminal.sent[-1][1]
    assert command == ('twist', [0.0] * 3, [0.0, 0.0, 0.4 * SPEED_STEPS[2]], 'link6')
    terminal.keys(' ')
    time.sleep(0.2)
    assert terminal.sent[-1][1] == ('twist', [0.0] * 3, [0.0] * 3, 'link6')
    count = len(terminal.sent)
    time.sleep(0.3)
    assert len(terminal.sent) == count                      # nothing after the stop


def test_joint_mode(terminal):
    """The m key: joint mode; a digit picks the joint; s jogs it negative."""
    terminal.keys('m3', every=0.05)
    terminal.hold('s', 0.3)
    assert terminal.sent[-1][1] == ('joint', ['joint3'], [-MAX_JOINT * SPEED_STEPS[1]])
    assert any('joint mode, joint3' in line for line in terminal.lines)


def test_quit_restores_the_terminal(terminal):
    """The x key ends the loop with code 0 and the terminal settings back as they were."""
    during = termios.tcgetattr(terminal.slave)
    assert during[3] & termios.ECHO == 0 and during[3] & termios.ICANON == 0
    terminal.keys('x')
    terminal.thread.join(timeout=5.0)
    assert terminal.code == 0 and terminal.error is None
    assert termios.tcgetattr(terminal.slave) == terminal.saved


def test_an_exception_restores_the_terminal_too():
    """A failing publisher ends the loop with its exception; the terminal is restored."""
    def publish(command):
        raise RuntimeError('publisher gone')

    term = Terminal(publish)
    try:
        term.keys('w')
        term.thread.join(timeout=5.0)
        assert isinstance(term.error, RuntimeError)
        assert termios.tcgetattr(term.slave) == term.saved
    finally:
        term.close()


def test_key_handling_without_a_terminal():
    """The same rules on synthetic time: held after a repeat, released after the hold."""
    teleop = Teleop(hold=0.15, first_hold=0.6)
    assert teleop.command(0.0) is None
    teleop.on_key('a', 0.0)
    assert teleop.command(0.5)[1] == [0.0, MAX_LINEAR * SPEED_STEPS[1], 0.0]
    assert teleop.command(0.61) is None
    teleop.on_key('a', 1.0)
    teleop.on_key('a', 1.1)             # a repeat: held for 0.15 s from here
    assert teleop.command(1.2) is not None and teleop.command(1.26) is None
    for _ in range(10):
        teleop.on_key('-', 2.0)
    assert teleop.speed == 0
    assert teleop.on_key('q', 2.0) is False
