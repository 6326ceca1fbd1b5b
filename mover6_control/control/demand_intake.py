"""
Demands into the controller: check, plan from a snapshot outside the node's lock, commit.

A node takes a ``Snapshot`` under its lock (``snapshot``), checks and plans the demand from it
without the lock (``prepare_demand``: planning the continuous profile takes tens of
milliseconds, the ticks go on), and starts it under the lock (``commit_demand``), which plans
again only when the controller moved on since the snapshot (``is_current``). A refused demand
stays in the status (``reject``) until one is taken.

The planning itself is a ``PlanJob`` (its inputs, read from the snapshot and the config, and
``run``: the plan and the collision check): the node may run it elsewhere (``prepare_demand``'s
``planner``: a process of its own for a large demand) and gets the same plan. A demand refused
for the controller's state raises ``NotAcceptingError``, so the node can tell it from a bad
demand (it waits for fresh states and asks again: the refusal names the state it is in then).

``DemandIntake`` is made with what it reads and changes: the arm (its limits), the robot (the
measured states, the reference a demand starts from, the plan it gives) and the ``CoreState``
it shares with the other parts of ``controller_core.ControllerCore`` (the state machine, the
motion's figures, the settings and the collision guard). A test builds it alone from those.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Optional

from mover6_control.control import state_machine as sm
from mover6_control.control.controller_config import ControllerConfig
from mover6_control.control.core_state import CoreState
from mover6_control.control.motion_plan import MotionPlan
from mover6_control.control.profiles import LawConfig
from mover6_control.control.robot import Robot
from mover6_control.control.status import StatusKey as K
from mover6_control.control.timed_plan import plan_demand, Timing
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import ArmModel
from mover6_control.validation import short_text
import numpy as np


@dataclass(frozen=True, eq=False)
class Snapshot:
    """
    What a demand is planned from, read once under the node's lock (``ControllerCore.snapshot``).

    ``state``; ``start`` = ``(q, qd)`` the plan starts from: the reference of the last tick and
    its velocity while moving, the measured position and None (rest) otherwise; ``moving``;
    ``motion_id`` of the latest accepted demand; ``message`` the state's reason then (a refusal
    names the state it was refused in, not a later one). Immutable, so planning from it outside
    the lock cannot see a tick change it halfway.
    """

    state: str
    start: tuple
    moving: bool
    motion_id: int
    message: str = ''


class NotAcceptingError(InvalidInputError):
    """The controller cannot take a demand in its state (``state``); the reason names it."""

    def __init__(self, state: str, message: str):
        """Say that no demand is taken while ``state`` (``message``: the state's reason)."""
        super().__init__(f'cannot take a demand while {state}: {message}')
        self.state = state


@dataclass(frozen=True, eq=False)
class PlanJob:
    """
    What a demand's plan is made from, and ``run`` to make it (``timed_plan.plan_demand``).

    Only values (the law, the start, the checked waypoints, the limits): it reads nothing of
    the controller, so it runs the same in another thread or process (it pickles).
    """

    law: LawConfig
    q_start: np.ndarray
    waypoints: np.ndarray
    velocity_limits: np.ndarray
    qd_start: Optional[np.ndarray]
    timing: Optional[Timing]
    lower: np.ndarray
    upper: np.ndarray

    def run(self, guard: Optional[Callable[[MotionPlan], None]] = None) -> tuple[MotionPlan, str]:
        """
        Return ``(plan, note)`` as ``plan_demand`` does, once ``guard(plan)`` let it pass.

        ``guard`` is the controller's collision check (None: none); it raises
        ``InvalidInputError`` for a motion that collides.
        """
        plan, note = plan_demand(self.law, self.q_start, self.waypoints, self.velocity_limits,
                                 self.qd_start, self.timing, self.lower, self.upper)
        if guard is not None:
            guard(plan)
        return plan, note


# Runs a PlanJob with the controller's collision guard: ``planner(job, guard)`` returns what
# ``job.run(guard)`` returns, or raises as it does (``prepare_demand``'s ``planner``).
Planner = Callable[[PlanJob, Optional[Callable[[MotionPlan], None]]], tuple[MotionPlan, str]]


@dataclass(frozen=True, eq=False)
class PendingDemand:
    """A checked and planned demand not yet started (``ControllerCore.prepare_demand``)."""

    now: float
    waypoints: np.ndarray
    plan: MotionPlan
    moving: bool
    motion_id: int
    demand_id: str = ''
    config: Optional[ControllerConfig] = None   # the config it was planned with
    timing: Optional[Timing] = None     # the points' times (timed_plan); None: the law's
    timing_note: str = ''               # plan_demand's note: '', 'as given', or why not
    profile: str = ''                   # the demand's own profile ('': the parameter's)


def _and_more(count):
    """Return ' (and <count - 1> more)' after the first of ``count`` offences ('' for one)."""
    return f' (and {count - 1} more)' if count > 1 else ''


class DemandIntake:
    """The demand protocol of one arm's controller (module docstring)."""

    def __init__(self, arm: ArmModel, robot: Robot, core_state: CoreState):
        """Take demands for ``arm`` into ``robot``, stepping ``core_state``'s state machine."""
        self.arm = arm
        self.robot = robot
        self.core_state = core_state

    def snapshot(self) -> Snapshot:
        """Return the ``Snapshot`` a demand is planned from (call it under the node's lock)."""
        shared = self.core_state
        state, ref = shared.state, self.robot.reference          # each read once
        moving = state != sm.IDLE and ref is not None
        q = self.robot.q if self.robot.measured else None
        return Snapshot(state, ref if moving else (q, None), moving, shared.motion_id,
                        shared.message)

    def prepare_demand(self, now: float, waypoints: np.ndarray, snapshot: Snapshot,
                       demand_id: str = '', timing: Optional[Timing] = None,
                       profile: str = '', planner: Optional[Planner] = None) -> PendingDemand:
        """
        Check a demand and plan it from ``snapshot``; return a ``PendingDemand``.

        Reads nothing of the controller but ``snapshot`` (and the constant arm and config), so
        a node calls it without holding its lock while the ticks go on (planning the continuous
        law takes tens of milliseconds), with a snapshot taken under the lock, then
        ``commit_demand`` under the lock. Raises ``InvalidInputError`` (nothing changed) when
        the demand is empty, has the wrong shape, non-finite values or values outside the joint
        limits, when the controller cannot take a demand (no joint states, fault, stopping),
        when the motion collides, and for an unknown ``profile``. With ``timing`` (a goal's
        ``time_from_start`` and velocities) the plan follows it where it can
        (``timed_plan.plan_demand``; its note goes to the status as ``timing``). ``profile``
        times this demand only (``law_for``). ``planner(job, guard)`` makes the plan of the
        ``PlanJob`` (default: ``job.run(guard)`` here; a node may run it in another process).
        Raises ``NotAcceptingError`` when the snapshot's state takes no demand.
        """
        derived = self.core_state.derived     # read once: the config and its limits together
        config, vlim = derived.config, derived.velocity_limits
        Q = self.check_demand(waypoints)
        self._check_accepts(snapshot.state, snapshot.message)
        q_start, qd_start = snapshot.start
        if q_start is None:
            raise InvalidInputError(f'cannot take a demand while {snapshot.state}: no joint '
                                    f'states yet')
        job = PlanJob(self.law_for(profile, config), q_start, Q, vlim, qd_start, timing,
                      self.arm.lower, self.arm.upper)
        guard = self.core_state.collision_guard   # raises InvalidInputError: the motion collides
        plan, note = job.run(guard) if planner is None else planner(job, guard)
        return PendingDemand(now, Q, plan, snapshot.moving, snapshot.motion_id, demand_id,
                             config, timing, note, profile)

    def law_for(self, profile: str = '', config: Optional[ControllerConfig] = None) -> LawConfig:
        """
        Return the law of a demand: ``config``'s (default: in force) with its own ``profile``.

        A demand's profile ('' : none) changes that demand's law only, never the configuration;
        an unknown one raises ``InvalidInputError`` (the demand is refused with the reason).
        """
        law = (self.core_state.config if config is None else config).law
        if not profile or profile == law.profile:
            return law
        return replace(law, profile=profile)

    def check_demand(self, waypoints: np.ndarray) -> np.ndarray:
        """Return the demand as (N, n) [rad] inside the limits, or raise ``InvalidInputError``."""
        n = self.arm.n_joints
        Q = np.asarray(waypoints, dtype=float)
        if Q.size == 0:
            raise InvalidInputError('demand is empty')
        if Q.ndim == 1:
            if Q.size % n:
                raise InvalidInputError(f'demand length {Q.size} is not a multiple of {n}')
            Q = Q.reshape(-1, n)
        if Q.ndim != 2 or Q.shape[1] != n:
            raise InvalidInputError(f'demand must have shape (N, {n}), got {Q.shape}')
        # The first offence and a count, never every waypoint: a reason stays small.
        finite = np.all(np.isfinite(Q), axis=1)
        if not np.all(finite):
            bad = np.flatnonzero(~finite)
            raise InvalidInputError(f'demand has non-finite values: waypoint {bad[0]} of '
                                    f'{len(Q)}{_and_more(bad.size)}')
        inside = np.all((Q >= self.arm.lower - 1e-6) & (Q <= self.arm.upper + 1e-6), axis=1)
        if not np.all(inside):
            bad = np.flatnonzero(~inside)
            raise InvalidInputError(
                f'demand outside joint limits: waypoint {bad[0]} of {len(Q)}: '
                + ', '.join(self.arm.limit_violations(Q[bad[0]], tol=1e-6))
                + _and_more(bad.size))
        return np.clip(Q, self.arm.lower, self.arm.upper)   # float32 rounding at a limit

    def commit_demand(self, pending: PendingDemand, start: Optional[float] = None) -> int:
        """
        Start a prepared demand; return the motion id.

        Its time counts from ``start`` [s] (default: when it was prepared, which a plan from a
        moving reference needs; a plan from rest may start when committed, however long its
        planning took).

        Call it under the node's lock. When the controller moved on since the snapshot (the
        motion ended, another started: ``is_current`` is False) the demand is planned again
        from a new snapshot; raises when it cannot take a demand any more.
        """
        shared = self.core_state
        self._check_accepts(shared.state)
        plan, note = pending.plan, pending.timing_note
        if not self.is_current(pending):
            q_start, qd_start = self.snapshot().start
            job = PlanJob(self.law_for(pending.profile), q_start, pending.waypoints,
                          shared.derived.velocity_limits, qd_start, pending.timing,
                          self.arm.lower, self.arm.upper)
            plan, note = job.run(self.core_state.collision_guard)   # checked by the guard too
        shared.timing = note
        self.robot.give(plan, pending.now if start is None else start)
        shared.motion_id += 1
        shared.waypoints_total, shared.waypoint = len(pending.waypoints), 0
        shared.result = {}
        shared.rejection = {}
        shared.arrived_at = None
        shared.motion_profile = pending.profile or shared.config.law.profile
        shared.step(sm.DEMAND, 'OK', f'motion {shared.motion_id}: {len(pending.waypoints)} '
                                     f'waypoint(s), {shared.motion_profile}, '
                                     f'{plan.duration:.2f} s')
        return shared.motion_id

    def is_current(self, pending: PendingDemand) -> bool:
        """
        Return whether ``pending`` still fits the controller (``commit_demand`` would not re-plan).

        It does not once the motion it was planned from ended or another one started; a node
        then prepares the demand again without its lock rather than let the commit plan under
        it (the ticks would wait for the planning).
        """
        snapshot = self.snapshot()
        return (snapshot.moving == pending.moving and snapshot.motion_id == pending.motion_id
                and self.core_state.state in sm.ACCEPTS_DEMANDS
                and pending.config is self.core_state.config)

    def reject(self, now: float, reason: str, demand_id: str = '') -> None:
        """Note a refused demand: reason, time [s] and id stay in the status until one is taken."""
        self.core_state.rejection = {K.REJECTED: short_text(reason),
                                     K.REJECTED_TIME: f'{now:.3f}',
                                     K.REJECTED_GOAL_ID: str(demand_id)}
        self.core_state.changed = True

    def refusal(self) -> Optional[NotAcceptingError]:
        """Return why no demand is taken in the state now (None: one is); under the lock."""
        shared = self.core_state
        if shared.state in sm.ACCEPTS_DEMANDS:
            return None
        return NotAcceptingError(shared.state, shared.message)

    def _check_accepts(self, state, message=None):
        if state not in sm.ACCEPTS_DEMANDS:
            raise NotAcceptingError(state,
                                    self.core_state.message if message is None else message)
