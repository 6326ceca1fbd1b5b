"""
The parameters of every node, declared once: name, type, default, unit, range, meaning.

``PLANNER``, ``CONTROLLER``, ``SIM_BRIDGE``, ``DRIVER``, ``STATE_PUBLISHER``, ``MARKERS`` and
``RECORDER`` (``NODES``, by node name) map each parameter name to a frozen ``ParameterSpec``.
The nodes declare their ROS parameters from these tables (with the range or the allowed values
in the descriptor, ``ros2 param describe`` shows them) and refuse a value that ``check_value``
refuses; ``config/<node>.yaml`` and ``docs/parameters.md`` are generated from them (``./run.sh
generate``, ``parameter_files``) and the defaults of the core's settings dataclasses are checked
against them by the tests.

ROS-free and in the base layer, so every layer can import it: the tables of allowed values are
defined here once (``PROFILES``, ``LIMIT_SETS``, ``JOG_UNITS``, ``TOOL_SHAPES``, ``POSE_MOTIONS``,
``PATH_MOTIONS``, ``SIM_MODES``) and the core imports them from here (a test checks that the core
takes every one of them); the Mover6's encoder ticks are written out (a test checks that they
are ``MOVER6_TICK_SIZE``).
"""

from dataclasses import dataclass
import math

from mover6_control.errors import InvalidInputError

TYPES = ('bool', 'int', 'float', 'str', 'float_list')

_PYTHON_TYPES = {'bool': (bool,), 'int': (int,), 'float': (float,), 'str': (str,)}


@dataclass(frozen=True)
class ParameterSpec:
    """
    One node parameter.

    ``type`` is one of ``TYPES``. ``minimum`` and ``maximum`` (inclusive, numbers only; for a
    ``float_list`` they bound every element) or ``allowed`` (strings only) say which values are
    valid; a ``float_list`` has exactly ``length`` values, or a multiple of ``multiple_of``
    (0: any number but none); ``read_only`` parameters are set at start and cannot change while
    the node runs. What relates one parameter to another (a capsule tool at least as long as
    wide) is checked by the node's whole configuration (``nodes.runtime.params.declare``).
    """

    name: str
    type: str     # noqa: A003 - the word users read in the table
    default: object
    unit: str
    description: str
    minimum: float = None
    maximum: float = None
    allowed: tuple = ()
    read_only: bool = False
    length: int = 0
    multiple_of: int = 0

    def __post_init__(self):
        """Check the spec itself, and that its default is a valid value."""
        if self.type not in TYPES:
            raise InvalidInputError(f'{self.name}: type must be one of {TYPES}, got {self.type}')
        if (self.minimum is None) != (self.maximum is None):
            raise InvalidInputError(f'{self.name}: give both minimum and maximum, or neither')
        if self.minimum is not None and self.type not in ('int', 'float', 'float_list'):
            raise InvalidInputError(f'{self.name}: a range needs a numeric type')
        if self.allowed and self.type != 'str':
            raise InvalidInputError(f'{self.name}: allowed values need type str')
        if (self.length or self.multiple_of) and self.type != 'float_list':
            raise InvalidInputError(f'{self.name}: a length needs type float_list')
        if isinstance(self.default, list):
            object.__setattr__(self, 'default', tuple(self.default))
        check_value(self, self.default)

    @property
    def has_range(self):
        """Return True when the value (or every element) must lie in [minimum, maximum]."""
        return self.minimum is not None

    def constraints(self):
        """Return the constraints in words ('' when there are none)."""
        if self.allowed:
            return 'one of: ' + ', '.join(self.allowed)
        words = []
        if self.has_range:
            each = 'each value ' if self.type == 'float_list' else ''
            words.append(f'{each}from {self.minimum:g} to {self.maximum:g}')
        if self.length:
            words.append(f'exactly {self.length} values')
        elif self.multiple_of:
            words.append(f'{self.multiple_of} values per entry')
        return '; '.join(words)


def _type_ok(spec, value):
    if spec.type == 'float_list':
        return (isinstance(value, (list, tuple)) and len(value) > 0
                and all(isinstance(v, float) for v in value))
    if spec.type in ('int', 'float') and isinstance(value, bool):
        return False
    return isinstance(value, _PYTHON_TYPES[spec.type])


