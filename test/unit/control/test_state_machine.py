"""The controller's transition table and pure step function."""

from hypothesis import given, settings
import hypothesis.strategies as st
from mover6_control.control import state_machine as sm
import pytest


def run(events, state=sm.WAITING_FOR_STATES):
    for event in events:
        state = sm.step(state, event)
    return state


def test_normal_life_cycle():
    assert run([sm.STATES_VALID]) == sm.IDLE
    assert run([sm.STATES_VALID, sm.DEMAND]) == sm.EXECUTING
    assert run([sm.STATES_VALID, sm.DEMAND, sm.REFERENCE_DONE]) == sm.SETTLING
    assert run([sm.STATES_VALID, sm.DEMAND, sm.REFERENCE_DONE, sm.SETTLED]) == sm.IDLE
    assert run([sm.STATES_VALID, sm.DEMAND, sm.REFERENCE_DONE, sm.SETTLE_TIMEOUT]) == sm.IDLE


def test_stop_and_path_error_decelerate_then_idle():
    for cause in (sm.STOP, sm.PATH_ERROR):
        assert run([sm.STATES_VALID, sm.DEMAND, cause]) == sm.STOPPING
        assert run([sm.STATES_VALID, sm.DEMAND, cause, sm.AT_REST]) == sm.IDLE
    assert run([sm.STATES_VALID, sm.DEMAND, sm.REFERENCE_DONE, sm.STOP]) == sm.STOPPING


def test_new_demand_replaces_the_running_motion():
    assert sm.step(sm.EXECUTING, sm.DEMAND) == sm.EXECUTING
    assert sm.step(sm.SETTLING, sm.DEMAND) == sm.EXECUTING
    assert sm.ACCEPTS_DEMANDS == {sm.IDLE, sm.EXECUTING, sm.SETTLING, sm.JOGGING}


def test_jogging_starts_from_idle_only_and_gives_way_to_a_demand():
    assert sm.step(sm.IDLE, sm.JOG) == sm.JOGGING
    for state in (sm.EXECUTING, sm.SETTLING, sm.STOPPING, sm.FAULT, sm.WAITING_FOR_STATES):
        assert sm.step(state, sm.JOG) == state
    assert sm.step(sm.JOGGING, sm.JOG_DONE) == sm.IDLE
    assert sm.step(sm.JOGGING, sm.DEMAND) == sm.EXECUTING
    assert sm.step(sm.JOGGING, sm.STOP) == sm.STOPPING
    assert sm.JOGGING in sm.MOVING_STATES


@pytest.mark.parametrize('state', [sm.IDLE, sm.EXECUTING, sm.SETTLING, sm.STOPPING,
                                   sm.JOGGING])
def test_bad_states_fault_from_every_active_state(state):
    assert sm.step(state, sm.STATES_INVALID) == sm.FAULT


def test_fault_holds_until_valid_states_or_reset():
    for event in sm.EVENTS:
        after = sm.step(sm.FAULT, event)
        if event == sm.STATES_VALID:
            assert after == sm.IDLE
        elif event == sm.RESET:
            assert after == sm.WAITING_FOR_STATES
        else:
            assert after == sm.FAULT, event


def test_waiting_takes_nothing_but_states():
    for event in sm.EVENTS:
        expected = sm.IDLE if event == sm.STATES_VALID else sm.WAITING_FOR_STATES
        assert sm.step(sm.WAITING_FOR_STATES, event) == expected


def test_pairs_not_in_the_table_leave_the_state():
    assert sm.step(sm.IDLE, sm.STOP) == sm.IDLE
    assert sm.step(sm.STOPPING, sm.DEMAND) == sm.STOPPING
    assert not sm.accepts(sm.IDLE, sm.STOP)
    assert sm.accepts(sm.EXECUTING, sm.STOP)


def test_table_is_closed_and_names_are_checked():
    for (state, event), target in sm.TRANSITIONS.items():
        assert state in sm.STATES and event in sm.EVENTS and target in sm.STATES
    with pytest.raises(ValueError, match='unknown state'):
        sm.step('dancing', sm.STOP)
    with pytest.raises(ValueError, match='unknown event'):
        sm.step(sm.IDLE, 'sneeze')


def test_every_state_is_reachable_from_the_start():
    seen, frontier = {sm.WAITING_FOR_STATES}, [sm.WAITING_FOR_STATES]
    while frontier:
        state = frontier.pop()
        for event in sm.EVENTS:
            nxt = sm.step(state, event)
            if nxt not in seen:
                seen.add(nxt)
                frontier.append(nxt)
    assert seen == set(sm.STATES)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.sampled_from(sm.EVENTS), max_size=30))
def test_invalid_states_always_end_motion(events):
    state = run(events)
    assert state in sm.STATES
    after = sm.step(state, sm.STATES_INVALID)
    assert after not in sm.MOVING_STATES
    if state != sm.WAITING_FOR_STATES:
        assert after == sm.FAULT
