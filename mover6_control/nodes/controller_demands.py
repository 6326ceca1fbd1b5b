"""
The controller node's demand thread: every demand ends accepted or refused with a reason.

Demands (/joint_demands, and the goals of the action server) are planned in their own thread,
in the order they came: the continuous profile plans a long path for tens of milliseconds,
hundreds on a loaded machine, and neither the ticks nor the /joint_states callback may wait that
long (states unread for ``state_timeout`` fault the controller); a plan that the controller
moved on from meanwhile is made again, also outside the lock. Which motion a goal's demand
became, or why it was refused, goes into the node's ``GoalLedger`` (``goal_ledger``).

``DemandThread`` is a part of ``controller_node.ControllerNode`` (its state is the node's, set
in ``ControllerNode.__init__``); it is not used on its own.
"""

import time
from typing import Optional

from mover6_control.control.state_machine import FAULT, WAITING_FOR_STATES
from mover6_control.control.timed_plan import Timing
from mover6_control.errors import InvalidInputError, Mover6Error
from mover6_control.nodes import demand_messages
from mover6_control.validation import short_text
from std_msgs.msg import Float32MultiArray

# Plans of one demand made without the lock before the last is committed as it is (re-planned
# under the lock when the controller moved on yet again: only when motions end that often).
DEMAND_ATTEMPTS = 3
# [s] a demand whose plan took longer than this is never planned again under the lock (the
# ticks would wait for it): refused with the reason instead when the controller moved on again.
LOCKED_PLAN_LIMIT = 0.02
# Longest wait [s] of a demand that comes before the first joint states (the planner can be
# quicker at start-up), or in a fault that fresh states clear (a stall at start-up: Fast DDS
# discovery can hold a process for 0.33 s); then it is refused with the reason. Less than the
# planner's resend window (RESEND_AFTER * (RESENDS + 1) = 6 s).
DEMAND_STATE_WAIT = 2.0
# States in which a demand waits (DEMAND_STATE_WAIT) for valid joint states.
WAIT_FOR_STATES = (WAITING_FOR_STATES, FAULT)


class DemandThread:
    """The demand thread of ``ControllerNode`` (module docstring)."""

    def on_demands(self, msg: Float32MultiArray) -> None:
        """Hand a /joint_demands message to the demand thread (it plans there)."""
        self.demands.put(msg)

    def demand_loop(self) -> None:
        """
        Take the queued demands in order until ``None`` comes (the node closes).

        An item is a /joint_demands message, ``(message, Timing)`` (a goal's ``time_from_start``
        and velocities, ``control.timed_plan``), or a callable from the action server that
        returns one of those, or None when it refused the goal: a goal of 10,000 points is
        converted here, not in the executor thread that must keep taking /joint_states.
        """
        while True:
            msg = self.demands.get()
            if msg is None or not self.running:
                return
            if callable(msg):
                msg = msg()
                if msg is None:
                    continue
            msg, timing = msg if isinstance(msg, tuple) else (msg, None)
            self.take_demand(msg, timing)   # never raises: refuses with a reason instead

    def take_demand(self, msg: Float32MultiArray, timing: Optional[Timing] = None) -> None:
        """
        Accept waypoints or say why not: every demand ends accepted or refused with a reason.

        The one concurrency rule (docs/architecture.md, "Threads"): a snapshot of the core is
        taken under the lock, the plan is made from it without the lock (the ticks go on), and
        it is committed under the lock only if the snapshot is still current; otherwise it is
        planned again from a new snapshot (the last attempt re-plans under the lock, unless the
        plans take longer than ``LOCKED_PLAN_LIMIT``: then it is refused). The waypoints are
        checked before the first snapshot (a refusal names the state the snapshot saw), and a
        goal its action gave up waiting for (``withdrawn``) is never started.
        """
        now = self.now()
        goal_id = demand_messages.demand_id_from_msg(msg)
        if goal_id and self.goals.known(goal_id):
            # The planner sends a demand again until this status names its goal: take it once.
            self.get_logger().info(f'goal {goal_id}: demand received again; already taken')
            self.publish_status(now)
            return
        try:
            Q = demand_messages.demands_from_msg(msg, len(self.joint_names))
            profile = demand_messages.demand_profile_from_msg(msg)   # this demand's law only
            with self.lock:
                waiting = self.core.state in WAIT_FOR_STATES
            if waiting:                          # no valid states yet: wait a moment
                self.has_states.wait(DEMAND_STATE_WAIT)
                now = self.now()
            Q = self.core.check_demand(Q)       # the arm's limits only: no lock needed
            for attempt in range(DEMAND_ATTEMPTS):
                with self.lock:
                    snapshot = self.core.snapshot()
                started = time.monotonic()
                pending = self.core.prepare_demand(now, Q, snapshot, goal_id, timing=timing,
                                                   profile=profile)
                slow = time.monotonic() - started > LOCKED_PLAN_LIMIT
                with self.lock:
                    if goal_id and self.goals.withdrawn(goal_id):
                        raise InvalidInputError(f'goal {goal_id}: its sender stopped waiting')
                    current = self.core.is_current(pending)
                    if not current and slow and attempt + 1 == DEMAND_ATTEMPTS:
                        raise InvalidInputError(
                            f'the controller moved on while this demand was planned, '
                            f'{DEMAND_ATTEMPTS} times; send it again')
                    if attempt + 1 == DEMAND_ATTEMPTS or current:
                        # From rest the plan starts now, not when its (long) planning began.
                        start = pending.now if pending.moving else self.now()
                        motion_id = self.core.commit_demand(pending, start)
                        self.goals.started(motion_id, goal_id, start)
                        break
                now = self.now()
        except Exception as err:  # noqa: B902 - no demand is dropped without a status
            reason = str(err) if isinstance(err, Mover6Error) else f'{type(err).__name__}: {err}'
            reason = short_text(reason)   # hostile demands quote little
            self.get_logger().warning(f'rejected /joint_demands: {reason}')
            with self.lock:
                if goal_id:
                    self.goals.refused(goal_id, reason)
                self.core.reject(now, reason, goal_id)
            self.publish_status(now, level='WARN', message=f'rejected demand: {reason}')
            return
        self.get_logger().info(f'motion {motion_id}: {len(Q)} waypoint(s) accepted'
                               + (f' (goal {goal_id})' if goal_id else ''))
        self.publish_status(now)
