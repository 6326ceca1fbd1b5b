"""
The controller node's demand thread: every demand ends accepted or refused with a reason.

Demands (/joint_demands, and the goals of the action server) are planned in their own thread,
in the order they came: the continuous profile plans a long path for tens of milliseconds,
hundreds on a loaded machine, and neither the ticks nor the /joint_states callback may wait that
long (states unread for ``state_timeout`` fault the controller); a plan that the controller
moved on from meanwhile is made again, also outside the lock. Which motion a goal's demand
became, or why it was refused, goes into the node's ``GoalLedger`` (``goal_ledger``).

A demand that names a goal is answered on ``controller/demand_acks`` (``demand_answers``):
received when it comes (``DemandAnswers.received``, from the executor's callback), then taken,
refused, or not ready (a state that takes no demand) when the thread is done with it.

``DemandThread`` gets what it uses in its constructor: the core and its lock, the goal ledger,
the answers, the status, the event that says the core has valid states, the planning process,
and the node's clock, logger and guard.
"""

import threading
import time
from typing import Callable, Optional, Union

from mover6_control.control.controller_core import ControllerCore
from mover6_control.control.demand_intake import NotAcceptingError, PendingDemand
from mover6_control.control.state_machine import FAULT, WAITING_FOR_STATES
from mover6_control.control.timed_plan import Timing
from mover6_control.errors import InvalidInputError, Mover6Error
from mover6_control.nodes.controller.demand_answers import DemandAnswers
from mover6_control.nodes.controller.goal_ledger import GoalLedger
from mover6_control.nodes.controller.plan_worker import PlanWorker
from mover6_control.nodes.messages import demand_messages
from mover6_control.nodes.messages.demand_acks import Answer
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from mover6_control.nodes.runtime.job_thread import JobThread
from mover6_control.validation import short_text
from rclpy.impl.rcutils_logger import RcutilsLogger
from std_msgs.msg import Float32MultiArray

# Plans of one demand made without the lock before the last is committed as it is (re-planned
# under the lock when the controller moved on yet again: only when motions end that often).
DEMAND_ATTEMPTS = 3
# [s] a demand whose plan took longer than this is never planned again under the lock (the
# ticks would wait for it): refused with the reason instead when the controller moved on again.
LOCKED_PLAN_LIMIT = 0.02
# Longest wait [s] of a demand for valid joint states, by the state it came in; then it is
# refused with the reason. Before the first joint states (the planner can be quicker at
# start-up, and Fast DDS discovery of the arm's publisher takes seconds on a loaded machine) it
# waits longer than in a fault that fresh states clear (a stall: Fast DDS discovery can hold a
# process for 0.33 s). Both are less than the planner, which waits for the answer
# (``demand_answers``) without a time limit.
DEMAND_STATE_WAIT = {WAITING_FOR_STATES: 10.0, FAULT: 2.0}
# States in which a demand waits (DEMAND_STATE_WAIT) for valid joint states.
WAIT_FOR_STATES = tuple(DEMAND_STATE_WAIT)
# Rounds of one demand's taking at most: DEMAND_ATTEMPTS plans, and waits for the state.
DEMAND_ROUNDS = DEMAND_ATTEMPTS + 3
# A demand of this many waypoints or more is planned in the planning process (plan_worker):
# planning it here holds the interpreter lock that the tick needs, between the compiled parts
# of the timing (motion/timing: they run without it); through the worker a demand costs the
# pickles and a second process waiting for a CPU beside the stack (bench/HISTORY.md has the
# figures). Below WORKER_POINTS (at most about 15 ms of CPU) a demand stays here, and so does
# every demand while the worker starts (seconds: the first such demand starts it): a demand
# must not wait for it; but one of WORKER_WAIT_POINTS or more (about 150 ms) waits: here it
# would hold the tick back.
WORKER_POINTS = 1200
WORKER_WAIT_POINTS = 8000


# What the queue takes: a message, a message and its timing, or a callable that returns either
# (or None: refused); None closes the thread.
Item = Union[Float32MultiArray, tuple, Callable, None]


