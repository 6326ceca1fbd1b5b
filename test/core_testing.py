"""
Drive a ``ControllerCore`` through the calls the controller node makes, in one thread.

The node hands each /joint_states message to the core by name (``controller_node.on_joint_states``:
``on_named_joint_states``), and takes each demand in its demand thread
(``nodes.controller.demand_thread.DemandThread.take_demand``): ``check_demand``; then, per
attempt, a ``snapshot``,
``prepare_demand`` from it, and under its lock (``commit_if_current``) ``refusal`` (the state
takes no demand: refused), ``is_current`` (the controller moved on since the snapshot: planned
again, up to ``DEMAND_ATTEMPTS``, the last committed as it is) and ``commit_demand`` from the
plan's time when moving, from now at rest; ``reject`` with the reason when any of them refuses.
``send_demand`` makes the same calls in the same order, without the node's lock and threads, so a
core test runs the path the node runs. What it cannot do in one thread: wait for valid joint
states (the node waits ``DEMAND_STATE_WAIT`` for them before it refuses for the state; here the
refusal comes at once), and plan in the planning process (``plan_worker``; the same plan).
"""

from typing import Optional, Sequence

from mover6_control.control.controller_core import ControllerCore
from mover6_control.control.timed_plan import Timing
from mover6_control.errors import InvalidInputError
import numpy as np

# Plans of one demand before the last is committed as it is (demand_thread.DEMAND_ATTEMPTS;
# the node's module needs ROS, so it is not imported here).
DEMAND_ATTEMPTS = 3


def send_states(core: ControllerCore, now: float, q: Sequence[float],
                qd: Optional[Sequence[float]] = None,
                names: Optional[Sequence[str]] = None) -> None:
    """Hand the core joint states at ``now`` [s] as a /joint_states message (all joints)."""
    names = core.robot.joint_names if names is None else names
    core.on_named_joint_states(now, names, q, [] if qd is None else qd)


def send_states_lacking(core: ControllerCore, now: float, joint: str) -> str:
    """Hand the core joint states without ``joint`` (refused: a fault); return the reason."""
    names = [n for n in core.robot.joint_names if n != joint]
    try:
        core.on_named_joint_states(now, names, np.zeros(len(names)))
    except InvalidInputError as err:
        return str(err)
    raise AssertionError(f'states without {joint} were taken')


def send_demand(core: ControllerCore, now: float, waypoints: np.ndarray, demand_id: str = '',
                profile: str = '', timing: Optional[Timing] = None) -> int:
    """
    Hand the core a demand at ``now`` [s] as the node's demand thread does; return the motion id.

    A refused demand is noted in the status with its reason (``reject``) and the
    ``InvalidInputError`` raised again.
    """
    try:
        Q = core.check_demand(waypoints)
        attempt = 0
        while True:
            attempt += 1
            pending = core.prepare_demand(now, Q, core.snapshot(), demand_id, timing=timing,
                                          profile=profile)
            refusal = core.refusal()
            if refusal is not None:
                raise refusal
            if core.is_current(pending) or attempt >= DEMAND_ATTEMPTS:
                return core.commit_demand(pending, pending.now if pending.moving else now)
    except InvalidInputError as err:
        core.reject(now, str(err), demand_id)
        raise
