"""
The controller core under the node's concurrency model: one lock, snapshot, plan outside, commit.

``ControllerNode`` touches the core from three threads (docs/architecture.md, "Threads"): the
tick thread (``tick``), the executor (``on_joint_states``, ``request_stop``, ``reset``) and the
demand thread, which takes a ``snapshot`` under the lock, plans from it without the lock
(``prepare_demand``) and commits under the lock (``commit_demand``) only if ``is_current``.

- a regression test for the race of the old ``prepare_demand``, which read ``_ref`` (now the
  robot's ``reference``) twice outside the lock: a tick clearing it in between raised inside
  the demand thread (on the ``DemandIntake`` part alone, with a robot that races);
- a seeded random schedule of those steps (thousands of interleavings, deterministic), and the
  same steps from real threads, checking the invariants: no exception, every demand accepted
  or refused with a reason (kept in the status), every command finite and inside the limits, a
  zero command in fault.
"""

import random
import threading

from core_testing import send_states, send_states_lacking
from mover6_control.control import state_machine as sm
from mover6_control.control.controller_config import ControllerConfig, derive_config
from mover6_control.control.controller_core import ControllerCore
from mover6_control.control.core_state import CoreState
from mover6_control.control.demand_intake import DemandIntake
from mover6_control.control.profiles import LawConfig
from mover6_control.control.robot import Robot
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import mover6
from mover6_control.nodes.controller.demand_thread import (DemandThread, WAIT_FOR_STATES,
                                                           WORKER_POINTS)
from mover6_control.nodes.controller.goal_ledger import GoalLedger
from mover6_control.nodes.messages.demand_acks import Answer
from mover6_control.nodes.messages.demand_messages import make_demands
import numpy as np
import pytest

ARM = mover6()
DT = 0.01


class RacingRobot(Robot):
    """A robot whose ``reference`` is cleared (as a tick ending the motion does) after a read."""

    clear_after_next_read = False

    @property
    def reference(self):
        value = self.__dict__.get('_ref_value')
        if self.clear_after_next_read:
            self.clear_after_next_read = False
            self.__dict__['_ref_value'] = None       # the tick thread ran just now
        return value

    @reference.setter
    def reference(self, value):
        self.__dict__['_ref_value'] = value


def test_a_tick_clearing_the_reference_during_prepare_demand_changes_nothing():
    # The old prepare_demand read `_ref` for `moving`, then again for the start: a tick between
    # the two reads (the motion ended) made the second None: TypeError in the demand thread,
    # the demand dropped with no status.
    config = ControllerConfig(law=LawConfig(profile='synchronised'))
    shared = CoreState(derive_config(ARM, config))
    base = Robot.from_arm(ARM)
    robot = RacingRobot(base.name, base.joints)
    intake = DemandIntake(ARM, robot, shared)
    q = np.zeros(6)
    robot.measure(0.0, ARM.joint_names, q, q)
    shared.state = sm.IDLE
    intake.commit_demand(intake.prepare_demand(0.0, [[0.2, 0.1, 0.0, 0.0, 0.0, 0.0]],
                                               intake.snapshot()))
    robot.reference = (q, np.full(6, 0.1))           # what the tick at DT followed
    assert shared.state == sm.EXECUTING and shared.motion_id == 1
    robot.clear_after_next_read = True
    pending = intake.prepare_demand(DT, [[0.3, 0.0, 0.0, 0.0, 0.0, 0.0]], intake.snapshot())
    assert pending.moving and robot.__dict__['_ref_value'] is None   # the race happened
    assert not intake.is_current(pending)
    motion = intake.commit_demand(pending)       # planned again, from rest at the measured q
    assert motion == 2 and shared.state == sm.EXECUTING
    np.testing.assert_allclose(robot.plan.q_goal, [0.3, 0.0, 0.0, 0.0, 0.0, 0.0])
    assert np.all(np.isfinite(robot.plan.duration))


