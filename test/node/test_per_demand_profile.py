"""A demand's own profile: its label, its motion only (node tests: test_controller_node.py)."""

from core_testing import send_demand, send_states
from geometry_msgs.msg import PoseStamped
from mover6_control.control.controller_config import ControllerConfig
from mover6_control.control.controller_core import ControllerCore
from mover6_control.control.planners import plan_motion
from mover6_control.control.profiles import LawConfig
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import mover6
from mover6_control.nodes.messages import conversions, demand_messages
from mover6_control.tools.goal_cli import run
from mover6_control.tools.goal_convention import EXIT_ARRIVED, EXIT_REFUSED, Outcome
import numpy as np
import pytest
from std_msgs.msg import Float32MultiArray

ARM = mover6()
GOAL = np.array([0.3, -0.2, 0.2, 0.1, -0.1, 0.3])


def labelled(label):
    """Return a one-row demand whose first dimension is labelled ``label``."""
    msg = demand_messages.make_demands(GOAL[None])
    msg.layout.dim[0].label = label
    return msg


# --- the label -------------------------------------------------------------------------------

def test_make_demands_writes_the_profile_after_the_goal_id():
    msg = demand_messages.make_demands(GOAL[None], 'g-1', 'cubic')
    assert msg.layout.dim[0].label == 'waypoints goal g-1 profile cubic'
    assert demand_messages.demand_id_from_msg(msg) == 'g-1'
    assert demand_messages.demand_profile_from_msg(msg) == 'cubic'
    np.testing.assert_allclose(demand_messages.demands_from_msg(msg), GOAL[None], atol=1e-6)


@pytest.mark.parametrize('label, goal_id, profile', [
    ('waypoints', '', ''),
    ('waypoints goal 1.000000000-3', '1.000000000-3', ''),          # what the planner wrote
    ('waypoints profile quintic', '', 'quintic'),                   # typed, no goal id
    ('waypoints profile septic goal abc', 'abc', 'septic'),          # any order
    ('waypoints  goal  abc   profile  bspline ', 'abc', 'bspline'),  # any spacing
    ('rows', '', ''),                                               # not ours: no options
])
def test_labels_ros2_topic_pub_can_type(label, goal_id, profile):
    msg = labelled(label)
    assert demand_messages.demand_id_from_msg(msg) == goal_id
    assert demand_messages.demand_profile_from_msg(msg) == profile


def test_a_flat_demand_carries_no_options():
    msg = Float32MultiArray()
    msg.data = [float(v) for v in GOAL]
    assert demand_messages.demand_options_from_msg(msg) == {}


@pytest.mark.parametrize('label', ['waypoints profile', 'waypoints goal a profile',
                                   'waypoints speed fast', 'waypoints profile cubic profile x'])
def test_a_malformed_label_is_refused_with_the_grammar(label):
    with pytest.raises(InvalidInputError, match=r'waypoints \[goal <id>\] \[profile <name>\]'):
        demand_messages.demand_profile_from_msg(labelled(label))


def test_goal_frame_carries_a_profile_and_stays_a_frame():
    msg = PoseStamped()
    msg.header.frame_id = 'base_link profile quintic'
    assert conversions.goal_profile_from_header(msg.header) == 'quintic'
    conversions.pose_goal_from_msg(msg, 'base_link')        # the frame is still checked
    msg.header.frame_id = 'world profile quintic'
    with pytest.raises(InvalidInputError, match='expected "base_link"') as refused:
        conversions.pose_goal_from_msg(msg, 'base_link')
    assert refused.value.code == 'wrong_frame'
    msg.header.frame_id = 'base_link'
    assert conversions.goal_profile_from_header(msg.header) == ''
    msg.header.frame_id = 'base_link profile a b'
    with pytest.raises(InvalidInputError, match='profile <name>'):
        conversions.goal_profile_from_header(msg.header)


# --- the goal command ------------------------------------------------------------------------

class RecordingClient:
    """Stands in for GoalClient: records how each goal is sent, 'arrives' at once."""

    arm = ARM

    def __init__(self):
        self.sent = []

    def wait_ready(self, **kwargs):
        return None

    def send_pose(self, T, frame_id='base_link', **kwargs):
        self.sent.append(('pose', frame_id, kwargs.get('motion')))
        return Outcome(EXIT_ARRIVED, 'arrived')

    def send_path(self, poses, frame_id='base_link', shape=None, **kwargs):
        self.sent.append(('path', frame_id, shape, len(poses)))
        return Outcome(EXIT_ARRIVED, 'arrived')

    def send_joints(self, Q, profile='', **kwargs):
        self.sent.append(('joints', profile))
        return Outcome(EXIT_ARRIVED, 'arrived')


@pytest.mark.parametrize('argv, sent', [
    (['0.3', '0.05', '0.36', '0', '0', '0', '--profile', 'quintic'],
     ('pose', 'base_link profile quintic', None)),
    (['0.3', '0.05', '0.36', '0', '0', '0'], ('pose', 'base_link', None)),
    (['path', '--shape', 'joint', '--profile', 'cubic', '--via', '0.32', '0', '0.38', '0', '0',
      '0', '0.30', '0.08', '0.34', '0', '0', '0'],
     ('path', 'base_link profile cubic', 'joint', 2)),
    (['joints', '0.2', '0.1', '0.3', '0', '0.4', '0', '--profile', 'bspline'],
     ('joints', 'bspline')),
])
def test_goal_command_sends_the_profile_with_the_goal(argv, sent):
    client = RecordingClient()
    assert run(argv, client, out=lambda text: None) == EXIT_ARRIVED
    assert client.sent == [sent]


def test_goal_command_refuses_an_unknown_profile(capsys):
    with pytest.raises(SystemExit) as exit_:
        run(['0.3', '0.05', '0.36', '0', '0', '0', '--profile', 'banana'], RecordingClient())
    assert exit_.value.code == EXIT_REFUSED
    assert "invalid choice: 'banana'" in capsys.readouterr().err


# --- the core --------------------------------------------------------------------------------

def started_core(profile='trapezoidal'):
    core = ControllerCore(ARM, ControllerConfig(law=LawConfig(profile=profile)))
    send_states(core, 0.0, np.zeros(6))
    core.tick(0.0)
    return core


def test_a_demands_profile_times_that_motion_and_leaves_the_configuration():
    core = started_core('trapezoidal')
    config = core.config
    send_demand(core, 0.0, GOAL[None], 'g', profile='quintic')
    assert core.config is config and core.config.law.profile == 'trapezoidal'
    expected = plan_motion(LawConfig(profile='quintic'), np.zeros(6), GOAL[None],
                           ARM.velocity_limits)
    assert core.plan.duration == pytest.approx(expected.duration)
    values = core.status().values
    assert values['profile'] == 'trapezoidal'            # the parameter in force
    assert values['motion_profile'] == 'quintic'         # the law of this motion
    assert 'quintic' in core.status().message
    # The next demand without a profile is timed by the parameter's law again.
    send_demand(core, 0.1, (GOAL / 2)[None], 'h')
    assert core.status().values['motion_profile'] == 'trapezoidal'


def test_an_unknown_profile_is_refused_with_the_reason_and_the_motion_kept():
    core = started_core()
    motion = send_demand(core, 0.0, GOAL[None], 'g')
    with pytest.raises(InvalidInputError, match='profile must be one of'):
        send_demand(core, 0.1, (GOAL / 2)[None], 'bad', profile='banana')
    assert core.motion_id == motion
    values = core.status().values
    assert values['rejected_goal_id'] == 'bad' and 'banana' in values['rejected']
    assert core.config.law.profile == 'trapezoidal'