def check_value(spec, value):
    """
    Raise ``InvalidInputError`` saying why ``value`` is not valid for ``spec``.

    Valid: of the spec's type (a float is not an int and back; a ``float_list`` is a non-empty
    list of floats, of ``length`` values or a multiple of ``multiple_of``), finite, within
    [minimum, maximum] (every element for a list), and among the allowed values. The reason
    quotes a long value by its length and first values only.
    """
    if not _type_ok(spec, value):
        raise InvalidInputError(
            f'{spec.name} must be of type {spec.type}, got {_short(value)} '
            f'({type(value).__name__})')
    if spec.type == 'float_list':
        n = len(value)
        if spec.length and n != spec.length:
            raise InvalidInputError(f'{spec.name} must have exactly {spec.length} values, got '
                                    f'{n}: {_short(value)}')
        if spec.multiple_of and n % spec.multiple_of:
            raise InvalidInputError(f'{spec.name} must have {spec.multiple_of} values per entry '
                                    f'(a multiple of {spec.multiple_of}), got {n}: '
                                    f'{_short(value)}')
    numbers = value if spec.type == 'float_list' else (
        [value] if spec.type in ('int', 'float') else [])
    for number in numbers:
        if not math.isfinite(number):
            raise InvalidInputError(f'{spec.name} must be finite, got {_short(value)}')
        if spec.has_range and not spec.minimum <= number <= spec.maximum:
            raise InvalidInputError(
                f'{spec.name} must be {spec.constraints()} {spec.unit}'.rstrip()
                + f', got {_short(value)}')
    if spec.allowed and value not in spec.allowed:
        raise InvalidInputError(f'{spec.name} must be {spec.constraints()}, got {_short(value)}')


def _short(value, most=8):
    """Return ``repr(value)``; a long list as its first ``most`` values and its length."""
    if isinstance(value, (list, tuple)) and len(value) > most:
        head = ', '.join(repr(v) for v in value[:most])
        return f'[{head}, ...] ({len(value)} values)'
    text = repr(value)
    return text if len(text) <= 200 else text[:200] + f'... ({len(text)} characters)'


def _table(*specs):
    """Return ``{name: spec}`` in the given order, refusing a name given twice."""
    table = {}
    for spec in specs:
        if spec.name in table:
            raise InvalidInputError(f'parameter {spec.name} declared twice')
        table[spec.name] = spec
    return table


P = ParameterSpec
PI = math.pi
# The joint limits of the arm model (kinematics.arm.mover6).
LIMIT_SETS = ('within_90_deg', 'hardware')
LIMIT_SET_TEXT = ('joint limits: within_90_deg (every joint in [-pi/2, pi/2], the limits of the '
                  "Mover6 report) or hardware (the vendor's limits); set at start")
# One encoder tick of each Mover6 joint [rad], as the vendor driver moves them (kinematics.arm
# derives them from the gear ratios as MOVER6_TICK_SIZE; a test checks they agree).
MOVER6_TICKS = (8.260740495997393e-06, 8.260740495997393e-06, 8.260740495997393e-06,
                8.742382548559054e-06, 0.006135923151542565, 0.006135923151542565)

# The controller's profiles: every time law a motion can be timed by (their laws:
# control.profiles).
PROFILES = ('synchronised', 'trapezoidal', 'jerk_limited', 'continuous',
            'cubic', 'quintic', 'septic', 'sharp_trapezoid',
            'cubic_spline', 'quintic_spline', 'bspline', 'multi_trapezoid')
PROFILE_TEXT = (
    'velocity law: continuous (through every waypoint, time-optimal), synchronised (all '
    'joints arrive together), trapezoidal (stop at each waypoint, as the Mover6 report), '
    'jerk_limited; stopping at each waypoint within the velocity limits and a_max: cubic, '
    'quintic (3-4-5), septic (4-5-6-7), sharp_trapezoid; through all waypoints within them: '
    'cubic_spline, quintic_spline, bspline, multi_trapezoid')

# JointJog velocities: ROS's rad/s, or fractions of each joint's maximum speed (the vendor driver).
JOG_UNITS = ('rad_per_s', 'fraction_of_max')
# The shapes of a pose goal's and a path goal's motion (planning.planner_core).
POSE_MOTIONS = ('linear', 'parabolic', 'joint')
PATH_MOTIONS = ('spline', 'arc', 'parabolic')
# What the simulator behaves as (sim_bridge.simulator): a rad/s driver or the vendor's driver.
SIM_MODES = ('rad_per_s', 'vendor_driver')

