"""
The status schema (``control.status``): one home for the controller's states, results and causes.

Readers decide on the typed cause, never on the words of a reason, and no product module
compares a status value with a retyped state or result name.
"""

import ast
import os

from control_msgs.action import FollowJointTrajectory
from mover6_control.control import state_machine as sm
from mover6_control.control.status import Cause, FINAL_RESULTS, MotionResult, State, StatusKey
from mover6_control.nodes.controller.trajectory_goal import ended_code
from source_tree import ROOT

Result = FollowJointTrajectory.Result
WORDS = {str(v) for v in (*State, *MotionResult)}


def test_the_state_machine_speaks_the_schema():
    assert sm.STATES == tuple(str(state) for state in State)
    assert sm.IDLE is State.IDLE and f'{sm.EXECUTING}' == 'executing'   # the wire text
    assert MotionResult.JOG_STOPPED not in FINAL_RESULTS                   # a jog is no goal
    assert StatusKey.CAUSE == 'cause'


def test_the_result_code_follows_the_cause_not_the_words():
    """Rewording a reason must not change a goal's result code."""
    reworded = {StatusKey.RESULT: MotionResult.ABORTED, StatusKey.CAUSE: Cause.GOAL_TOLERANCE,
                StatusKey.REASON: 'did not settle in 3 s'}
    assert ended_code(reworded) == Result.GOAL_TOLERANCE_VIOLATED
    misleading = {StatusKey.RESULT: MotionResult.ABORTED, StatusKey.CAUSE: Cause.PATH_TOLERANCE,
                  StatusKey.REASON: 'tracking error before the goal tolerance was reached'}
    assert ended_code(misleading) == Result.PATH_TOLERANCE_VIOLATED
    for cause in (Cause.STATES_INVALID, Cause.STOP_REQUESTED):
        assert ended_code({StatusKey.CAUSE: cause}) == Result.PATH_TOLERANCE_VIOLATED


def literal_comparisons(tree):
    """Yield (line, text) of every string literal compared with ``==``, ``!=``, ``in``."""
    for node in ast.walk(tree):
        if not isinstance(node, ast.Compare):
            continue
        for operand in [node.left, *node.comparators]:
            items = operand.elts if isinstance(operand, (ast.Tuple, ast.List, ast.Set)) else [
                operand]
            for item in items:
                if isinstance(item, ast.Constant) and isinstance(item.value, str):
                    yield node.lineno, item.value


def test_no_module_compares_with_a_retyped_state_or_result():
    found = []
    for package in ('mover6_control', 'sim_bridge'):
        for folder, _, files in os.walk(os.path.join(ROOT, package)):
            for name in (f for f in files if f.endswith('.py')):
                path = os.path.join(folder, name)
                with open(path) as f:
                    tree = ast.parse(f.read(), path)
                found += [f'{os.path.relpath(path, ROOT)}:{line} {text!r}'
                          for line, text in literal_comparisons(tree) if text in WORDS]
    assert found == []
