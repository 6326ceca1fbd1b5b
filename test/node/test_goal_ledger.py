"""The controller node's goal ledger: bounded, one outcome per goal, a future for the waiting."""

import threading

from mover6_control.nodes.controller.goal_ledger import GoalLedger
import pytest

pytestmark = pytest.mark.node     # rclpy's Future (no context, no node)


def test_a_goal_taken_completes_its_future_with_the_motion():
    ledger = GoalLedger(threading.RLock())
    taken = ledger.expect('g1')
    assert not taken.done() and not ledger.known('g1')
    ledger.started(7, 'g1', 12.5)
    assert taken.done() and taken.result() == 7
    assert ledger.known('g1') and ledger.goal_of(7) == 'g1' and ledger.start_of(7) == 12.5
    assert ledger.withdraw('g1') == 7          # taken: never withdrawn
    assert not ledger.withdrawn('g1')


def test_a_goal_refused_completes_its_future_with_the_reason():
    ledger = GoalLedger(threading.RLock())
    taken = ledger.expect('g2')
    ledger.refused('g2', 'outside the joint limits')
    assert taken.result() == 'outside the joint limits'
    assert ledger.withdraw('g2') == 'outside the joint limits'


def test_an_outcome_before_the_wait_is_already_done():
    ledger = GoalLedger(threading.RLock())
    ledger.started(1, 'early', 0.0)
    assert ledger.expect('early').result() == 1


def test_a_goal_withdrawn_is_never_started_and_close_wakes_the_waiting():
    ledger = GoalLedger(threading.RLock())
    late = ledger.expect('late')
    assert ledger.withdraw('late') is None and ledger.withdrawn('late')
    other = ledger.expect('other')
    ledger.close()
    assert other.done() and other.result() is None
    assert not late.done()                      # withdrawn: nobody waits for it any more


def test_a_motion_without_a_goal_is_known_by_its_start_only():
    ledger = GoalLedger(threading.RLock())
    ledger.started(3, '', 1.0)
    assert ledger.goal_of(3) == '' and ledger.start_of(3) == 1.0
    assert ledger.goal_of(4) == '' and ledger.start_of(4) is None


def test_the_ledger_keeps_only_the_latest_goals_and_motions():
    ledger = GoalLedger(threading.RLock(), size=4)
    for k in range(10):
        ledger.started(k, f'g{k}', float(k))
        ledger.withdraw(f'w{k}')
    assert [ledger.known(f'g{k}') for k in range(10)] == [False] * 6 + [True] * 4
    assert [ledger.start_of(k) for k in range(6, 10)] == [6.0, 7.0, 8.0, 9.0]
    assert ledger.start_of(5) is None and not ledger.withdrawn('w5') and ledger.withdrawn('w9')
    sizes = (len(ledger._motion_goals), len(ledger._outcomes), len(ledger._withdrawn))
    assert sizes == (4, 4, 4)


class CountingLock:
    """A reentrant lock that counts how often it was taken."""

    def __init__(self):
        self.lock, self.taken = threading.RLock(), 0

    def __enter__(self):
        self.lock.acquire()
        self.taken += 1

    def __exit__(self, *exc):
        self.lock.release()


@pytest.mark.parametrize('call', [
    lambda g: g.expect('x'), lambda g: g.known('x'), lambda g: g.started(1, 'x', 0.0),
    lambda g: g.refused('x', 'no'), lambda g: g.withdraw('x'), lambda g: g.withdrawn('x'),
    lambda g: g.goal_of(1), lambda g: g.start_of(1), lambda g: g.close()])
def test_every_method_takes_the_nodes_lock(call):
    lock = CountingLock()
    ledger = GoalLedger(lock)
    call(ledger)
    assert lock.taken >= 1