# The collision check of the planner and the controller (mover6_control.collision): the same
# parameters on both nodes. The tool volumes on the flange (collision.geometry.ToolVolume).
TOOL_SHAPES = ('capsule', 'box', 'none')
# [m] the smallest table margin the Mover6's body needs: collision.body_model.MIN_TABLE_MARGIN,
# derived from its meshes (every vertex of links 1 to 6 is inside their shapes, so the shapes
# kept above the table keep the real arm above it); written out here, a test checks they agree.
BODY_MIN_TABLE_MARGIN = 0.0


def _collision_specs(who):
    """Return the collision-check parameters of the planner or the controller (``who``)."""
    return (
        P('collision_check', 'bool', True, '',
          f'check every motion {who}, swept between its waypoints, against the table, the arm '
          'itself and the keep-out boxes; refuse one that touches'),
        P('tool_shape', 'str', 'capsule', '',
          'volume of the tool on the flange for the collision check: capsule, box or none',
          allowed=TOOL_SHAPES),
        P('tool_size', 'float_list', (0.06, 0.06, 0.08), 'm',
          'tool width (flange x), depth (flange y) and length (along the flange z axis, from '
          'the flange); a capsule is max(width, depth) across and at least that long (default: '
          'a small gripper); a tool that puts the arm in collision where it stands is refused',
          0.001, 1.0, length=3),
        P('table_margin', 'float', 0.02, 'm',
          'clearance every part of the arm and tool keeps above the table (z = 0 of base_link); '
          "at least what the Mover6's body needs (its meshes inside the collision shapes: "
          f'{BODY_MIN_TABLE_MARGIN * 1e3:g} mm); refused when the arm stands in it',
          BODY_MIN_TABLE_MARGIN, 0.5),
        P('keep_out_boxes', 'float_list', (0.0,) * 6, 'm',
          'keep-out zones in base_link, 6 values per box: x, y, z min then x, y, z max, no max '
          'below its min; a box without volume is none (default: none); a box the arm stands '
          'in is refused', -5.0, 5.0,
          multiple_of=6),
        P('collision_step', 'float', 0.01, 'rad',
          'largest joint step between two checked samples of a motion', 0.0005, 0.5),
    )


PLANNER = _table(
    P('motion', 'str', 'linear', '', 'shape of /pose_goal moves',
      allowed=POSE_MOTIONS),
    P('path_motion', 'str', 'spline', '',
      'shape of /path_goal moves (through the via poses; parabolic: one via pose, the peak)',
      allowed=PATH_MOTIONS),
    P('n_waypoints', 'int', 20, '',
      'poses sampled along a Cartesian path (when max_step and max_angle_step are 0)', 2, 10000),
    P('max_step', 'float', 0.0, 'm',
      'largest Cartesian step between waypoints; 0 = use n_waypoints', 0.0, 1.0),
    P('max_angle_step', 'float', 0.0, 'rad',
      'largest orientation step between waypoints; 0 = use n_waypoints', 0.0, PI),
    P('peak_height', 'float', 0.05, 'm',
      'parabolic moves: height of the peak above the straight line mid-point, along base z',
      -0.5, 0.5),
    P('max_joint_step', 'float', 0.35, 'rad',
      'largest joint jump between neighbouring waypoints before a path is refused', 0.001, PI),
    P('max_condition', 'float', 1000.0, '',
      'largest Jacobian condition number allowed along the path (margin to singularities)',
      1.0, 1e9),
    P('position_tolerance', 'float', 0.001, 'm',
      'largest position error of any waypoint, the last included', 1e-6, 0.1),
    P('orientation_tolerance', 'float', 0.01, 'rad',
      'largest orientation error of any waypoint, the last included', 1e-6, 1.0),
    P('limit_set', 'str', 'within_90_deg', '', LIMIT_SET_TEXT, allowed=LIMIT_SETS,
      read_only=True),
    P('frame_id', 'str', 'base_link', '', 'the only frame goals are accepted in'),
    P('state_timeout', 'float', 1.0, 's',
      '/joint_states older than this are too old to plan from', 0.01, 60.0),
    P('state_wait_timeout', 'float', 5.0, 's',
      'a goal that comes before fresh /joint_states waits this long for them before it is '
      'refused (0: refused at once)', 0.0, 60.0),
    P('match_timeout', 'float', 3.0, 's',
      'longest wait for /joint_demands readers to be matched before publishing a plan',
      0.0, 60.0),
    P('profile', 'str', 'continuous', '',
      "the controller's velocity law the predicted duration is timed with (set it as the "
      "controller's profile; its other law parameters are the controller's defaults)",
      allowed=PROFILES),
    *_collision_specs('it plans'),
)