class Harness:
    """The core, a lock, a simple arm that follows the command, and the invariants."""

    def __init__(self, seed, profile):
        self.rng = random.Random(seed)
        self.core = ControllerCore(ARM, ControllerConfig(law=LawConfig(profile=profile)))
        self.lock = threading.Lock()
        self.q = np.zeros(6)
        self.now = 0.0
        self.vlim = np.asarray(ARM.velocity_limits)
        self.accepted = self.refused = 0
        self.states_seen = set()

    def random_demand(self):
        """Mostly valid waypoints; sometimes outside the limits, non-finite or empty."""
        kind = self.rng.random()
        n = self.rng.randint(1, 3)
        Q = np.array([[self.rng.uniform(lo * 0.9, hi * 0.9) for lo, hi in
                       zip(ARM.lower, ARM.upper)] for _ in range(n)])
        if kind < 0.1:
            Q[0, self.rng.randrange(6)] = 5.0
        elif kind < 0.15:
            Q[0, 0] = np.nan
        elif kind < 0.18:
            Q = np.zeros((0, 6))
        return Q

    def demand_steps(self):
        """Yield between the node's steps of one demand: snapshot, plan, commit."""
        Q = self.random_demand()
        for attempt in range(3):
            with self.lock:
                snapshot = self.core.snapshot()
                now = self.now
            yield
            try:
                pending = self.core.prepare_demand(now, Q, snapshot, f'd{id(Q)}')
            except InvalidInputError as err:
                self.refuse(now, err)
                return
            yield
            with self.lock:
                if attempt == 2 or self.core.is_current(pending):
                    try:
                        self.core.commit_demand(pending)
                    except InvalidInputError as err:
                        self.refuse(now, err, locked=True)
                        return
                    self.accepted += 1
                    assert 'rejected' not in self.core.status().values
                    return
            yield

    def refuse(self, now, err, locked=False):
        assert str(err)
        if locked:
            self.core.reject(now, str(err))
        else:
            with self.lock:
                self.core.reject(now, str(err))
        with (self.lock if not locked else _Null()):
            assert self.core.status().values['rejected'] == str(err)
        self.refused += 1

    def tick(self):
        with self.lock:
            self.now += DT
            out = self.core.tick(self.now)
        assert np.all(np.isfinite(out.qd)) and np.all(np.isfinite(out.jog))
        assert np.all(np.abs(out.qd) <= self.vlim + 1e-9)
        assert np.all(self.q + out.qd * DT <= ARM.upper + 1e-9)
        assert np.all(self.q + out.qd * DT >= ARM.lower - 1e-9)
        if out.state == sm.FAULT or out.state not in sm.MOVING_STATES:
            assert not np.any(out.qd)
        self.states_seen.add(out.state)
        self.q = self.q + out.qd * DT

    def event(self):
        """One executor callback: states (fresh, missing, invalid), stop or reset."""
        r = self.rng.random()
        with self.lock:
            if r < 0.75:
                send_states(self.core, self.now, self.q + self.rng.gauss(0, 1e-4))
            elif r < 0.8:
                send_states_lacking(self.core, self.now, 'joint5')
            elif r < 0.85:
                self.now += 0.3                      # states go stale
            elif r < 0.93:
                ok, message = self.core.request_stop(self.now)
                assert ok and message
            else:
                self.core.reset(self.now)


class _Null:
    def __enter__(self):
        return self

    def __exit__(self, *args):
        return False


@pytest.mark.parametrize('seed', range(6))
def test_random_interleavings_keep_the_invariants(seed):
    h = Harness(seed, ('synchronised', 'trapezoidal', 'continuous')[seed % 3])
    demands = []
    steps = 0
    for _ in range(3000):                 # scheduling decisions per seed
        r = h.rng.random()
        if r < 0.4:
            h.tick()
        elif r < 0.65:
            h.event()
        else:
            if not demands or h.rng.random() < 0.1:
                demands.append(h.demand_steps())
            gen = h.rng.choice(demands)
            try:
                next(gen)
            except StopIteration:
                demands.remove(gen)
        steps += 1
    for gen in demands:                   # every demand ends accepted or refused
        for _ in gen:
            h.tick()
    assert steps == 3000
    assert h.accepted > 10 and h.refused > 10
    assert {sm.EXECUTING, sm.FAULT, sm.IDLE} <= h.states_seen


# Demands a run of real threads takes to the end (accepted or refused) before it stops.
DEMANDS = 40


def test_real_threads_keep_the_invariants():
    h = Harness(99, 'synchronised')
    errors = []
    stop = threading.Event()

    def run(body):
        try:
            while not stop.is_set():
                body()
        except Exception as err:  # noqa: B902 - report any failure of any thread
            errors.append(err)
            stop.set()

    def demands():
        for _ in h.demand_steps():
            pass
        if h.accepted + h.refused >= DEMANDS:   # enough demands ended: the run is over
            stop.set()

    threads = [threading.Thread(target=run, args=(f,)) for f in (h.tick, h.event, demands)]
    for t in threads:
        t.start()
    finished = stop.wait(60.0)        # a bound for a hung thread only; it ends by the count
    stop.set()
    for t in threads:
        t.join()
    assert not errors, errors
    assert finished and h.accepted + h.refused >= DEMANDS


