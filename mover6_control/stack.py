"""
The stack both launchers start: its options, and for a choice of them the nodes and parameters.

``OPTIONS`` are the launchers' arguments, each with its ``scripts/launch.sh`` option
(``--profile``) and its ``ros2 launch`` argument (``profile:=``), its choices and default (those
of ``profile``, ``jog_units`` and ``limit_set`` from the controller's parameter table);
``plan(choices)`` returns what to start, in order: each ``Start`` a node (its executable, its
parameter file ``config/<name>.yaml``, the parameters the choices set, the environment variable
of extra ROS arguments) or a process (``can_sim``, RViz). Whether a node is essential or a
helper is ``node_roles``'s.

``launch/mover6.launch.py`` imports this module: it declares ``OPTIONS`` as launch arguments
and starts ``plan`` of their values. ``scripts/launch.sh`` runs ``python3 -m
mover6_control.stack shell ARGS``, which parses its options (``--help`` prints them), and
evaluates the shell lines it prints: the options' values, then a ``start`` line per node.

ROS-free (the base layer); the namespace is checked by ROS's naming rules in the launchers.
"""

import argparse
from dataclasses import dataclass, field
import shlex
import sys

from mover6_control.parameters import CONTROLLER
import yaml

HARDWARE_CHOICES = ('sim', 'can_sim', 'can')
# [s] the controller's state timeout: its parameter's on the simulator, 0.5 s behind the driver
# (it publishes /joint_states at its 20 Hz cycle).
STATE_TIMEOUT = {'sim': CONTROLLER['state_timeout'].default, 'can_sim': 0.5, 'can': 0.5}
DEFAULT_CAN_CHANNEL = '/dev/ttyUSB0'
# The nodes of the stack, each with its parameter file config/<node>.yaml (the launch file's
# ``<node>_params`` arguments; launch.sh passes the installed file).
PARAMETER_FILES = ('sim_bridge', 'driver', 'controller', 'planner', 'state_publisher',
                   'markers')


@dataclass(frozen=True)
class Option:
    """
    One launcher argument: ``name`` as ``ros2 launch`` takes it, ``flag`` as launch.sh does.

    ``choices`` (empty: any text) and ``default`` are the launch argument's; launch.sh spells a
    choice with '-' for '_' when ``dashed``. A ``switch`` is a true/false argument that launch.sh
    gives as a flag without a value (``--rviz``; ``--no-sim`` sets ``sim`` false). ``shell`` is
    False for an argument launch.sh does not take, True for one only launch.sh takes.
    """

    name: str
    flag: str
    default: str
    help: str     # noqa: A003 - argparse's word
    choices: tuple = ()
    dashed: bool = False
    switch: bool = False
    shell: bool = None

    @property
    def in_shell(self):
        """Return True when launch.sh takes this option."""
        return self.shell is not False

    @property
    def in_launch(self):
        """Return True when ``ros2 launch`` takes this argument."""
        return self.shell is not True


def _controller_option(name, flag, help_text):
    """Return the option of controller parameter ``name``: its choices, default first."""
    spec = CONTROLLER[name]
    choices = (spec.default,) + tuple(c for c in spec.allowed if c != spec.default)
    return Option(name, flag, spec.default, help_text, choices)


OPTIONS = (
    Option('namespace', '--namespace', '',
           'namespace of every node, topic, service and action (a second arm: arm2); TF frames '
           'are prefixed with it (ROS naming rules; a malformed one is refused)'),
    Option('sim', '--no-sim', 'true',
           "true: the MuJoCo bridge stands in for the arm; false (--no-sim): a real arm's "
           'driver instead, started on its own', ('true', 'false'), switch=True),
    Option('hardware', '--hardware', 'sim',
           'sim: the MuJoCo bridge; can_sim: the CAN-level Mover6 on a pty (can_sim) and the '
           "driver on it, enabled at start; can: the driver on a real arm's bus "
           '(can_interface, can_channel), enable it with its ~/reset, ~/enable',
           HARDWARE_CHOICES, dashed=True),
    Option('can_interface', '--can-interface', 'cpr_usb2can',
           'bus of the driver with hardware can: cpr_usb2can, socketcan, pcan, ...'),
    Option('can_channel', '--can-channel', '',
           'its channel (/dev/ttyUSB0 by default, can0, ...); with can_sim the link of the pty '
           '(default: in a fresh temporary folder)'),
    _controller_option('profile', '--profile',
                       'controller velocity profile (the planner times its prediction with it '
                       'too)'),
    _controller_option('jog_units', '--jog-units',
                       'JointJog units: rad_per_s (ROS standard) or fraction_of_max (the vendor '
                       'cpr driver; the simulator then runs as that driver)'),
    _controller_option('limit_set', '--limit-set',
                       'joint limits of every node: within_90_deg or hardware (vendor)'),
    Option('rviz', '--rviz', 'false',
           'true: also start RViz (rviz2, where installed) with rviz/mover6.rviz: the arm, /tf, '
           '/markers', ('true', 'false'), switch=True),
    Option('console', '--console', 'false',
           'true: also start the web console on http://127.0.0.1:8080 (docs/console.md; its own '
           'options, --port and --host, in MOVER6_CONSOLE_ARGS)', ('true', 'false'), switch=True),
    Option('log_dir', '--log-dir', '', "also write each node's output to DIR/<node>.log",
           shell=True),
)
OPTION = {option.name: option for option in OPTIONS}
EPILOG = """\
Extra ROS arguments per node: MOVER6_SIM_ARGS, MOVER6_DRIVER_ARGS, MOVER6_CONTROLLER_ARGS,
MOVER6_PLANNER_ARGS, MOVER6_STATE_PUBLISHER_ARGS, MOVER6_MARKERS_ARGS, e.g.
MOVER6_CONTROLLER_ARGS="-p t_max:=2.0"; MOVER6_CAN_SIM_ARGS for can_sim's command line (e.g.
"--home 0 0.3 0 0 0 0"). Parameter files: config/<node>.yaml (docs/parameters.md).
With the driver the controller's state_timeout is 0.5 s (the driver publishes at its 20 Hz).
The timed threads (the controller's tick, the bridge's physics, the driver's cycle) run at
SCHED_FIFO 50 where the system allows it (tick_priority, physics_priority, cycle_priority;
without the right each node says so once and runs at normal scheduling;
MOVER6_CONTROLLER_ARGS="-p tick_priority:=0" turns one off).
Essential nodes (the arm, the driver, the controller) stop the stack when they exit; a helper
(planner, state publisher, markers, RViz) is started again after a back-off delay
(mover6_control/node_roles.py). DDS stays on this machine (docs/dds.md)."""