CONTROLLER = _table(
    P('rate', 'float', 100.0, 'Hz', 'control rate: one /JointJog per tick', 1.0, 1000.0),
    P('profile', 'str', 'continuous', '', PROFILE_TEXT, allowed=PROFILES),
    P('lambda_max', 'float', 0.5, 'rad/s',
      'synchronised: speed of the joint with the furthest to go (the Mover6 report eq. 1)',
      0.001, 10.0),
    P('t_max', 'float', 1.0, 's',
      'trapezoidal: time of each move (stretched to respect the velocity limits)', 0.01, 600.0),
    P('t_blend', 'float', 0.0, 's',
      'trapezoidal: ramp time, at most t_max / 2; 0 = t_max / 4 (the Mover6 report)',
      0.0, 300.0),
    P('a_max', 'float', 1.0, 'rad/s^2',
      'acceleration limit of every law but synchronised and trapezoidal, and of every stop',
      0.001, 100.0),
    P('j_max', 'float', 5.0, 'rad/s^3', 'jerk limit of jerk_limited', 0.001, 1000.0),
    P('goal_tolerance', 'float', 0.002, 'rad', 'arrived when every joint is this close',
      1e-6, 0.5),
    P('state_timeout', 'float', 0.25, 's',
      '/joint_states older than this: zero command and fault', 0.001, 10.0),
    P('position_gain', 'float', 2.0, '1/s', 'closed-loop gain on the position error',
      0.0, 100.0),
    P('settle_timeout', 'float', 3.0, 's', 'give up settling into the goal tolerance after',
      0.01, 600.0),
    P('settle_tolerance', 'float', 0.0001, 'rad',
      'after arriving, keep converging until every joint is this close (fraction_of_max or '
      'cycle_driver: one tick), then hold with a zero command', 1e-7, 0.5),
    P('settle_time', 'float', 1.0, 's',
      'after arriving, converge for at most this long, then hold with a zero command',
      0.0, 60.0),
    P('path_tolerance', 'float', 0.3, 'rad',
      'tracking error that aborts a motion with a controlled stop', 0.001, 2.0 * PI),
    P('jog_units', 'str', 'rad_per_s', '',
      'JointJog velocities: rad_per_s (ROS standard) or fraction_of_max (the vendor driver: '
      "fractions of each joint's maximum speed); set at start: it must match the driver's "
      'units, fixed while the driver runs', allowed=JOG_UNITS,
      read_only=True),
    P('speed_override', 'float', 0.25, '',
      'fraction_of_max: speed override of the vendor driver', 0.01, 1.0),
    P('driver_tick_size', 'float_list', MOVER6_TICKS, 'rad',
      "fraction_of_max: one encoder tick per joint (default the Mover6's): commands under one "
      'tick per cycle are lifted to it near the goal; goal tolerance at least one tick',
      1e-9, 1.0, length=len(MOVER6_TICKS)),
    P('driver_cycle', 'float', 0.05, 's',
      'fraction_of_max: cycle of the vendor driver (20 Hz)', 0.001, 1.0),
    P('cycle_driver', 'bool', False, '',
      'the driver integrates /JointJog into set-points every driver_cycle and reports once a '
      'cycle (the CAN driver): compensate what is in flight and settle by whole ticks as in '
      'fraction_of_max, either unit',
      read_only=True),
    P('limit_set', 'str', 'within_90_deg', '', LIMIT_SET_TEXT, allowed=LIMIT_SETS,
      read_only=True),
    P('status_rate', 'float', 5.0, 'Hz', 'rate of /controller/status between state changes',
      0.1, 100.0),
    P('tick_priority', 'int', 50, '',
      "real-time priority (SCHED_FIFO 1 to 99) of the tick thread, the node's other threads "
      "one below (as ros2_control's controller manager); 0 = off (normal scheduling); refused "
      'without the right (logged once, normal scheduling then); set at start', 0, 99,
      read_only=True),
    P('servo_command_timeout', 'float', 0.1, 's',
      'jogging: a twist or joint jog older than this (by its stamp) decelerates the arm to rest',
      0.001, 10.0),
    P('servo_pose_gain', 'float', 5.0, '1/s',
      'jogging: gain holding the tool on the commanded line and orientation', 0.0, 100.0),
    P('servo_damping', 'float', 0.01, '',
      'jogging: damped least squares factor on the Jacobian normalised by the reach', 0.0, 1.0),
    P('servo_lower_singularity_threshold', 'float', 17.0, '',
      'jogging: condition number (Jacobian normalised by the reach) where a motion towards a '
      'singularity starts slowing down', 1.0, 1e6),
    P('servo_hard_stop_singularity_threshold', 'float', 30.0, '',
      'jogging: condition number where a motion towards a singularity halts (above the lower '
      'threshold)', 1.0, 1e6),
    P('servo_joint_limit_margin', 'float', 0.1, 'rad',
      'jogging: a joint this close to a limit halts the motion towards it', 0.0, 1.0),
    P('allow_partial_joints_goal', 'bool', False, '',
      "follow_joint_trajectory (joint_trajectory_controller's name and default): a goal may "
      'name only some joints; the others hold where they are'),
    P('constraints.stopped_velocity_tolerance', 'float', 0.01, 'rad/s',
      "follow_joint_trajectory (joint_trajectory_controller's): after the last point's time "
      'every joint must be slower than this (unless the goal gives a velocity goal tolerance); '
      '0 = not checked', 0.0, 10.0),
    P('constraints.goal_time', 'float', 0.0, 's',
      "follow_joint_trajectory (joint_trajectory_controller's): the goal tolerances must hold "
      "this long after the last point's time, else GOAL_TOLERANCE_VIOLATED (a goal's "
      'goal_time_tolerance replaces it); 0 = no limit but settle_timeout', 0.0, 600.0),
    P('action_monitor_rate', 'float', 20.0, 'Hz',
      "follow_joint_trajectory (joint_trajectory_controller's): rate of the goal's feedback and "
      'of its checks against the tolerances', 0.1, 1000.0, read_only=True),
    P('speed_scaling.initial_scaling_factor', 'float', 1.0, '',
      "the speed scaling factor at start (joint_trajectory_controller's): 1 = the motions' own "
      'timing, 0 = paused; ~/speed_scaling_input changes it while running', 0.0, 1.0,
      read_only=True),
    *_collision_specs('it is sent directly (/joint_demands, the trajectory action)'),
)

