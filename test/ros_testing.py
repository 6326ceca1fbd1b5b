"""
Start the three nodes as separate processes, talk to them over DDS, stop them by pid.

Used by the end-to-end tests and the benchmarks: ``Stack`` starts nodes of the one stack
definition (``mover6_control.stack.plan``, what both launchers start, for the launchers' options
a test chooses as a user would: ``--jog-units fraction-of-max`` is ``options={'jog_units':
'fraction_of_max'}``), each with its parameter file from config/ and the parameters the plan
sets, then a test's own overrides as a user passes them (``MOVER6_CONTROLLER_ARGS="-p
name:=value"``); the installed executables when the package is built, ``python -m`` otherwise.
Their output goes to log files shown when a test fails.

``GOAL_TOLERANCE``, ``SETTLE_TOLERANCE`` and ``POSITION_TOLERANCE`` are the product's promises
about arrival, from the shipped parameters: the bounds the tests of arrival assert.
"""

import contextlib
import ctypes
import os
import resource
import signal
import subprocess
import threading
import time

from mover6_control import stack as stack_definition
from mover6_control.parameters import CONTROLLER, PLANNER
from mover6_control.resources import CONFIG_DIR, executable_command
import numpy as np
from rclpy.executors import SingleThreadedExecutor

ROOT = os.path.dirname(CONFIG_DIR)

# [rad] the controller reports 'arrived' when every joint is this close to the goal.
GOAL_TOLERANCE = CONTROLLER['goal_tolerance'].default
# [rad] it then keeps converging until every joint is this close (settled), then holds.
SETTLE_TOLERANCE = CONTROLLER['settle_tolerance'].default
# [m] the planner's joint goal puts the tool this close to the goal's position.
POSITION_TOLERANCE = PLANNER['position_tolerance'].default


PR_CAPBSET_DROP, CAP_SYS_NICE = 24, 23       # linux/prctl.h, linux/capability.h


def without_the_right():
    """
    Take the right to real-time scheduling from a child process (its ``preexec_fn``).

    No rtprio limit and no CAP_SYS_NICE.
    As root the capability goes from the bounding set, so the program run keeps none of it;
    elsewhere the limit is enough (the drop fails harmlessly).
    """
    resource.setrlimit(resource.RLIMIT_RTPRIO, (0, 0))
    ctypes.CDLL(None, use_errno=True).prctl(PR_CAPBSET_DROP, CAP_SYS_NICE, 0, 0, 0)


