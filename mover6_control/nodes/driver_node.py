"""
The driver node of the real Mover6: /JointJog in, CAN set-points out, /joint_states back.

Subscribes /JointJog (control_msgs/JointJog, velocities by joint name; ``jog_units`` rad_per_s or
fraction_of_max x ``speed_override``, as the controller's); publishes /joint_states
(sensor_msgs/JointState: joint1..joint6, position, velocity) every driver cycle once every module
has answered, and /diagnostics (diagnostic_msgs/DiagnosticArray: one status per joint with its
state, flags by name, referenced and lag, one for the bus with the arm's state, why it holds, the
frames dropped and refused), at ``diagnostics_rate`` and at once on every change. Services
(std_srvs/Trigger, each answering once the modules confirm or with the reason): ~/reset,
~/enable, ~/disable, ~/reference (joints one at a time, refused while moving), ~/set_zero
(refused unless ``allow_set_zero``). The gripper and joint 1's digital outputs are parameters.
``frame_log`` writes every frame sent and read (python-can's writer: candump's log format for
``.log``), ``listen_only`` sends nothing; a frame log that cannot be written, or listen_only with
enable_on_start, stops the node at start with the reason.

The work is ``mover6_control.hardware.driver.ArmDriver`` on its own control thread (the cycle);
the node converts messages and publishes. The control thread never waits on DDS: it hands each
cycle's report to a publisher thread (a DDS write can block for hundreds of milliseconds, see
controller_node.py). With ``cycle_priority`` (default 50) it runs at SCHED_FIFO where the system
allows it, the node's other threads just below (``mover6_control.realtime``, as the controller's
``tick_priority``). The cycle is Python and needs the interpreter lock, so the rest of the
process keeps it short: the lock changes hands every ``SWITCH_INTERVAL``, what was loaded at
start is frozen out of the garbage collector (a full collection held the lock for 25-45 ms),
/JointJog and the parameters are served by a single-threaded executor (the multi-threaded one
delayed a JointJog by 27 ms on average) and the services, which wait for the modules, by a
node (``driver_services``, no parameters) and executor of their own. Measured with
``./run.sh bench driver``.

The node is three parts: this module (parameters, services, the threads), ``driver_jog``
(/JointJog checked and commanded, or refused: which JointJogs are refused and what is counted)
and ``driver_publish`` (the publisher thread: /joint_states, /diagnostics and the state log).
"""

import gc
import sys
import threading
from typing import Optional

from control_msgs.msg import JointJog
from diagnostic_msgs.msg import DiagnosticArray
from mover6_control.errors import InvalidInputError
from mover6_control.hardware.bus import open_bus, open_frame_log
from mover6_control.hardware.calibration import calibration_refusal
from mover6_control.hardware.driver import ArmDriver
from mover6_control.hardware.scaling import JOINTS_YAML, load_joints
from mover6_control.nodes.driver.gripper_action import GripperAction, InputPublisher
from mover6_control.nodes.driver_jog import JogInput
from mover6_control.nodes.driver_publish import ReportPublisher
from mover6_control.nodes.runtime import shutdown
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from mover6_control.nodes.runtime.params import declare
from mover6_control.parameters import DRIVER
from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

GRIPPER_BITS = {'off': 0x00, 'open': 0x03, 'closed': 0x02}
"""Joint 4's outputs: bit 0 'gripper open', bit 1 'gripper enabled' (the vendor's CPRMover6)."""
GRIPPER_JOINT, OUTPUTS_JOINT = 4, 1
SWITCH_INTERVAL = 0.0005
"""[s] the interpreter lock's switch interval in the driver's process (Python's default 5 ms)."""