class DemandHarness:
    """
    A ``DemandThread`` built alone around a real core; the clock is ``self.t``.

    ``tick()`` is the tick thread's step (the core's tick, then ``has_states`` as
    ``tick_loop.TickLoop.on_tick`` sets it); ``plan_worker`` plans here and runs
    ``plan_worker.during`` first (what the ticks do while a large demand is planned). The log,
    the guard's refusals and the answers to goal demands are recorded (``logged``, ``answers``).
    """

    def __init__(self):
        self.lock = threading.RLock()
        self.core = ControllerCore(ARM, ControllerConfig())
        self.goals = GoalLedger(self.lock)
        self.has_states = threading.Event()
        self.t = 0.0
        self.plan_worker = DuringPlan()
        self.logged = []
        self.answers = RecordedAnswers()
        self.demands = DemandThread(self.core, self.lock, self.goals, self.answers,
                                    lambda now, **kwargs: None, self.has_states,
                                    self.plan_worker, lambda: self.t, RecordedLog(self.logged),
                                    RecordedGuard(self.logged), '/joint_demands')

    def take_demand(self, msg):
        self.demands.take_demand(msg)

    def tick(self, states=True):
        with self.lock:
            self.t += DT
            if states:
                send_states(self.core, self.t, np.zeros(6))
            out = self.core.tick(self.t)
        (self.has_states.clear if out.state in WAIT_FOR_STATES else self.has_states.set)()
        return out.state


class RecordedLog:
    """The node's logger as the demand thread uses it: the lines go to a list."""

    def __init__(self, lines):
        self.lines = lines

    def info(self, text):
        self.lines.append(text)

    warning = info


class RecordedGuard:
    """The node's callback guard as a refused demand uses it: noted in the log."""

    def __init__(self, lines):
        self.lines = lines

    def refuse(self, source, err):
        self.lines.append(f'{source}: refused: {err}')


class RecordedAnswers:
    """The answers to goal demands (``DemandAnswers``), recorded: goal id -> (answer, text)."""

    def __init__(self):
        self.given = {}

    def received(self, goal_id):
        self.given[goal_id] = (Answer.RECEIVED, '')

    def answer(self, goal_id, answer, text):
        self.given[goal_id] = (answer, text)

    def repeat(self, goal_id):
        return goal_id in self.given


class DuringPlan:
    """The planning process's part in ``DemandHarness``: runs ``during`` once, then plans."""

    def __init__(self):
        self.during = None

    def ready(self):
        return True

    def __call__(self, job, guard):
        if self.during is not None:
            during, self.during = self.during, None
            during()
        return job.run(guard)


def test_a_fault_that_clears_while_a_demand_is_planned_does_not_refuse_it():
    """
    The states went stale while a large demand was planned, and came back: it is taken.

    Before, the commit refused it ('cannot take a demand while fault: /joint_states stale'),
    naming a fault that cleared a tick later (issue 21, item 6). Now the demand waits for valid
    states (DEMAND_STATE_WAIT) and is planned again; refused only if the fault stays, and then
    for the state the controller is in when it refuses.
    """
    h = DemandHarness()
    assert h.tick() == sm.IDLE

    def stale_then_back():
        while h.tick(states=False) != sm.FAULT:       # states stale: fault
            pass
        timer = threading.Timer(0.3, lambda: [h.tick() for _ in range(3)])
        timer.start()                                   # fresh states again, 0.3 s later
    h.plan_worker.during = stale_then_back
    Q = np.linspace(0.0, 0.3, WORKER_POINTS)[:, None] * np.ones(6)
    h.take_demand(make_demands(Q, 'large-1'))
    assert h.core.state == sm.EXECUTING, h.logged
    assert h.goals.withdraw('large-1') == 1, h.logged
    assert h.answers.given['large-1'] == (Answer.TAKEN, 'motion 1')
    assert 'rejected' not in h.core.status().values

    # The fault stays: refused after the wait, naming the fault it is in then.
    while h.tick(states=False) != sm.FAULT:
        pass
    h.take_demand(make_demands(Q[::-1], 'large-2'))
    reason = h.goals.withdraw('large-2')
    assert reason.startswith('cannot take a demand while fault: /joint_states stale'), reason
    assert h.answers.given['large-2'] == (Answer.NOT_READY, reason)