def pid_alive(pid):
    """Return True while process ``pid`` exists."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def installed():
    """Return True when the package is found on the ament index (launch.sh needs it)."""
    try:
        from ament_index_python.packages import get_package_prefix
        get_package_prefix('mover6_control')
        return True
    except Exception:  # noqa: B902 - not built
        return False


@contextlib.contextmanager
def ready_client(stack, make, timeout=30.0):
    """
    Yield the goal client ``make()`` once every node of ``stack`` answers (its ``wait_ready``).

    rclpy is initialised before ``make()`` and shut down after the client is destroyed: the
    module fixtures of the end-to-end tests, one client per module.
    """
    import rclpy
    rclpy.init()
    node = make()
    try:
        problem = node.wait_ready(timeout=timeout)
        assert problem is None, f'{problem}\n{stack.report()}'
        yield node
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


class NodeProcess:
    """
    One node in its own process, output to a log file.

    ``ros_args`` are added after the parameters (e.g. remappings ``('-r', 'a:=b')``);
    ``new_session`` starts it in its own session and process group, with no controlling terminal,
    as a launch system or a service manager runs it; ``log_name`` names the log file (default:
    the node's name); ``command`` replaces the node's command line (params and ros_args unused).
    """

    def __init__(self, name, log_dir, params=None, ros_args=(), new_session=False, log_name=None,
                 command=None):
        self.name = name
        self.log_path = os.path.join(str(log_dir), f'{log_name or name}.log')
        if command is None:
            command = executable_command(name) + ['--ros-args', '--params-file',
                                                  os.path.join(CONFIG_DIR, f'{name}.yaml')]
            for key, value in (params or {}).items():
                command += ['-p', f'{key}:={value}']
            command += list(ros_args)
        self.log = open(self.log_path, 'w')
        env = dict(os.environ, PYTHONUNBUFFERED='1')
        self.proc = subprocess.Popen(command, stdout=self.log, stderr=subprocess.STDOUT, env=env,
                                     cwd=ROOT, start_new_session=new_session)

    @property
    def pid(self):
        """Return the process id."""
        return self.proc.pid

    def alive(self):
        """Return True while the process runs."""
        return self.proc.poll() is None

    def interrupt(self):
        """Send SIGINT by pid (the start of ``stop``, for stopping several at once)."""
        if self.alive():
            self.proc.send_signal(signal.SIGINT)

    def stop(self, timeout=10.0):
        """Stop the process by its pid: SIGINT, then SIGKILL after ``timeout`` [s]."""
        if self.alive():
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5.0)
        self.log.close()
        return self.proc.returncode

    def tail(self, lines=30):
        """Return the last lines of the node's output."""
        try:
            with open(self.log_path) as f:
                return ''.join(f.readlines()[-lines:])
        except OSError:
            return ''


def planned_parameters(options):
    """Return {node name: {parameter: text}} the stack definition sets for launcher ``options``."""
    text = stack_definition.parameter_text
    return {start.name: {k: text(v) for k, v in start.parameters.items()}
            for start in stack_definition.plan(options) if start.kind == 'node'}


class Stack:
    """
    Nodes of the stack definition as processes (by default the three); a context manager.

    ``options`` are the launchers' (``mover6_control.stack.OPTIONS``: name to text); ``sim``,
    ``controller``, ``planner``, ``driver`` (and ``params``: node name to parameters, any node)
    are a test's overrides on top of the plan's, as a user passes them with ``-p``.
    """

    def __init__(self, log_dir, sim=None, controller=None, planner=None,
                 names=('sim_bridge', 'controller', 'planner'), driver=None, ros_args=None,
                 params=None, options=None):
        self.log_dir = str(log_dir)
        self.ros_args = dict(ros_args or {})    # node name -> extra ROS arguments
        self.options = dict(options or {})
        self.planned = planned_parameters(self.options)
        self.overrides = {'sim_bridge': sim or {}, 'controller': controller or {},
                          'planner': planner or {}, 'driver': driver or {}}
        self.overrides.update(params or {})     # node name -> parameters, any other node
        self.names = names
        self.nodes = {}

    def choose(self, **options):
        """Change launcher options, as a user starting the stack again: nodes started after."""
        self.options.update(options)
        self.planned = planned_parameters(self.options)

    def parameters(self, name):
        """Return the parameters node ``name`` starts with: the plan's, then the overrides."""
        return {**self.planned.get(name, {}), **self.overrides.get(name, {})}

    def start(self, name):
        """Start (or restart) one node."""
        old = self.nodes.get(name)
        if old is not None and old.alive():
            old.stop()
        self.nodes[name] = NodeProcess(name, self.log_dir, self.parameters(name),
                                       ros_args=self.ros_args.get(name, ()))
        return self.nodes[name]

    def __enter__(self):
        """Start every node."""
        for name in self.names:
            self.start(name)
        return self

    def __exit__(self, *exc):
        """Stop every node by pid."""
        self.stop_all()

    def stop_all(self):
        """Stop every node still running: SIGINT to all at once, then wait for each."""
        for node in self.nodes.values():
            node.interrupt()
        for node in self.nodes.values():
            node.stop()

    def report(self):
        """Return the tail of every node's output, for a failure message."""
        return '\n'.join(f'--- {n.name} (pid {n.pid}, alive={n.alive()}) ---\n{n.tail()}'
                         for n in self.nodes.values())


def assert_settled(status, stack=None, settle_tolerance=SETTLE_TOLERANCE,
                   goal_tolerance=GOAL_TOLERANCE):
    """
    Assert the controller's status ``status`` about a goal that ended says it kept its promise.

    'arrived' inside the goal tolerance (its ``final_joint_error``), then settled inside the
    settle tolerance (``settled_joint_error``), both [rad], the shipped ones unless given (a
    controller on a driver with a cycle settles to one tick).
    """
    from mover6_control.nodes.messages.conversions import status_values
    values = status_values(status)
    report = f'{values}\n{stack.report() if stack is not None else ""}'
    assert values.get('result') == 'arrived', report
    assert float(values['final_joint_error']) <= np.max(goal_tolerance), report
    assert float(values['settled_joint_error']) <= np.max(settle_tolerance), report


def settled_q(client, stack=None, timeout=10.0):
    """
    Return a fresh /joint_states reading of goal client ``client`` once the controller settled.

    Its state idle after the goal, and ``assert_settled`` of its status; then one reading that
    came after (the pose it holds).
    """
    from mover6_control.nodes.messages.conversions import status_values
    report = stack.report() if stack is not None else ''
    assert client.spin_until(
        lambda: status_values(client.controller_status).get('state') == 'idle', timeout), report
    assert_settled(client.controller_status, stack)
    client.q = None
    assert client.spin_until(lambda: client.q is not None, timeout), report
    return client.q.copy()


def spin_until(executor, predicate, timeout=30.0, period=0.01, each=None):
    """
    Spin ``executor`` until ``predicate()`` holds: return the monotonic time it did, else None.

    ``each()``, when given, runs after every spin (a stream the test keeps up meanwhile).
    """
    def spin(slice_):
        executor.spin_once(timeout_sec=slice_)
        if each is not None:
            each()
    return time.monotonic() if wait_until(predicate, timeout, spin, period) else None


class Spinning:
    """
    Spin each of ``nodes`` on a ``SingleThreadedExecutor`` of its own, in a thread of its own.

    As each node's ``main()`` runs it. One ``MultiThreadedExecutor`` for a driver node and a
    test's client node instead spun while the driver's ``on_activate`` waited seconds for
    referencing: its list of pending handlers grew to thousands, and scanning it at every wait
    held the interpreter lock for hundreds of milliseconds at a time, long enough for the
    simulated modules in the same process to trip their communication watchdog.
    ``close()`` stops the executors and joins the threads.
    """

    def __init__(self, context, nodes):
        self.executors = []
        self.threads = []
        for node in nodes:
            executor = SingleThreadedExecutor(context=context)
            executor.add_node(node)
            thread = threading.Thread(target=executor.spin, daemon=True,
                                      name=f'spin_{node.get_name()}')
            thread.start()
            self.executors.append(executor)
            self.threads.append(thread)

    def close(self, timeout=10.0):
        """Stop every executor; wait for its thread."""
        for executor in self.executors:
            executor.shutdown(timeout_sec=timeout)
        for thread in self.threads:
            thread.join(timeout=timeout)


def wait_until(predicate, timeout, spin=None, period=0.05):
    """Wait until ``predicate()`` is true (spinning ``spin(period)`` between checks)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        if spin is not None:
            spin(period)
        else:
            time.sleep(period)
    return bool(predicate())


class CanSimProcess(NodeProcess):
    """
    The CAN-level Mover6 (``can_sim``) in its own process on a pty linked at ``link``.

    ``args`` are added to its command line; its output goes to ``log_dir``/can_sim.log.
    ``control(line)`` talks to its control socket. Use as a context manager.
    """

    def __init__(self, log_dir, link, args=()):
        self.link = str(link)
        self.control_path = self.link + '.control'
        super().__init__('can_sim', log_dir,
                         command=executable_command('can_sim') + ['--link', self.link] +
                         list(args))

    def wait_ready(self, timeout=30.0):
        """Wait until the link and the control socket exist; return True if they do."""
        return wait_until(lambda: not self.alive() or (
            os.path.exists(self.link) and os.path.exists(self.control_path)), timeout) \
            and self.alive()

    def control(self, line):
        """Send one control command; return its JSON answer as a dict."""
        from sim_bridge.can_sim import control
        return control(self.control_path, line)

    def __enter__(self):
        """Return self once it is ready (or raise with its output)."""
        if not self.wait_ready():
            self.stop()
            raise RuntimeError(f'can_sim did not come up:\n{self.tail()}')
        return self

    def __exit__(self, *exc):
        """Stop it."""
        self.stop()
