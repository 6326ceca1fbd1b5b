"""
What the controller says on /controller/status: the one schema of its states, results and keys.

Every value is a ``StrEnum``, so it is its own wire text (``f'{State.IDLE}'`` is ``idle``) and
compares equal to the string a status message carries: a reader compares
``values[StatusKey.STATE] == State.EXECUTING`` and never retypes ``'executing'``.

- ``State``: the controller's states (``state_machine`` moves between them).
- ``MotionResult``: how a motion (or a jog) ended, the status value ``result``.
  ``FINAL_RESULTS`` are the ones that end a motion started by a demand.
- ``Cause``: why a motion ended other than arrived, the status value ``cause``, next to the
  human ``reason``; a reader decides on the cause, never on the reason's words.
- ``StatusKey``: the keys of the status values (the controller's and the planner's).
- ``PlannerState``, ``PlannerResult``: the planner's readiness (``state``) and how a goal
  ended there (``result`` on /planner/status).
"""

from enum import StrEnum


class State(StrEnum):
    """The controller's states."""

    WAITING_FOR_STATES = 'waiting_for_states'
    IDLE = 'idle'
    EXECUTING = 'executing'
    SETTLING = 'settling'
    STOPPING = 'stopping'
    FAULT = 'fault'
    JOGGING = 'jogging'


class MotionResult(StrEnum):
    """How a motion ended (status value ``result``)."""

    ARRIVED = 'arrived'          # every joint inside its goal tolerance
    ABORTED = 'aborted'          # path tolerance left, or not settled in time (see ``Cause``)
    STOPPED = 'stopped'          # stopped on request, at rest
    FAULT = 'fault'              # joint states went stale or invalid while moving
    JOG_STOPPED = 'jog_stopped'  # the jog commands went stale and the arm came to rest


# The results that end a motion started by a demand (a goal's motion: arrived or not).
FINAL_RESULTS = frozenset({MotionResult.ARRIVED, MotionResult.ABORTED, MotionResult.STOPPED,
                           MotionResult.FAULT})


class Cause(StrEnum):
    """Why a motion ended other than arrived (status value ``cause``, with the ``reason``)."""

    PATH_TOLERANCE = 'path_tolerance'    # tracking error above the path tolerance: aborted
    GOAL_TOLERANCE = 'goal_tolerance'    # not within the goal tolerance in time: aborted
    STATES_INVALID = 'states_invalid'    # joint states stale, incomplete or non-finite: fault
    STOP_REQUESTED = 'stop_requested'    # the stop service (or a cancel): stopped
    JOG_ENDED = 'jog_ended'              # the jog commands went stale: jog_stopped


class StatusKey(StrEnum):
    """The keys of the status values."""

    STATE = 'state'
    MOTION_ID = 'motion_id'
    WAYPOINT = 'waypoint'
    WAYPOINTS = 'waypoints'
    TRACKING_ERROR = 'tracking_error'
    MAX_JOINT_ERROR = 'max_joint_error'
    PROFILE = 'profile'
    MOTION_PROFILE = 'motion_profile'
    JOG_UNITS = 'jog_units'
    RATE = 'rate'
    GOAL_TOLERANCE = 'goal_tolerance'
    PENDING_PARAMETERS = 'pending_parameters'
    TIMING = 'timing'
    RESULT = 'result'
    CAUSE = 'cause'
    REASON = 'reason'
    FINAL_JOINT_ERROR = 'final_joint_error'
    SETTLED_JOINT_ERROR = 'settled_joint_error'
    REJECTED = 'rejected'
    REJECTED_TIME = 'rejected_time'
    REJECTED_GOAL_ID = 'rejected_goal_id'
    JOG_REASON = 'jog_reason'
    JOG_CONDITION = 'jog_condition'
    JOG_SCALE = 'jog_scale'
    JOG_REFUSED = 'jog_refused'
    GOAL_ID = 'goal_id'              # the controller's (the goal of motion_id) and the planner's
    GOAL_STAMP = 'goal_stamp'        # the planner's: the stamp of the goal it is about
    MAX_TICK_GAP = 'max_tick_gap'
    MAX_STATES_AGE = 'max_states_age'    # the controller's: oldest valid states a tick saw [s]
    SPEED_SCALING = 'speed_scaling'      # the controller's: the factor motions run at now
    SPEED_SCALING_INPUT = 'speed_scaling_input'  # the controller's: the factor asked for


class PlannerState(StrEnum):
    """The planner's readiness (status value ``state`` on /planner/status)."""

    WAITING_FOR_STATES = 'waiting_for_states'
    READY = 'ready'


class PlannerResult(StrEnum):
    """What became of a goal at the planner (status value ``result`` on /planner/status)."""

    WAITING_FOR_STATES = 'waiting_for_states'   # the goal waits for the first joint states
    PLANNED = 'planned'                         # its demand went to the controller
    REFUSED = 'refused'                         # refused, with the ``reason`` code
    FAILED = 'failed'                           # no controller acknowledged the demand


# The timing value of a timed goal whose time_from_start is followed (``timed_plan``).
TIMING_AS_GIVEN = 'as given'