SIM_BRIDGE = _table(
    P('physics_dt', 'float', 0.002, 's',
      'fixed physics step (0.001 to 0.002 recommended); set at start', 0.0001, 0.01,
      read_only=True),
    P('real_time_factor', 'float', 1.0, '',
      'sim time per wall time; 0 runs as fast as it can', 0.0, 100.0),
    P('publish_rate', 'float', 100.0, 'Hz',
      '/joint_states rate of sim time (rad_per_s mode; vendor_driver: the driver cycle)',
      0.1, 500.0),
    P('rest_publish_rate', 'float', 20.0, 'Hz',
      '/joint_states rate while the arm rests (rad_per_s mode: no command moves it, every '
      'joint slower than 1e-4 rad/s), as the real arm publishes at 10 to 20 Hz; a command that '
      'moves it brings publish_rate back at its first step; at or above publish_rate: one rate',
      0.1, 500.0),
    P('command_timeout', 'float', 0.2, 's',
      'a /JointJog older than this (by receive time, sim clock) halts the joints; set at '
      'start: the simulator is built with it', 0.001, 10.0, read_only=True),
    P('mode', 'str', 'rad_per_s', '',
      'JointJog units and driver behaviour: rad_per_s (ROS standard) or vendor_driver (behaves '
      'like the vendor driver: fractions, 20 Hz cycle, whole encoder ticks); set at start',
      allowed=SIM_MODES, read_only=True),
    P('speed_override', 'float', 0.25, '',
      'vendor_driver: speed = fraction * max speed * speed_override; set at start: the '
      'simulator is built with it', 0.01, 1.0, read_only=True),
    P('limit_set', 'str', 'within_90_deg', '', LIMIT_SET_TEXT, allowed=LIMIT_SETS,
      read_only=True),
    P('urdf_path', 'str', '', '',
      'URDF of the arm; empty = the shipped Mover6 (config/mover6.urdf) with limit_set; '
      'set at start', read_only=True),
    P('initial_q', 'float_list', (0.0,) * 6, 'rad',
      'start and home configuration, one value per joint; set at start', -PI, PI,
      read_only=True),
    P('publish_clock', 'bool', False, '',
      'publish /clock after every physics step and stamp with sim time; set at start',
      read_only=True),
    P('physics_priority', 'int', 50, '',
      "real-time priority (SCHED_FIFO 1 to 99) of the physics thread, the node's other threads "
      'one below (unpaced, real_time_factor 0: normal scheduling); 0 = off (normal '
      'scheduling); refused without the right (logged once, normal scheduling then); set at '
      'start', 0, 99, read_only=True),
    P('viewer', 'bool', False, '',
      'open the MuJoCo viewer when a display exists (headless otherwise); set at start',
      read_only=True),
    P('kv', 'float', 1000.0, 'N m s/rad',
      'joint velocity servo gain; set at start: the MuJoCo model is built with it',
      0.001, 1e6, read_only=True),
    P('damping', 'float', 0.5, 'N m s/rad',
      'joint viscous damping; set at start: the MuJoCo model is built with it', 0.0, 1e4,
      read_only=True),
)

