"""
Drive a ``ControllerCore`` through the calls the controller node makes, in one thread.

The node hands each /joint_states message to the core by name (``controller_node.on_joint_states``:
``on_named_joint_states``), and plans each demand in its demand thread
(``controller_demands.take_demand``): ``check_demand``, a ``snapshot``, ``prepare_demand`` from
it, ``commit_demand``, and ``reject`` with the reason when any of them refuses. These helpers make
the same calls without the node's lock and threads, so a core test runs the path the node runs.
"""

from typing import Optional, Sequence

from mover6_control.control.controller_core import ControllerCore
from mover6_control.control.timed_plan import Timing
from mover6_control.errors import InvalidInputError
import numpy as np


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
        pending = core.prepare_demand(now, Q, core.snapshot(), demand_id, timing=timing,
                                      profile=profile)
        return core.commit_demand(pending)
    except InvalidInputError as err:
        core.reject(now, str(err), demand_id)
        raise