class DriverNode(JogInput, ReportPublisher, Node):
    """Drive the arm over CAN; see the module docstring."""

    def __init__(self, **kwargs):
        super().__init__('driver', **kwargs)
        self.guard = CallbackGuard(self)     # no callback ends the node (bad input: refused)
        declare(self, DRIVER, guard=self.guard)
        self.guard.after_set(self.on_parameters_set)
        p = {name: self.get_parameter(name).value for name in DRIVER}
        self.jog_units = p['jog_units']
        firmware, joints = load_joints(p['joints_file'] or JOINTS_YAML)
        self.max_speed = [j.max_speed for j in joints]
        if p['listen_only'] and p['enable_on_start']:
            raise SystemExit('driver: listen_only sends nothing, enable_on_start asks to enable: '
                             'refused (set one of them false)')
        refusal = calibration_refusal(p['calibration_file'], joints, self.get_logger().warning)
        if refusal:
            raise SystemExit(f'driver: {refusal}')
        try:
            frame_log = open_frame_log(p['frame_log']) if p['frame_log'] else None
        except InvalidInputError as err:
            raise SystemExit(f'driver: {err}') from None
        bus = open_bus(p['can_interface'], p['can_channel'], p['bitrate'])
        self.driver = ArmDriver(
            bus, joints, cycle=p['cycle'], command_timeout=p['command_timeout'],
            max_lag=p['max_lag'], silent_cycles=p['silent_cycles'], frame_gap=p['frame_gap'],
            limit_set=p['limit_set'],
            firmware=firmware, on_cycle=self.on_cycle, priority=p['cycle_priority'],
            frame_log=frame_log, listen_only=p['listen_only'])
        self.names = self.driver.names
        self.refused = 0
        self.refused_by = {}          # reason -> JointJogs refused for it
        self.last_refusal = ''
        self.jogs = 0                 # JointJogs received
        self.clipped = 0
        self.superseded = 0           # replaced before a cycle took them
        self._jog_pending = False
        self._scheduling_logged = False
        self._latest = None
        self._seen = None
        self._last_diag = None
        self._diag_now = False
        self._wake = threading.Condition()
        self._closing = False
        self.pub_states = self.create_publisher(JointState, 'joint_states', 10)
        self.pub_diag = self.create_publisher(DiagnosticArray, 'diagnostics', 10)
        self.guard.subscription(JointJog, 'JointJog', self.on_jog, 10)
        # The services wait for the modules (seconds; referencing minutes): they are served by a
        # node and executor of their own, so the node's single-threaded executor never waits
        # and /JointJog arrives within a millisecond (a multi-threaded executor for everything
        # took 27 ms on average, its threads churning the interpreter lock the cycle needs).
        self._service_node = Node(f'{self.get_name()}_services', namespace=self.get_namespace(),
                                  context=self.context, start_parameter_services=False,
                                  use_global_arguments=False)
        base = self.get_fully_qualified_name()
        for kind in ('reset', 'enable', 'disable', 'reference', 'set_zero'):
            self.guard.service(Trigger, f'{base}/{kind}', self._service(kind),
                               on=self._service_node)
        self.gripper_action = GripperAction(self, self._service_node)
        self.inputs = InputPublisher(self, self._service_node)
        self._service_executor = MultiThreadedExecutor(num_threads=2, context=self.context)
        self._service_executor.add_node(self._service_node)
        self._service_thread = threading.Thread(target=self._serve, name='driver_services',
                                                daemon=True)
        self._service_thread.start()
        self._apply_outputs(p['gripper'], p['digital_outputs'])
        self._publisher = threading.Thread(target=self._publish_loop, name='driver_publish',
                                           daemon=True)
        self._publisher.start()
        self.driver.start()
        if p['enable_on_start']:
            threading.Thread(target=self._enable_on_start, daemon=True).start()
        self.get_logger().info(f'driving the arm on {p["can_interface"]} {p["can_channel"]}, '
                               f'cycle {p["cycle"]} s, JointJog in {self.jog_units}')

    # --- parameters ---

    def on_parameters_set(self, parameters: list[Parameter]) -> None:
        """Apply the live parameters to the driver (they were checked before they were set)."""
        names = {x.name for x in parameters}
        if 'cycle' in names:
            self.driver.cycle = self.get_parameter('cycle').value
        if 'command_timeout' in names:
            self.driver.command_timeout = self.get_parameter('command_timeout').value
        if 'max_lag' in names:
            self.driver.max_lag = self.get_parameter('max_lag').value
        if names & {'gripper', 'digital_outputs'}:
            self._apply_outputs(self.get_parameter('gripper').value,
                                self.get_parameter('digital_outputs').value)

    def _apply_outputs(self, gripper, outputs):
        self.driver.set_outputs(GRIPPER_JOINT, GRIPPER_BITS[gripper])
        self.driver.set_outputs(OUTPUTS_JOINT, outputs)

    # --- services ---

    def _serve(self):
        try:
            self._service_executor.spin()
        except Exception:  # noqa: B902 - the context shut down: the node is closing
            pass

    def _service(self, kind):
        def callback(request, response):
            response.success, response.message = self.run_request(kind)
            return response
        return callback

    def run_request(self, kind: str) -> tuple[bool, str]:
        """Run one request to the modules; return (success, message) for the service."""
        if kind == 'set_zero' and not self.get_parameter('allow_set_zero').value:
            return False, 'set_zero refused: set the parameter allow_set_zero to true first'
        if kind != 'reference':
            timeout = self.get_parameter('request_timeout').value
            return self.driver.request(kind, timeout=timeout).wait(timeout + 5.0)
        timeout = self.get_parameter('reference_timeout').value
        for n in range(1, len(self.names) + 1):
            ok, reason = self.driver.request('reference', [n], timeout).wait(timeout + 5.0)
            if not ok:
                return False, reason
        return True, f'reference: joints 1..{len(self.names)} referenced one at a time'

    def _enable_on_start(self):
        for kind in ('reset', 'enable'):
            ok, reason = self.run_request(kind)
            if not ok:
                self.get_logger().error(f'enable_on_start: {reason}')
                return
            self.get_logger().info(f'enable_on_start: {reason}')

    def destroy_node(self) -> None:
        """Stop the control thread, disable every module, then destroy the node."""
        self.driver.close()
        with self._wake:
            self._closing = True
            self._wake.notify()
        self._publisher.join(timeout=5.0)
        self._service_executor.shutdown(timeout_sec=5.0)
        self._service_thread.join(timeout=5.0)
        self._service_node.destroy_node()
        super().destroy_node()


def main(args: Optional[list[str]] = None) -> None:
    """Run the driver node until Ctrl-C, SIGTERM or shutdown; every module is disabled then."""
    sys.setswitchinterval(SWITCH_INTERVAL)
    gc.collect()
    gc.freeze()            # what is loaded now is never scanned again: no long full collections
    shutdown.run_node(DriverNode, args, SingleThreadedExecutor)


if __name__ == '__main__':
    main()