# The driver of the real arm (nodes/driver/, hardware/driver.py).
DRIVER = _table(
    P('can_interface', 'str', 'cpr_usb2can', '',
      "CAN adapter: cpr_usb2can (the vendor's USB2CAN serial adapter) or a python-can "
      'interface name (socketcan, pcan, virtual, ...); set at start', read_only=True),
    P('can_channel', 'str', '/dev/ttyUSB0', '',
      'the adapter: a serial device for cpr_usb2can (/dev/ttyUSB0, a pty), a CAN interface '
      '(can0) or channel otherwise; set at start', read_only=True),
    P('bitrate', 'int', 500000, 'bit/s',
      "CAN bit rate (the Mover6's: 500000; the USB2CAN adapter sets its own); set at start",
      10000, 1000000, read_only=True),
    P('cycle', 'float', 0.05, 's',
      'driver cycle: one set-point per module per cycle (the vendor: 50 ms)', 0.005, 0.5),
    P('cycle_priority', 'int', 50, '',
      "real-time priority (SCHED_FIFO 1 to 99) of the cycle thread, the node's other threads "
      'one below; 0 = off (normal scheduling); refused without the right (logged once, normal '
      'scheduling then); set at start', 0, 99, read_only=True),
    P('command_timeout', 'float', 0.2, 's',
      'a JointJog older than this stops the arm: the set-points hold', 0.01, 5.0),
    P('jog_units', 'str', 'rad_per_s', '',
      'JointJog velocities: rad_per_s (ROS standard) or fraction_of_max (the vendor driver: '
      "fractions of each joint's maximum speed times speed_override); set at start",
      allowed=JOG_UNITS, read_only=True),
    P('speed_override', 'float', 0.25, '',
      "fraction_of_max: the vendor driver's speed override", 0.01, 1.0),
    P('enable_on_start', 'bool', False, '',
      'reset and enable the motors once every module answers; set at start', read_only=True),
    P('limit_set', 'str', 'hardware', '',
      'set-points are clamped to these joint limits, always within the hardware ones: '
      "hardware (the vendor's, the default: an arm parked outside [-pi/2, pi/2] is not pulled "
      'in at enable) or within_90_deg; set at start', allowed=LIMIT_SETS, read_only=True),
    P('joints_file', 'str', '', '',
      "joint scaling YAML (gears, ticks, offsets, limits); '' = the shipped "
      'config/mover6_joints.yaml; set at start', read_only=True),
    P('max_lag', 'float', 0.2, 'rad',
      'a set-point stays within this of the measured position', 0.001, 1.0),
    P('silent_cycles', 'int', 6, '',
      'a module that misses this many replies in a row is a fault (until ~/reset); the first '
      'missed reply already holds the arm', 1, 100, read_only=True),
    P('frame_gap', 'float', 0.005, 's',
      "time between two frames sent (the vendor's 5 ms): six set-points take 25 ms of the "
      'cycle', 0.0, 0.006, read_only=True),
    P('frame_log', 'str', '', '',
      "every frame sent and read, with its direction, to this file (python-can's writer by "
      "the suffix: .log candump's format); '' = none; set at start", read_only=True),
    P('calibration_file', 'str', '', '',
      "first_run's calibration file (per joint: direction and scale confirmed); a direction "
      "seen wrong with the gear the joint still has refuses the start; '' = none; set at start",
      read_only=True),
    P('listen_only', 'bool', False, '',
      'send nothing: decode and publish what the modules answer to another master on the bus '
      '(every request refused); set at start', read_only=True),
    P('allow_set_zero', 'bool', False, '',
      '~/set_zero is refused unless this is true (it redefines every joint zero)'),
    P('request_timeout', 'float', 2.0, 's',
      '~/reset, ~/enable, ~/disable, ~/set_zero: answer false when the modules do not confirm '
      'within this', 0.1, 60.0),
    P('reference_timeout', 'float', 60.0, 's',
      '~/reference: time for each joint to report itself referenced', 1.0, 600.0),
    P('gripper', 'str', 'off', '',
      "the Mover6's gripper on joint 4's digital outputs: off, open or closed",
      allowed=('off', 'open', 'closed')),
    P('digital_outputs', 'int', 0, '',
      "joint 1's digital outputs 1-4 as bits 0-3", 0, 15),
    P('diagnostics_rate', 'float', 5.0, 'Hz',
      '/diagnostics between changes (each change of state or hold is sent at once)',
      0.1, 50.0),
)