@dataclass(frozen=True)
class Start:
    """
    One thing to start: a node of this package (``kind`` 'node'), ``can_sim``, RViz or the console.

    A node gets its parameter file (``config/<name>.yaml``, one of ``PARAMETER_FILES``), then
    ``parameters`` (the choices' values, in order), then the ROS arguments in environment
    variable ``extra_args``; can_sim gets ``--link`` ``parameters['link']`` and those.
    """

    name: str
    executable: str
    kind: str = 'node'
    parameters: dict = field(default_factory=dict)
    extra_args: str = ''


def frame_prefix(namespace):
    """Return the TF frame prefix of a namespace: '/arm1' -> 'arm1/', '' or '/' -> ''."""
    name = namespace.strip('/')
    return f'{name}/' if name else ''


def resolve(choices):
    """
    Return every option's value: ``choices`` (name: text) over the defaults, checked.

    Raise ``ValueError`` naming the option and its choices for a value not among them.
    """
    values = {option.name: option.default for option in OPTIONS}
    for name, value in choices.items():
        if name not in OPTION:
            raise ValueError(f'unknown option {name}')
        option = OPTION[name]
        if option.choices and value not in option.choices:
            raise ValueError(f'{option.flag} must be one of: {" ".join(option.choices)}; got '
                             f"'{value}'")
        values[name] = value
    return values


def plan(choices):
    """Return the ``Start``s of the stack for ``choices`` (option name: text), in order."""
    v = resolve(choices)
    hardware = v['hardware']
    with_driver = hardware != 'sim'
    prefix = frame_prefix(v['namespace'])
    starts = []
    if v['sim'] == 'true' and not with_driver:
        starts.append(Start('sim_bridge', 'sim_bridge', extra_args='MOVER6_SIM_ARGS', parameters={
            'limit_set': v['limit_set'],
            # The simulator stands in for the vendor driver when the controller speaks its units.
            'mode': 'vendor_driver' if v['jog_units'] == 'fraction_of_max' else 'rad_per_s'}))
    if hardware == 'can_sim':
        starts.append(Start('can_sim', 'can_sim', kind='process',
                            extra_args='MOVER6_CAN_SIM_ARGS',
                            parameters={'link': v['can_channel']}))
    if with_driver:
        channel = v['can_channel'] or (DEFAULT_CAN_CHANNEL if hardware == 'can' else '')
        starts.append(Start('driver', 'driver', extra_args='MOVER6_DRIVER_ARGS', parameters={
            'can_interface': 'cpr_usb2can' if hardware == 'can_sim' else v['can_interface'],
            'can_channel': channel, 'jog_units': v['jog_units'], 'limit_set': v['limit_set'],
            'enable_on_start': hardware == 'can_sim'}))
    starts += [
        Start('controller', 'controller', extra_args='MOVER6_CONTROLLER_ARGS', parameters={
            'profile': v['profile'], 'jog_units': v['jog_units'], 'limit_set': v['limit_set'],
            'state_timeout': STATE_TIMEOUT[hardware],
            # The driver integrates set-points at its cycle: compensate what is in flight.
            'cycle_driver': with_driver}),
        Start('planner', 'planner', extra_args='MOVER6_PLANNER_ARGS',
              parameters={'limit_set': v['limit_set'], 'profile': v['profile']}),
        # /robot_description, /tf and /tf_static for RViz (robot_state_publisher's topics).
        Start('state_publisher', 'state_publisher', extra_args='MOVER6_STATE_PUBLISHER_ARGS',
              parameters={'frame_prefix': prefix}),
        # The goal, the planned tool path, the table and the keep-out boxes on /markers.
        Start('markers', 'markers', extra_args='MOVER6_MARKERS_ARGS',
              parameters={'frame_prefix': prefix}),
    ]
    if v['rviz'] == 'true':
        starts.append(Start('rviz2', 'rviz2', kind='rviz'))
    if v['console'] == 'true':
        # The web console: its own options (--port, --host) come before its ROS arguments.
        starts.append(Start('console', 'console', extra_args='MOVER6_CONSOLE_ARGS',
                            kind='console'))
    return starts


