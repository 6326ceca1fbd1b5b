"""
The keyboard teleop's key handling (no ROS): its loop on synthetic time, and on a pseudo-terminal.

The loop's timing (the rate while a key is held, the hold after the last repeat) runs on a
synthetic clock: ``read_keys`` is replaced by the keys of a schedule, each read at its time, so
the figures are counts of commands per synthetic second, never the wall clock's. The terminal's
own handling (raw mode, restored on quit and on an exception) runs on a real pseudo-terminal.
"""

import os
import pty
import termios
import threading
import time

from mover6_control.tools import teleop as teleop_module
from mover6_control.tools.teleop import (FIRST_HOLD, HOLD, loop, MAX_JOINT, MAX_LINEAR, RATE,
                                         SPEED_STEPS, Teleop)
import pytest

PERIOD = 1.0 / RATE


class Terminal:
    """A pseudo-terminal with the teleop loop reading its slave side in a thread."""

    def __init__(self, publish=None):
        self.master, self.slave = pty.openpty()
        self.saved = termios.tcgetattr(self.slave)
        self.sent = []
        self.lines = []
        self.teleop = Teleop()
        self.error = None
        self.code = None
        self.publish = publish or self.sent.append
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()
        deadline = time.monotonic() + 10.0      # the loop runs once it shows its status line
        while not self.lines and self.error is None and time.monotonic() < deadline:
            time.sleep(0.005)
        assert self.lines, self.error

    def run(self):
        try:
            self.code = loop(self.slave, self.teleop, self.publish, self.lines.append,
                             lambda: 'idle: ok')
        except Exception as err:  # noqa: B902 - the test reads it
            self.error = err

    def keys(self, keys):
        for key in keys:
            os.write(self.master, key.encode())

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


def run_loop(monkeypatch, schedule, end):
    """
    Run ``loop`` on synthetic time with the keys of ``schedule`` ([(time [s], key)]) until ``end``.

    Return ``(sent, lines)``: ``[(time, command)]`` published and the status lines shown.
    """
    keys = sorted(schedule, key=lambda item: item[0]) + [(end, 'x')]
    now = [0.0]

    def read_keys(fd, timeout):         # the next key if it comes within the timeout
        if keys[0][0] <= now[0] + max(timeout, 0.0):
            now[0] = max(now[0], keys[0][0])
            return keys.pop(0)[1]
        now[0] += max(timeout, 0.0)
        return ''
    monkeypatch.setattr(teleop_module, 'read_keys', read_keys)
    sent, lines = [], []
    fd = os.open(os.devnull, os.O_RDONLY)       # not a terminal: no raw mode to set
    try:
        code = loop(fd, Teleop(), lambda command: sent.append((now[0], command)),
                    lines.append, lambda: 'idle: ok', clock=lambda: now[0])
    finally:
        os.close(fd)
    assert code == 0
    return sent, lines


def repeat(key, start, stop, every=0.03):
    """Return a key's autorepeat: ``key`` every ``every`` s from ``start`` until ``stop``."""
    count = int(round((stop - start) / every))
    return [(start + i * every, key) for i in range(count + 1)]


def test_publishes_while_held_and_nothing_otherwise(monkeypatch):
    """A held key publishes at the rate, until the hold after its last repeat; nothing else."""
    held = repeat('w', 0.3, 1.3)
    sent, lines = run_loop(monkeypatch, held, 2.0)
    times = [t for t, _ in sent]
    last = held[-1][0]
    assert times[0] - held[0][0] <= PERIOD + 1e-9          # at once, not before
    assert last < times[-1] <= last + HOLD + 1e-9          # released: stops within the hold
    gaps = [b - a for a, b in zip(times, times[1:])]
    assert max(gaps) <= PERIOD + 1e-9 and min(gaps) >= PERIOD - 1e-9   # RATE while held
    assert len(sent) == pytest.approx((last + HOLD - held[0][0]) * RATE, abs=2)
    kind, linear, angular, frame = sent[0][1]
    assert kind == 'twist' and frame == 'base_link'
    assert linear == [MAX_LINEAR * SPEED_STEPS[1], 0.0, 0.0] and angular == [0.0] * 3
    assert any('held w' in line for line in lines)
    assert lines[-1].endswith('idle: ok')


def test_a_single_press_lasts_the_first_hold_then_stops(monkeypatch):
    """One key press (no repeat yet) moves for the first hold only."""
    sent, _ = run_loop(monkeypatch, [(0.2, 'r')], 2.0)
    times = [t for t, _ in sent]
    assert times and 0.2 <= times[0] and times[-1] <= 0.2 + FIRST_HOLD + 1e-9
    assert len(sent) == pytest.approx(FIRST_HOLD * RATE, abs=2)
    assert sent[-1][1][1] == [0.0, 0.0, MAX_LINEAR * SPEED_STEPS[1]]


def test_frame_speed_rotation_and_stop_keys(monkeypatch):
    """t: tool frame; +: faster; o: yaw; space: one zero twist, keys released, then nothing."""
    schedule = [(0.1, 't'), (0.15, '+')] + repeat('o', 0.2, 0.5) + [(0.52, ' ')]
    sent, _ = run_loop(monkeypatch, schedule, 2.0)
    yaw = [command for t, command in sent if t < 0.52]
    assert yaw[-1] == ('twist', [0.0] * 3, [0.0, 0.0, 0.4 * SPEED_STEPS[2]], 'link6')
    assert sent[-1][1] == ('twist', [0.0] * 3, [0.0] * 3, 'link6')
    assert [t for t, _ in sent if t >= 0.52] == [sent[-1][0]]   # one zero twist, no more


def test_joint_mode(monkeypatch):
    """The m key: joint mode; a digit picks the joint; s jogs it negative."""
    sent, lines = run_loop(monkeypatch, [(0.1, 'm'), (0.15, '3')] + repeat('s', 0.2, 0.5), 1.0)
    assert sent[-1][1] == ('joint', ['joint3'], [-MAX_JOINT * SPEED_STEPS[1]])
    assert any('joint mode, joint3' in line for line in lines)


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
