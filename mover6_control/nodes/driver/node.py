"""
The driver node of the real Mover6, a lifecycle node: /JointJog in, CAN set-points out.

Subscribes /JointJog (control_msgs/JointJog, velocities by joint name; ``jog_units`` rad_per_s or
fraction_of_max x ``speed_override``, as the controller's); publishes /joint_states
(sensor_msgs/JointState: joint1..joint6, position, velocity) every driver cycle once every module
has answered, and /diagnostics (one status per joint, one for the bus with the arm's state, the
lifecycle state, why it holds, the frames dropped and refused).

The lifecycle (``ros2 lifecycle set /driver <transition>``; docs/driver.md tells each
transition): configure opens the bus and reads every position with commands that move nothing;
activate resets, enables and references; deactivate stops and disables; cleanup, shutdown and
on_error disable every module and close the bus.

At start the node configures itself and, with ``enable_on_start``, activates (what the launchers
ask for); a configure at start that cannot open the bus or the frame log ends the process with
the reason (exit code 1), as a missing adapter always did; one that finds the modules silent
leaves the node unconfigured (configure again once the arm is on). Services (std_srvs/Trigger,
``trigger_services``): ~/reset, ~/disable, ~/set_zero (guarded by ``allow_set_zero``) once
configured; ~/enable, ~/reference and ~/recover (reset + enable + (re)reference in one call, the
only way back after power was lost) only while active.

The work is ``mover6_control.hardware.driver.ArmDriver`` on its own control thread (the cycle),
made at configure by ``arm_session.ArmSession``; the node converts messages and publishes from a
thread of its own (``report_publisher``), so the control thread never waits on DDS. With
``cycle_priority`` (default 50) the cycle runs at SCHED_FIFO where the system allows it. The
cycle is Python and needs the interpreter lock, so the rest of the process keeps it short: the
lock changes hands every 0.5 ms and what was loaded at start is frozen out of the garbage
collector (``realtime.steady_interpreter``), /JointJog, the parameters and the lifecycle
services are served by a single-threaded executor and the Trigger services by an executor of
their own. Measured with ``./run.sh bench driver``.
"""

from typing import Callable, Optional

import can
from control_msgs.msg import JointJog
from mover6_control.errors import InvalidInputError
from mover6_control.hardware.bus import open_bus, open_frame_log
from mover6_control.hardware.calibration import calibration_refusal
from mover6_control.hardware.driver import ArmDriver
from mover6_control.hardware.scaling import JOINTS_YAML, load_joints
from mover6_control.nodes.driver.arm_session import ArmSession
from mover6_control.nodes.driver.gripper_action import GripperAction, InputPublisher
from mover6_control.nodes.driver.jog_intake import JogIntake
from mover6_control.nodes.driver.report_publisher import ReportPublisher
from mover6_control.nodes.driver.trigger_services import TriggerServices
from mover6_control.nodes.driver.unknown_transitions import UnknownTransitions
from mover6_control.nodes.runtime import shutdown
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from mover6_control.nodes.runtime.params import declare
from mover6_control.parameters import DRIVER
from mover6_control.realtime import steady_interpreter
from rclpy.executors import SingleThreadedExecutor
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.parameter import Parameter

GRIPPER_BITS = {'off': 0x00, 'open': 0x03, 'closed': 0x02}
"""Joint 4's outputs: bit 0 'gripper open', bit 1 'gripper enabled' (the vendor's CPRMover6)."""
GRIPPER_JOINT, OUTPUTS_JOINT = 4, 1
SERVICES = ('reset', 'enable', 'disable', 'reference', 'set_zero', 'recover')
NEEDS_ACTIVE = ('enable', 'reference', 'recover')
"""The services that may move or enable the arm: only while the driver is active."""
OK, FAILED, ERROR = (TransitionCallbackReturn.SUCCESS, TransitionCallbackReturn.FAILURE,
                     TransitionCallbackReturn.ERROR)