# The package's own state publisher (nodes/state_publisher/node.py): robot_state_publisher's
# parameters of the same names, where the ROS install has no robot_state_publisher.
STATE_PUBLISHER = _table(
    P('robot_description', 'str', '', '',
      'URDF text published on /robot_description and used for /tf; empty = the shipped Mover6 '
      '(config/mover6.urdf); set at start', read_only=True),
    P('publish_frequency', 'float', 20.0, 'Hz',
      'largest rate of /tf (one message per /joint_states, at most this often)', 0.1, 1000.0),
    P('frame_prefix', 'str', '', '',
      'prefix of every frame id on /tf and /tf_static (e.g. arm1/); set at start',
      read_only=True),
)

# The markers node (nodes/markers/node.py): RViz markers of the goal, the planned tool path, the
# table and the keep-out boxes.
_PLANNER_COLLISION = {spec.name: spec for spec in _collision_specs('by the planner')}
MARKERS = _table(
    P('frame_id', 'str', 'base_link', '', "frame of the markers (the planner's frame_id)"),
    P('frame_prefix', 'str', '', '',
      "prefix of the frame (the state publisher's frame_prefix); set at start", read_only=True),
    P('planner_node', 'str', 'planner', '',
      'node whose table_margin and keep_out_boxes are shown (followed as they change); empty: '
      "this node's own; set at start", read_only=True),
    P('table_size', 'float', 1.0, 'm', 'side of the table slab shown', 0.01, 20.0),
    _PLANNER_COLLISION['table_margin'],
    _PLANNER_COLLISION['keep_out_boxes'],
)

# The recorder (nodes/recorder/node.py): a rosbag2-layout MCAP recording of the stack's topics.
# The goals: /pose_goal and /path_goal, and their shape topics (the planner's motion and
# path_motion choices) and /path_goal/joint.
RECORDED_TOPICS = (
    ('joint_states', 'JointJog', 'joint_demands', 'pose_goal', 'path_goal')
    + tuple(f'pose_goal/{m}' for m in PLANNER['motion'].allowed)
    + tuple(f'path_goal/{m}' for m in PLANNER['path_motion'].allowed + ('joint',))
    + ('planner/status', 'controller/status', '/tf', '/tf_static', 'diagnostics',
       'sim_bridge/contacts', 'robot_description', '/parameter_events'))
RECORDER = _table(
    P('path', 'str', '', '',
      'recording folder (must not exist; its folder must be writable); empty = '
      'rosbag2_<date>-<time> in the working folder, as ros2 bag; set at start', read_only=True),
    P('topics', 'str', ' '.join(RECORDED_TOPICS), '',
      'topics to record, separated by spaces (relative names follow the namespace); set at '
      'start', read_only=True),
    P('discovery_period', 'float', 0.2, 's',
      'how often the graph is looked at for the topics not yet recorded', 0.01, 10.0),
)

NODES = {'planner': PLANNER, 'controller': CONTROLLER, 'sim_bridge': SIM_BRIDGE,
         'driver': DRIVER, 'state_publisher': STATE_PUBLISHER, 'markers': MARKERS,
         'recorder': RECORDER}
