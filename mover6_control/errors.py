"""
Exceptions shared by the ROS-free core, and the one table of reasons for refusing a goal.

Every error raised by the core on bad input is a ``ValueError`` subclass, so callers (the nodes)
can catch one type, log ``str(err)`` and drop the input. What a caller branches on is the
error's code (``error_code``), never its text: ``REASONS`` for a goal the planner refuses,
``INPUT_CODES`` for malformed input refused where it enters (``values``).
"""

from __future__ import annotations

# The reason codes of ``UnreachableError.reason``, of a reachability verdict
# (``kinematics.reachability.Verdict.reason``) and of the planner node's refusals, each with its
# meaning. The planner node sends the code with its refusal on /planner/status; the goal CLI and
# the demo print it.
REASONS = {
    'reachable': 'not a refusal: the verdict of a pose or path that can be reached',
    'out_of_reach': 'no configuration puts the tool at the pose, within the joint limits or not '
                    '(outside the workspace), or the last waypoint misses the goal',
    'joint_limits': 'the pose is reachable only with a joint outside its limits',
    'singularity': 'the pose or path needs the arm at or moving towards a singular '
                   'configuration (Jacobian condition number above max_condition)',
    'discontinuity': 'two consecutive waypoints need a joint step above max_joint_step (the '
                     'path would switch IK branch)',
    'not_controllable': 'the joint path cannot be timed within the velocity and acceleration '
                        'limits (continuous timing)',
    'unreachable': 'unreachable, for no more specific reason (the default)',
    'invalid_goal': 'the goal or the present state cannot be planned from: a malformed pose, '
                    'a bad setting, or joint states too old to know the current pose',
    'no_controller': 'nothing subscribes to /joint_demands: the plan would reach no controller',
    'collision': 'the motion, swept between its waypoints, would put a part of the arm or its '
                 'tool into the table margin, into another part of the arm or into a keep-out '
                 'box',
    'no_joint_states': "no valid /joint_states came within the planner's state_wait_timeout: "
                       'the current pose is unknown',
    'controller_refused': 'the controller refused the planned demand (its reason follows)',
    'controller_not_ready': 'the controller refused the planned demand for its state (no '
                            'valid joint states, a fault ...; its reason follows)',
    'not_acknowledged': 'the demand went out but no controller answered it: none on the '
                        "graph for the planner's match_timeout",
    'superseded': 'a demand sent after this one reached the controller first; this one never '
                  'did and is not sent again',
    'stopped': "the planner's stop service ended the goal before its demand was sent",
    'internal_error': 'the planner failed on the goal for a reason of its own (a bug): the '
                      'message names the exception',
}


# The codes of ``InvalidInputError.code``: why an input was refused where it entered, each with
# its meaning. The driver counts refused JointJogs by these codes on /diagnostics.
INPUT_CODES = {
    'invalid_input': 'malformed input, for no more specific reason (the default)',
    'non_finite': 'a value is NaN or infinite',
    'bad_shape': 'an array has the wrong shape or a value is not a number',
    'not_a_transform': 'a pose matrix is no rigid transform: its rotation is not orthonormal, '
                       'is a reflection, or its last row is not [0, 0, 0, 1]',
    'bad_quaternion': 'an orientation quaternion is zero or not of unit length',
    'wrong_frame': "a goal's frame is not the planner's base frame (no TF lookup is done)",
    'empty': 'a command or a demand holds no values (no joints, no waypoints, no poses)',
    'length': 'the arrays of one message disagree in length',
    'names': 'a joint is named twice',
    'unknown_joint': 'a joint name the arm does not have',
    'displacements': 'a JointJog carries displacements: only velocities are supported',
    'out_of_range': 'a value beyond what the arm takes (a jog speed beyond its limit)',
    'in_collision': 'a collision parameter (keep-out box, table margin, tool) that puts the arm '
                    'into collision where it stands',
}


class Mover6Error(Exception):
    """Base of every exception the core raises on purpose; ``code`` says which kind."""

    code = 'refused'


class InvalidInputError(Mover6Error, ValueError):
    """
    An argument has the wrong shape, a non-finite value or an out-of-range setting.

    ``code`` is a key of ``INPUT_CODES``: the class's own, or the one given.
    """

    code = 'invalid_input'

    def __init__(self, message: str, code: str | None = None) -> None:
        super().__init__(message)
        if code is not None:
            if code not in INPUT_CODES:
                raise KeyError(f'no input code {code!r} in errors.INPUT_CODES')
            self.code = code


class NonFiniteError(InvalidInputError):
    """A value is NaN or infinite."""

    code = 'non_finite'


class ShapeError(InvalidInputError):
    """An array has the wrong shape, or a value is no number."""

    code = 'bad_shape'


class NotATransformError(InvalidInputError):
    """A matrix is no rigid transform (rotation not orthonormal, a reflection, a bad last row)."""

    code = 'not_a_transform'


class QuaternionError(InvalidInputError):
    """A quaternion is zero or not of unit length."""

    code = 'bad_quaternion'


class UnreachableError(Mover6Error, ValueError):
    """A pose or path cannot be reached; ``reason`` is a code of ``REASONS``."""

    def __init__(self, message: str, reason: str = 'unreachable',
                 details: dict | None = None) -> None:
        super().__init__(message)
        self.reason = reason
        self.code = reason
        self.details = dict(details or {})


def error_code(err: BaseException) -> str:
    """
    Return the code of ``err``: its ``code`` for a ``Mover6Error``, else ``internal_error``.

    What a caller branches on (never the error's text): an exception that is no ``Mover6Error``
    was not raised on purpose, a bug of the input checks.
    """
    return err.code if isinstance(err, Mover6Error) else 'internal_error'