class DriverNode(LifecycleNode):
    """Drive the arm over CAN as a lifecycle node; see the module docstring."""

    def __init__(self, **kwargs):
        super().__init__('driver', **kwargs)
        self.lifecycle_state = 'unconfigured'
        self.last_failure = ''
        self.unknown_transitions = UnknownTransitions(   # inside the guard, made next
            self, state=lambda: self.lifecycle_state, failure=self._failed)
        self.guard = CallbackGuard(self)     # no callback ends the node (bad input: refused)
        declare(self, DRIVER, guard=self.guard)
        self.guard.after_set(self.on_parameters_set)
        self.params = {name: self.get_parameter(name).value for name in DRIVER}
        if self.params['listen_only'] and self.params['enable_on_start']:
            raise SystemExit('driver: listen_only sends nothing, enable_on_start asks to enable: '
                             'refused (set one of them false)')
        self.firmware, self.joints = load_joints(self.params['joints_file'] or JOINTS_YAML)
        refusal = calibration_refusal(self.params['calibration_file'], self.joints,
                                      self.get_logger().warning)
        if refusal:                       # the first-run check saw a joint turn the wrong way
            raise SystemExit(f'driver: {refusal}')
        self.names = tuple(j.name for j in self.joints)
        self.max_speed = [j.max_speed for j in self.joints]
        self.fatal = None
        self.cannot_open = False                  # the last transition could not open the bus
        self.session = ArmSession(self._open_driver, self._timeouts,
                                  on_cycle=lambda report: self.reports.on_cycle(report),
                                  allow_set_zero=self._live('allow_set_zero'))
        self.intake = JogIntake(self.names, self.max_speed, self.params['jog_units'],
                                speed_override=self._live('speed_override'),
                                blocked=self._jog_blocked, command=self._command,
                                on_refusal=lambda: self.reports.notify())
        self.reports = ReportPublisher(self, self.names, self.intake.counts,
                                       lifecycle=lambda: self.lifecycle_state,
                                       scheduling=self._scheduling,
                                       rate=self._live('diagnostics_rate'))
        self.guard.subscription(JointJog, 'JointJog', self.intake.on_jog, 10)
        self.trigger_services = TriggerServices(self, self.guard, SERVICES, self.run_service)
        self.gripper_action = GripperAction(
            self.trigger_services.node, f'{self.get_fully_qualified_name()}/gripper_cmd',
            self.guard, self.get_logger(), driver=lambda: self.driver,
            lifecycle_state=lambda: self.lifecycle_state)
        self.inputs = InputPublisher(self, self.guard, self.trigger_services.node,
                                     driver=lambda: self.driver)
        self._start = self.guard.timer(0.01, self._start_transitions)

    # --- the parts' inputs ---

    def _live(self, name: str) -> Callable:
        return lambda: self.get_parameter(name).value

    @property
    def machine_state(self) -> str:
        """
        Return the lifecycle state as rcl's state machine has it (as ~/get_state answers).

        ``lifecycle_state`` is what the last transition made of the node, set inside its
        callback: it says 'inactive' while the machine is still 'configuring'; a transition
        may be asked for once this says where the node is.
        """
        return self._state_machine.current_state[1]

    @property
    def driver(self) -> Optional[ArmDriver]:
        """Return the arm driver while configured, else None."""
        return self.session.driver

    def _timeouts(self) -> tuple[float, float]:
        return (self.get_parameter('request_timeout').value,
                self.get_parameter('reference_timeout').value)

    def _scheduling(self) -> str:
        driver = self.driver
        return driver.scheduling if driver is not None else 'not configured'

    def _jog_blocked(self) -> str:
        if self.lifecycle_state != 'active':
            return (f'the driver is {self.lifecycle_state}: activate it '
                    f'(ros2 lifecycle set {self.get_fully_qualified_name()} activate)')
        return ''

    def _command(self, qd: list) -> None:
        driver = self.driver
        if driver is not None:
            driver.set_velocity(qd)

    def _open_driver(self, on_cycle) -> ArmDriver:
        """Open the frame log and the bus and make the driver (configure)."""
        p = self.params
        frame_log = open_frame_log(p['frame_log']) if p['frame_log'] else None
        try:
            bus = open_bus(p['can_interface'], p['can_channel'], p['bitrate'])
        except BaseException:
            if frame_log is not None:
                frame_log.stop()
            raise
        get = self.get_parameter
        driver = ArmDriver(
            bus, self.joints, cycle=get('cycle').value,
            command_timeout=get('command_timeout').value, max_lag=get('max_lag').value,
            silent_cycles=p['silent_cycles'], frame_gap=p['frame_gap'],
            limit_set=p['limit_set'], firmware=self.firmware, on_cycle=on_cycle,
            priority=p['cycle_priority'], frame_log=frame_log, listen_only=p['listen_only'])
        self._apply_outputs(driver, get('gripper').value, get('digital_outputs').value)
        self.get_logger().info(f'bus open: {p["can_interface"]} {p["can_channel"]}, cycle '
                               f'{driver.cycle} s, JointJog in {p["jog_units"]}')
        return driver

    # --- the lifecycle ---

    def _start_transitions(self) -> None:
        """Configure at start and, with ``enable_on_start``, activate (one shot)."""
        self._start.cancel()
        self.cannot_open = False
        if self.trigger_configure() != OK:
            if self.cannot_open:             # no adapter, a frame log that cannot be written
                self.fatal = f'driver: configure at start failed: {self.last_failure}'
            else:                            # modules silent: the arm may be switched on later
                self.get_logger().warning(
                    'unconfigured: configure again once the arm answers (ros2 lifecycle set '
                    f'{self.get_fully_qualified_name()} configure)')
            return
        if self.params['enable_on_start']:
            self.trigger_activate()

    def _transition(self, name: str, step: Callable[[], tuple[bool, str]],
                    target: str) -> TransitionCallbackReturn:
        """Run one transition's work; log its outcome; SUCCESS moves to ``target``."""
        try:
            ok, message = step()
        except (InvalidInputError, OSError, can.CanError) as err:
            self.cannot_open = True
            ok, message = False, f'{type(err).__name__}: {err}'
        except Exception as err:  # noqa: B902 - an error in a transition: on_error follows
            self.last_failure = f'{name}: {type(err).__name__}: {err}'
            self.get_logger().error(f'{self.last_failure}: on_error disables every module')
            return ERROR
        if not ok:
            self.last_failure = f'{name} refused: {message}'
            self.get_logger().error(self.last_failure)
            self.reports.notify()
            return FAILED
        self.lifecycle_state = target
        self.get_logger().info(f'{name}: {message} -> {target}')
        self.reports.notify()
        return OK

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Open the bus and read every module's position (``ArmSession.configure``)."""
        return self._transition('configure', self.session.configure, 'inactive')

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Reset, enable, reference what needs it (``ArmSession.activate``)."""
        return self._transition('activate', self.session.activate, 'active')

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop, come to rest, disable (``ArmSession.deactivate``)."""
        self.lifecycle_state = 'deactivating'        # JointJog is no longer taken
        result = self._transition('deactivate', self.session.deactivate, 'inactive')
        if result == FAILED:
            return ERROR                             # not disabled: on_error disables
        return result

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Disable every module and close the bus."""
        return self._transition('cleanup', self._close, 'unconfigured')

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Disable every module and close the bus."""
        return self._transition('shutdown', self._close, 'finalized')

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Disable every module and close the bus; the node is then unconfigured."""
        self.session.close()
        self.lifecycle_state = 'unconfigured'
        self.get_logger().error('on_error: every module disabled, the bus closed -> '
                                'unconfigured')
        self.reports.notify()
        return OK

    def _close(self) -> tuple[bool, str]:
        self.session.close()
        return True, 'every module disabled, the bus closed'

    def _failed(self, reason: str) -> None:
        self.last_failure = reason
        self.get_logger().warning(reason)

    # --- services and parameters ---

    def run_service(self, kind: str) -> tuple[bool, str]:
        """Run one Trigger service; return (success, message)."""
        if kind in NEEDS_ACTIVE and self.lifecycle_state != 'active':
            return False, (f'{kind} refused: the driver is {self.lifecycle_state}; activate it '
                           f'first (ros2 lifecycle set {self.get_fully_qualified_name()} '
                           'activate)')
        if kind == 'recover':
            return self.session.recover()
        return self.session.run(kind)

    def on_parameters_set(self, parameters: list[Parameter]) -> None:
        """Apply the live parameters to the driver (they were checked before they were set)."""
        driver = self.driver
        if driver is None:
            return
        names = {x.name for x in parameters}
        if 'cycle' in names:
            driver.cycle = self.get_parameter('cycle').value
        if 'command_timeout' in names:
            driver.command_timeout = self.get_parameter('command_timeout').value
        if 'max_lag' in names:
            driver.max_lag = self.get_parameter('max_lag').value
        if names & {'gripper', 'digital_outputs'}:
            self._apply_outputs(driver, self.get_parameter('gripper').value,
                                self.get_parameter('digital_outputs').value)

    @staticmethod
    def _apply_outputs(driver: ArmDriver, gripper: str, outputs: int) -> None:
        driver.set_outputs(GRIPPER_JOINT, GRIPPER_BITS[gripper])
        driver.set_outputs(OUTPUTS_JOINT, outputs)

    def destroy_node(self) -> None:
        """Disable every module and close the bus, stop the threads, destroy the node."""
        self.session.close()
        self.reports.close()
        self.trigger_services.close()
        super().destroy_node()


def main(args: Optional[list[str]] = None) -> None:
    """Run the driver node until Ctrl-C, SIGTERM or shutdown; every module is disabled then."""
    steady_interpreter()
    shutdown.run_node(DriverNode, args, SingleThreadedExecutor)


if __name__ == '__main__':
    main()
