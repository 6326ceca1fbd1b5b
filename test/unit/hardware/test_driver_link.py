"""
The driver's link to the adapter (``LinkWatch``) and a control thread that dies.

``LinkWatch`` alone with a stand-in bus that loses and regains its device (a unit test of one
class); the death of the control thread with the real ``ArmDriver`` on python-can's ``virtual``
bus. The whole unplug-replug on a pty is test/e2e/test_cable.py.
"""

import threading

import can
from mover6_control.hardware.driver import ArmDriver
from mover6_control.hardware.driver_state import ModuleState
from mover6_control.hardware.link import LinkWatch
from mover6_control.hardware.scaling import load_joints


class Adapter:
    """A bus stand-in: ``connected`` and ``reopen`` as ``Usb2CanBus`` has them."""

    def __init__(self):
        self.connected = True
        self.back = False
        self.attempts = []
        self.link_error = 'USB2CAN read failed: device gone'

    def reopen(self):
        self.attempts.append(True)
        self.connected = self.back
        return self.back


def test_a_lost_link_is_reopened_with_back_off_and_says_why():
    bus = Adapter()
    watch = LinkWatch(bus, backoff=0.1, backoff_max=0.4)
    assert not watch.lost(0.0) and watch.reason(0.0) == ''
    bus.connected = False
    assert watch.lost(1.0) and not watch.lost(1.05)      # one loss, seen once
    for t in range(100, 300):
        assert not watch.poll(t / 100)
    assert len(bus.attempts) == 6            # at 1.1, 1.3 (+0.2), 1.7 (+0.4), 2.1, 2.5, 2.9 s
    assert 'device gone' in watch.reason(2.95) and 'attempt 6' in watch.reason(2.95)
    bus.back = True
    assert not watch.poll(3.2) and watch.poll(3.31)
    assert watch.lost_at is None and watch.recoveries == 1
    assert abs(watch.last_outage - 2.31) < 1e-9 and watch.reason(3.31) == ''


def test_a_bus_that_cannot_lose_its_device_is_always_up():
    bus = can.Bus(interface='virtual', channel='link_always_up')
    try:
        watch = LinkWatch(bus)
        assert watch.is_up() and not watch.lost(0.0) and not watch.poll(1.0)
    finally:
        bus.shutdown()


def test_a_control_thread_that_dies_reports_a_fault_not_silence():
    _, joints = load_joints()
    bus = can.Bus(interface='virtual', channel='link_thread_death')
    reports = []
    died = threading.Event()

    def on_cycle(report):
        reports.append(report)
        if len(reports) == 3:
            raise RuntimeError('a bug in the cycle')
        if report.state == ModuleState.FAULT:
            died.set()

    driver = ArmDriver(bus, joints, on_cycle=on_cycle)
    driver.start()
    try:
        assert died.wait(10.0)
        assert not driver.alive
        assert driver.thread_error == 'RuntimeError: a bug in the cycle'
        last = reports[-1]
        assert last.state == ModuleState.FAULT and 'control thread died' in last.hold
        assert 'restart the driver' in last.hold
    finally:
        driver.close()
