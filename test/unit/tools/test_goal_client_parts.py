"""
The goal client's parts, each built alone.

What it hears (``LatestStatus``) and following one goal to its end (``MotionFollower``, with a
scripted stand-in for the ``Spinner`` it is given).
"""

from mover6_control.control.status import MotionResult, State, StatusKey
from mover6_control.kinematics.arm import mover6
from mover6_control.nodes.messages.conversions import make_joint_state, make_status
from mover6_control.nodes.messages.demand_messages import make_demands
from mover6_control.tools.goal_convention import EXIT_ARRIVED, EXIT_FAILED, EXIT_REFUSED
from mover6_control.tools.goal_follower import MotionFollower
from mover6_control.tools.readiness import LatestStatus
import numpy as np

ARM = mover6()
NAMES = list(ARM.joint_names)
GOAL_Q = np.array([0.2, 0.1, 0.1, 0.0, 0.2, 0.0])


def controller(**values):
    return make_status('controller', 'OK', 'status', values)


def test_latest_status_keeps_the_latest_and_leaves_malformed_messages_out():
    latest = LatestStatus(NAMES)
    latest.on_joint_states(make_joint_state(NAMES, GOAL_Q))
    np.testing.assert_array_equal(latest.q, GOAL_Q)
    latest.on_joint_states(make_joint_state(NAMES, [float('nan')] * 6))
    np.testing.assert_array_equal(latest.q, GOAL_Q)           # the malformed one left out
    latest.on_demands(make_demands(np.stack([GOAL_Q, GOAL_Q])))
    assert latest.last_demands.shape == (2, 6)
    latest.follow('g1')
    assert latest.last_demands is None and latest.goal_id == 'g1'


def test_a_refusal_counts_only_for_the_goal_followed():
    latest = LatestStatus(NAMES)
    latest.follow('g1')
    latest.on_controller(controller(**{StatusKey.REJECTED: 'too far',
                                       StatusKey.REJECTED_GOAL_ID: 'g2'}))
    assert latest.rejection is None
    latest.on_controller(controller(**{StatusKey.REJECTED: 'too far',
                                       StatusKey.REJECTED_GOAL_ID: 'g1'}))
    assert latest.rejection == 'too far'


class ScriptedSpinner:
    """Stands in for ``readiness.Spinner``: each spin delivers the next scripted messages."""

    def __init__(self, events):
        self.events = list(events)

    def spin_until(self, predicate, timeout, tick=None):
        while not predicate() and self.events:
            self.events.pop(0)()
            if tick is not None:
                tick()
        return bool(predicate())


def follow_joint_goal(events):
    latest = LatestStatus(NAMES)
    follower = MotionFollower(ScriptedSpinner(events), latest, ARM)
    sent = []
    outcome = follower.run(lambda: sent.append('goal'), planned=False, goal_id='g1',
                           timeout=1.0)
    assert sent == ['goal']
    return latest, outcome


def test_a_joint_goal_followed_to_arrival_reports_the_pose_reached():
    latest = LatestStatus(NAMES)
    events = [lambda: latest.on_demands(make_demands(GOAL_Q[None], 'g1')),
              lambda: latest.on_controller(controller(**{
                  StatusKey.GOAL_ID: 'g1', StatusKey.STATE: State.IDLE,
                  StatusKey.RESULT: MotionResult.ARRIVED})),
              lambda: latest.on_joint_states(make_joint_state(NAMES, GOAL_Q))]
    follower = MotionFollower(ScriptedSpinner(events), latest, ARM)
    outcome = follower.run(lambda: None, planned=False, goal_id='g1', timeout=1.0)
    assert outcome.code == EXIT_ARRIVED, outcome
    # /joint_demands is float32: the waypoint heard is the goal rounded to it.
    rounded = GOAL_Q.astype(np.float32).astype(float)
    assert outcome.figures['final_joint_error'] == np.abs(GOAL_Q - rounded).max()
    assert outcome.figures['result'] == MotionResult.ARRIVED


def test_a_joint_goal_the_controller_refuses_is_refused():
    latest = LatestStatus(NAMES)
    events = [lambda: latest.on_controller(controller(**{
        StatusKey.REJECTED: 'outside the limits', StatusKey.REJECTED_GOAL_ID: 'g1'}))]
    outcome = MotionFollower(ScriptedSpinner(events), latest, ARM).run(
        lambda: None, planned=False, goal_id='g1', timeout=1.0)
    assert outcome.code == EXIT_REFUSED
    assert 'outside the limits' in outcome.text


def test_a_goal_nothing_answers_about_fails():
    _, outcome = follow_joint_goal([])
    assert outcome.code == EXIT_FAILED
    assert 'did not finish' in outcome.text