class DemandThread:
    """The controller's demand thread (module docstring)."""

    def __init__(self, core: ControllerCore, lock: threading.RLock, goals: GoalLedger,
                 answers: DemandAnswers, publish_status: Callable, has_states: threading.Event,
                 plan_worker: PlanWorker, now: Callable[[], float], logger: RcutilsLogger,
                 guard: CallbackGuard, topic: str):
        """
        Take demands for ``core`` (changed under ``lock``); see ``start``.

        ``publish_status(now, level=, message=)`` publishes the controller's status; ``topic``
        is the resolved name of /joint_demands (a refusal is counted by the ``guard`` there).
        """
        self.core = core
        self.lock = lock
        self.goals = goals
        self.answers = answers
        self.publish_status = publish_status
        self.has_states = has_states
        self.plan_worker = plan_worker
        self.now = now
        self.logger = logger
        self.guard = guard
        self.topic = topic
        # The demands not yet taken, in order (``take_item``); closing it wakes a demand that
        # waits for valid states.
        self.jobs = JobThread('controller_demands', self.take_item, wake=has_states.set)

    def start(self) -> None:
        """Start the demand thread."""
        self.jobs.start()

    def put(self, item: Item) -> None:
        """Queue a demand (module docstring; ``take_item`` says what an item is)."""
        self.jobs.put(item)

    def stop(self) -> None:
        """Take no further demand (the one being taken ends as it would); see ``close``."""
        self.jobs.stop()

    def close(self, timeout: float) -> None:
        """End the thread: a demand waiting for states stops waiting; wait ``timeout`` [s]."""
        self.jobs.close(timeout)

    def take_item(self, item: Item) -> None:
        """
        Take one queued item; never raises (a demand is refused with its reason instead).

        An item is a /joint_demands message, ``(message, Timing)`` (a goal's ``time_from_start``
        and velocities, ``control.timed_plan``), or a callable from the action server that
        returns one of those, or None when it refused the goal: a goal of 10,000 points is
        converted here, not in the executor thread that must keep taking /joint_states.
        """
        if callable(item):
            item = item()
            if item is None:
                return
        msg, timing = item if isinstance(item, tuple) else (item, None)
        self.take_demand(msg, timing)

    def take_demand(self, msg: Float32MultiArray, timing: Optional[Timing] = None) -> None:
        """
        Accept waypoints or say why not: every demand ends accepted or refused with a reason.

        The one concurrency rule (docs/architecture.md, "Threads"): a snapshot of the core is
        taken under the lock, the plan is made from it without the lock (the ticks go on; a
        demand of ``WORKER_POINTS`` waypoints or more in the planning process once it is up,
        ``plan_worker``),
        and it is committed under the lock only if the snapshot is still current; otherwise it
        is planned again from a new snapshot (the last attempt re-plans under the lock, unless
        the plans take longer than ``LOCKED_PLAN_LIMIT``: then it is refused). The waypoints
        are checked first. In a state that takes no demand it waits for valid states
        (``DEMAND_STATE_WAIT``) and tries again; a refusal for the state names the state the
        controller is in when it refuses (``refuse_for_state``). A goal its action gave up
        waiting for (``withdrawn``) is never started.
        """
        now = self.now()
        goal_id = demand_messages.demand_id_from_msg(msg)
        if goal_id and self.goals.known(goal_id):
            # The planner sends a demand again until this status names its goal: take it once.
            self.logger.info(f'goal {goal_id}: demand received again; answered already')
            self.answers.repeat(goal_id)
            return
        try:
            Q = demand_messages.demands_from_msg(msg, len(self.core.arm.joint_names))
            profile = demand_messages.demand_profile_from_msg(msg)   # this demand's law only
            Q = self.core.check_demand(Q)       # the arm's limits only: no lock needed
            planner = (self.plan_worker if len(Q) >= WORKER_WAIT_POINTS or (
                len(Q) >= WORKER_POINTS and self.plan_worker.ready()) else None)
            until = None        # [s, monotonic] end of this demand's wait for valid states
            motion_id, attempt = None, 0
            for _ in range(DEMAND_ROUNDS):
                until = self.wait_for_states(until)
                now = self.now()
                with self.lock:
                    snapshot = self.core.snapshot()
                started = time.monotonic()
                try:
                    pending = self.core.prepare_demand(now, Q, snapshot, goal_id, timing=timing,
                                                       profile=profile, planner=planner)
                    slow = time.monotonic() - started > LOCKED_PLAN_LIMIT
                    attempt += 1
                    with self.lock:
                        motion_id = self.commit_if_current(pending, goal_id, slow,
                                                           attempt >= DEMAND_ATTEMPTS)
                except NotAcceptingError:
                    until = self.refuse_for_state(until)   # returns when it may try again
                    continue
                if motion_id is not None:
                    break
            if motion_id is None:
                self.refuse_for_state(time.monotonic())
                raise InvalidInputError('the controller moved on while this demand was planned, '
                                        f'{DEMAND_ATTEMPTS} times; send it again')
        except Exception as err:  # noqa: B902 - no demand is dropped without a status
            reason = str(err) if isinstance(err, Mover6Error) else f'{type(err).__name__}: {err}'
            reason = short_text(reason)   # hostile demands quote little
            # Logged once a second and counted on ~/guard by source, as any refused input.
            self.guard.refuse('follow_joint_trajectory' if goal_id.startswith('fjt-')
                              else self.topic, err)
            with self.lock:
                if goal_id:
                    self.goals.refused(goal_id, reason)
                self.core.reject(now, reason, goal_id)
            if goal_id:
                self.answers.answer(goal_id, Answer.NOT_READY if isinstance(
                    err, NotAcceptingError) else Answer.REFUSED, reason)
            self.publish_status(now, level='WARN', message=f'rejected demand: {reason}')
            return
        if goal_id:
            self.answers.answer(goal_id, Answer.TAKEN, f'motion {motion_id}')
        self.logger.info(f'motion {motion_id}: {len(Q)} waypoint(s) accepted'
                         + (f' (goal {goal_id})' if goal_id else ''))
        self.publish_status(now)

    def commit_if_current(self, pending: PendingDemand, goal_id: str, slow: bool,
                          last: bool) -> Optional[int]:
        """
        Start ``pending`` if it still fits, or on the ``last`` attempt; return its motion id.

        Call it under the lock. Returns None when it must be planned again. Raises
        ``NotAcceptingError`` when the state now takes no demand, and ``InvalidInputError``
        when its goal was withdrawn or when the controller moved on meanwhile on the last
        attempt of a ``slow`` plan (it is never planned under the lock).
        """
        if goal_id and self.goals.withdrawn(goal_id):
            raise InvalidInputError(f'goal {goal_id}: its sender stopped waiting')
        refusal = self.core.refusal()
        if refusal is not None:
            raise refusal
        current = self.core.is_current(pending)
        if not current and slow and last:
            raise InvalidInputError(f'the controller moved on while this demand was planned, '
                                    f'{DEMAND_ATTEMPTS} times; send it again')
        if not (current or last):
            return None
        # From rest the plan starts now, not when its (long) planning began.
        start = pending.now if pending.moving else self.now()
        motion_id = self.core.commit_demand(pending, start)
        self.goals.started(motion_id, goal_id, start)
        return motion_id

    def wait_for_states(self, until: Optional[float]) -> Optional[float]:
        """
        Wait while the core has no valid joint states, until ``until`` (monotonic) at most.

        ``until`` None: the wait starts now (``DEMAND_STATE_WAIT``); returns the end of the
        wait (None when there was none to wait for).
        """
        with self.lock:
            state = self.core.state
        if state in WAIT_FOR_STATES:         # no valid states yet: wait a moment
            until = time.monotonic() + DEMAND_STATE_WAIT[state] if until is None else until
            self.has_states.wait(max(0.0, until - time.monotonic()))
        return until

    def refuse_for_state(self, until: Optional[float]) -> Optional[float]:
        """
        After the state took no demand: return to try again, or raise why not in the state now.

        It tries again when the state takes demands by now (a fault cleared meanwhile), or
        when it waits for valid joint states and the wait (``until``, monotonic; None: from
        now, ``DEMAND_STATE_WAIT``) has not ended: it returns the end of that wait. Otherwise it
        raises the ``NotAcceptingError`` of the state the controller is in now, never of the
        state it was in when the demand was planned.
        """
        with self.lock:
            refusal = self.core.refusal()
        if refusal is None:
            return until
        if refusal.state in WAIT_FOR_STATES:
            until = (time.monotonic() + DEMAND_STATE_WAIT[refusal.state] if until is None
                     else until)
            if time.monotonic() < until:
                return until
        raise refusal