def parameter_text(value):
    """Return ``value`` as the text of a ``-p name:=value`` ROS argument (YAML, typed)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return repr(value)
    return yaml.safe_dump(value, default_style=None).strip().removesuffix('...').strip()


def shell_lines(starts):
    """Return launch.sh's start lines (its functions start, start_can_sim, start_command)."""
    lines = []
    for s in starts:
        hook = f' ${{{s.extra_args}:-}}' if s.extra_args else ''
        if s.kind == 'process':
            lines.append('start_can_sim')
        elif s.kind == 'rviz':
            lines.append('start_command rviz2 "$(command -v rviz2)" '
                         '-d "$prefix/share/mover6_control/rviz/mover6.rviz"')
        elif s.kind == 'console':
            lines.append(f'start_command console "$bin/console"{hook} '
                         '--ros-args "${ns_args[@]}"')
        else:
            args = ' '.join(f'-p {shlex.quote(f"{k}:={parameter_text(v)}")}'
                            for k, v in s.parameters.items())
            lines.append(f'start {s.name} {s.executable} {args}{hook}')
    return lines


def parser():
    """Return the argument parser of launch.sh (its ``--help``)."""
    p = argparse.ArgumentParser(
        prog='scripts/launch.sh', epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description='Start the mover6_control nodes (the arm: sim_bridge or the CAN driver; '
                    'controller, planner; the state publisher: /robot_description, /tf; the '
                    'markers) and keep them running until Ctrl-C. launch/mover6.launch.py '
                    '(ros2 launch mover6_control mover6.launch.py) takes the same arguments as '
                    'name:=value.')
    for option in OPTIONS:
        if not option.in_shell:
            continue
        if option.switch:
            p.add_argument(option.flag, dest=option.name, action='store_const',
                           const='false' if option.flag.startswith('--no-') else 'true',
                           default=option.default, help=f'{option.help}')
            continue
        shown = tuple(c.replace('_', '-') for c in option.choices) if option.dashed \
            else option.choices
        words = f' ({" | ".join(shown)}; default {shown[0]})' if shown else ''
        p.add_argument(option.flag, dest=option.name, default=option.default,
                       metavar=option.flag.lstrip('-').split('-')[-1].upper(),
                       help=f'{option.help}{words}')
    return p


def spelled(option, value):
    """Return a value as launch.sh spells it ('-' for '_' in a dashed option's choice)."""
    return value.replace('_', '-') if option.dashed else value


def parse_shell(argv):
    """Return the option values of launch.sh's arguments ``argv`` (exit 2 when malformed)."""
    p = parser()
    args = vars(p.parse_args(argv))
    for option in OPTIONS:
        value = args.get(option.name)
        if option.in_shell and option.choices and not option.switch:
            shown = [spelled(option, c) for c in option.choices]
            if value not in shown:
                p.exit(2, f'launch.sh: {option.flag} must be one of: {" ".join(shown)}; got '
                       f"'{value}'\n")
            args[option.name] = option.choices[shown.index(value)]
    return resolve(args)


def shell(argv, can_channel=None):
    """
    Return what launch.sh evaluates for its arguments ``argv``: values, then start lines.

    The values: every option as a shell variable (``hardware`` as launch.sh spells it, with
    '-'); ``can_channel`` replaces the option's (launch.sh's pty link for can-sim).
    """
    values = parse_shell(argv)
    if can_channel is not None:
        values['can_channel'] = can_channel
    out = [f'{name}={shlex.quote(spelled(OPTION[name], value))}'
           for name, value in values.items()]
    starts = plan({k: v for k, v in values.items() if OPTION[k].in_launch})
    body = '\n'.join(f'    {line}' for line in shell_lines(starts))
    out.append(f'start_stack() {{\n{body}\n}}')
    return '\n'.join(out) + '\n'


def main(argv):
    """``shell [--channel C] -- ARGS``: print launch.sh's values and start lines for ARGS."""
    if argv[:1] == ['help']:
        parser().print_help()
        return
    if argv[:1] != ['shell']:
        sys.exit('usage: python -m mover6_control.stack help | shell [--channel C] -- ARGS')
    rest = argv[1:]
    channel = None
    if rest[:1] == ['--channel']:
        channel, rest = rest[1], rest[2:]
    if rest[:1] == ['--']:
        rest = rest[1:]
    sys.stdout.write(shell(rest, channel))


if __name__ == '__main__':
    main(sys.argv[1:])
