"""
A cable that comes back: the USB2CAN adapter pulled and plugged in again, on a pty.

``can_sim`` (its own process) serves the CAN-level Mover6 on a pty linked at a path; the driver
(``ArmDriver`` on its control thread, real clock, the package's ``Usb2CanBus``) opens that path
as it opens ``/dev/ttyUSB0``. ``unplug`` closes the pty and removes the link (the driver's reads
fail), ``replug`` makes a new pty at the same path; the modules keep running meanwhile and stop
on their own watchdog. The driver must hold and say why, reopen the port with back-off, read
every position again and stay not enabled until asked. The time from the replug to every
position known again is printed as a FIGURE line.
"""

import time

from diagnostic_msgs.msg import DiagnosticArray
from mover6_control.hardware.bus import open_bus
from mover6_control.hardware.driver import ArmDriver
from mover6_control.hardware.driver_state import ModuleState
from mover6_control.hardware.link import BACKOFF_MAX
from mover6_control.hardware.scaling import load_joints
from mover6_control.nodes.messages.conversions import status_level_name, status_values
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from ros_testing import CanSimProcess, spin_until, Stack, wait_until

pytestmark = pytest.mark.e2e


@pytest.fixture
def rig(tmp_path):
    """can_sim on a pty and a driver on its control thread, reset and enabled."""
    with CanSimProcess(tmp_path, tmp_path / 'mover6-can') as sim:
        _, joints = load_joints()
        states = []

        def on_cycle(report):
            states.append((time.monotonic(), str(report.state), report.link))

        driver = ArmDriver(open_bus('cpr_usb2can', sim.link), joints, on_cycle=on_cycle)
        driver.start()
        try:
            for kind in ('reset', 'enable'):
                ok, reason = driver.request(kind, timeout=5.0).wait(10.0)
                assert ok, reason
            yield sim, driver, states
        finally:
            driver.close()


def transitions(states):
    """Return the (state, link) changes of the reports, in order."""
    out = []
    for _, state, link in states:
        if not out or out[-1] != f'{state}/{link}':
            out.append(f'{state}/{link}')
    return ' -> '.join(out)


def test_a_pulled_adapter_holds_reopens_and_stays_disabled(rig):
    sim, driver, states = rig
    assert driver.report.state in (ModuleState.ENABLED, ModuleState.REFERENCED)
    driver.set_velocity([0.1, 0, 0, 0, 0, 0])
    assert sim.control('unplug')['ok']
    t_unplug = time.monotonic()
    assert wait_until(lambda: driver.report.link == 'lost', 5.0)
    t_seen = time.monotonic()
    report = driver.report
    assert report.state == ModuleState.DISCONNECTED
    assert 'link to the CAN adapter lost' in report.hold and 'stays disabled' in report.hold
    # The modules stop on their own watchdog (no set-point comes), the arm at rest.
    assert wait_until(lambda: not any(m['enabled'] for m in sim.control('status')['modules']),
                      5.0)
    # Requests are refused with the reason while the link is lost.
    ok, reason = driver.request('enable', timeout=1.0).wait(5.0)
    assert not ok and 'no reply' in reason
    assert sim.control('replug')['ok']
    t_replug = time.monotonic()
    assert wait_until(lambda: driver.report.link == 'up' and
                      all(j.replies for j in driver.report.joints), BACKOFF_MAX + 5.0)
    t_back = time.monotonic()
    report = driver.report
    # Every position read again, within a few ticks of the simulated encoders; not enabled.
    status = sim.control('status')
    assert [j.state for j in report.joints] == [ModuleState.ERROR] * 6, report
    assert all('comm_watchdog' in j.flag_names for j in report.joints)
    assert not any(m['enabled'] for m in status['modules'])
    assert report.hold and report.link_losses == 1 and report.bus_error == ''
    for ok_kind in ('reset', 'enable'):
        ok, reason = driver.request(ok_kind, timeout=5.0).wait(10.0)
        assert ok, reason
    assert driver.report.state in (ModuleState.ENABLED, ModuleState.REFERENCED)
    print(f'FIGURE cable: link lost seen {t_seen - t_unplug:.3f} s after the unplug; back '
          f'{t_back - t_replug:.3f} s after the replug with every position read again (outage '
          f'{report.link_outage:.2f} s, back-off max {BACKOFF_MAX} s); states '
          f'{transitions(states)}')


def test_close_never_hangs_with_the_adapter_gone(rig):
    sim, driver, _ = rig
    assert sim.control('unplug')['ok']
    assert wait_until(lambda: driver.report.link == 'lost', 5.0)
    start = time.monotonic()
    driver.close()
    took = time.monotonic() - start
    print(f'FIGURE cable: close() with the adapter gone took {took:.3f} s')
    assert took < 1.0


def test_the_driver_node_says_so_on_diagnostics(tmp_path):
    """The driver as a process on can_sim's pty: the loss and the return on /diagnostics."""
    with CanSimProcess(tmp_path, tmp_path / 'mover6-can') as sim:
        driver = {'can_interface': 'cpr_usb2can', 'can_channel': sim.link,
                  'enable_on_start': True}
        with Stack(tmp_path, driver=driver, names=('driver',)) as stack:
            context = rclpy.Context()
            rclpy.init(context=context)
            node = rclpy.create_node('cable_watch', context=context)
            executor = SingleThreadedExecutor(context=context)
            executor.add_node(node)
            seen = []

            def on_diagnostics(msg):
                for status in msg.status:
                    if status.name == 'driver: bus':
                        seen.append((status_level_name(status), status_values(status)))
            node.create_subscription(DiagnosticArray, 'diagnostics', on_diagnostics, 10)
            try:
                def bus():
                    return seen[-1][1] if seen else {}
                assert spin_until(executor, lambda: bus().get('state') == 'enabled', 60.0), \
                    stack.report()
                assert sim.control('unplug')['ok']
                assert spin_until(executor, lambda: bus().get('link') == 'lost', 10.0), \
                    stack.report()
                lost = bus()
                assert lost['state'] == 'disconnected' and seen[-1][0] == 'WARN'
                assert 'link to the CAN adapter lost' in lost['hold']
                assert sim.control('replug')['ok']
                t_replug = time.monotonic()
                # Back, every module answered, none enabled: 'connected' (the driver's disable
                # came before the watchdog) or 'error' (the watchdog came first).
                t_back = spin_until(executor, lambda: bus().get('link') == 'up' and
                                    bus().get('state') in ('connected', 'error'), 15.0)
                assert t_back, stack.report()
                back = bus()
                assert back['hold'] and back['link_losses'] == '1'
                assert not any(m['enabled'] for m in sim.control('status')['modules'])
                print(f'FIGURE cable: the driver node on /diagnostics: link lost, then back '
                      f'{t_back - t_replug:.2f} s after the replug, arm {back["state"]} '
                      f'({back["hold"]}): not enabled until asked')
            finally:
                node.destroy_node()
                rclpy.try_shutdown(context=context)
