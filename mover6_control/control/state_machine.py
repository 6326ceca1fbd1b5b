"""
The controller's states and the table of transitions between them, with a pure step function.

::

    waiting_for_states --states_valid--> idle --demand--> executing --reference_done--> settling
    settling --settled | settle_timeout--> idle
    executing | settling --stop | path_error--> stopping --at_rest--> idle
    executing --demand--> executing (the new motion replaces the running one)
    idle | executing | settling | stopping --states_invalid--> fault
    fault --states_valid | reset--> idle | waiting_for_states
    idle --jog--> jogging --jog_done--> idle     (control.servo: a twist or joint jog)
    jogging --demand--> executing (from the jog's velocity) | --stop--> stopping
    jogging --states_invalid--> fault
    idle | executing | settling | stopping | jogging --tick_fault--> fault

Any (state, event) pair not in ``TRANSITIONS`` leaves the state unchanged: that is deliberate
(for example a stop request while idle, or a stale-state event while already in fault).
"""

from __future__ import annotations

from mover6_control.control.status import State

# The states (``status.State``: their names are the status schema's), short for the table.
WAITING_FOR_STATES = State.WAITING_FOR_STATES
IDLE = State.IDLE
EXECUTING = State.EXECUTING
SETTLING = State.SETTLING
STOPPING = State.STOPPING
FAULT = State.FAULT
JOGGING = State.JOGGING
STATES = tuple(str(state) for state in State)     # plain text, as the wire has it

STATES_VALID = 'states_valid'          # fresh, complete, finite joint states arrived
STATES_INVALID = 'states_invalid'      # joint states stale, incomplete or non-finite
DEMAND = 'demand'                      # a valid demand was accepted
REFERENCE_DONE = 'reference_done'      # the planned reference has reached its end
SETTLED = 'settled'                    # every joint within its goal tolerance
SETTLE_TIMEOUT = 'settle_timeout'      # not within tolerance in time
STOP = 'stop'                          # stop requested (service)
PATH_ERROR = 'path_error'              # tracking error above the path tolerance
AT_REST = 'at_rest'                    # the stopping ramp has ended
RESET = 'reset'                        # reset requested
JOG = 'jog'                            # a fresh twist or joint jog command arrived while idle
JOG_DONE = 'jog_done'                  # the jog commands went stale and the arm is at rest
TICK_FAULT = 'tick_fault'              # the tick raised, or a law made a non-finite command
EVENTS = (STATES_VALID, STATES_INVALID, DEMAND, REFERENCE_DONE, SETTLED, SETTLE_TIMEOUT, STOP,
          PATH_ERROR, AT_REST, RESET, JOG, JOG_DONE, TICK_FAULT)

TRANSITIONS = {
    (WAITING_FOR_STATES, STATES_VALID): IDLE,

    (IDLE, DEMAND): EXECUTING,
    (IDLE, STATES_INVALID): FAULT,

    (EXECUTING, DEMAND): EXECUTING,
    (EXECUTING, REFERENCE_DONE): SETTLING,
    (EXECUTING, STOP): STOPPING,
    (EXECUTING, PATH_ERROR): STOPPING,
    (EXECUTING, STATES_INVALID): FAULT,

    (SETTLING, SETTLED): IDLE,
    (SETTLING, SETTLE_TIMEOUT): IDLE,
    (SETTLING, DEMAND): EXECUTING,
    (SETTLING, STOP): STOPPING,
    (SETTLING, STATES_INVALID): FAULT,

    (STOPPING, AT_REST): IDLE,
    (STOPPING, STATES_INVALID): FAULT,

    (FAULT, STATES_VALID): IDLE,
    (FAULT, RESET): WAITING_FOR_STATES,

    (IDLE, JOG): JOGGING,
    (JOGGING, JOG_DONE): IDLE,
    (JOGGING, DEMAND): EXECUTING,
    (JOGGING, STOP): STOPPING,
    (JOGGING, STATES_INVALID): FAULT,

    (IDLE, TICK_FAULT): FAULT,
    (EXECUTING, TICK_FAULT): FAULT,
    (SETTLING, TICK_FAULT): FAULT,
    (STOPPING, TICK_FAULT): FAULT,
    (JOGGING, TICK_FAULT): FAULT,
}

# States in which the arm may be commanded to move; in the others the command is zero.
MOVING_STATES = frozenset({EXECUTING, SETTLING, STOPPING, JOGGING})
# States that accept a new demand.
ACCEPTS_DEMANDS = frozenset(state for state, event in TRANSITIONS if event == DEMAND)


def step(state: str, event: str) -> str:
    """
    Return the state after ``event`` in ``state`` (unchanged when the table has no entry).

    Raises ``ValueError`` for an unknown state or event, so a typo cannot pass silently.
    """
    if state not in STATES:
        raise ValueError(f'unknown state "{state}"; states are {STATES}')
    if event not in EVENTS:
        raise ValueError(f'unknown event "{event}"; events are {EVENTS}')
    return TRANSITIONS.get((state, event), state)


def accepts(state: str, event: str) -> bool:
    """Return True when ``event`` has a transition out of ``state`` in the table."""
    return (state, event) in TRANSITIONS
