"""
The tick's figures on the controller's status: the longest gap between ticks, the oldest states.

``max_tick_gap`` [s] is the longest time between two ticks since the node started (node clock;
nominal ``1 / rate``); ``max_states_age`` [s] the age of the oldest valid /joint_states a tick
found (nominal the states' period plus a tick): how long their intake was held up at most.
Written by the tick thread only; read as text by the status.
"""

from mover6_control.control.status import StatusKey


class TickFigures:
    """The tick thread's figures (module docstring)."""

    def __init__(self):
        """Start with no tick seen."""
        self.last_tick = None            # node clock [ns] of the latest tick
        self.max_tick_gap = 0.0
        self.max_states_age = 0.0

    def note_tick(self, stamp_ns: int) -> float:
        """Record a tick at ``stamp_ns`` [ns] of the node clock; return the gap [s] (0 first)."""
        last, self.last_tick = self.last_tick, stamp_ns
        if last is None or stamp_ns < last:          # first tick, or the clock went back
            return 0.0
        gap = (stamp_ns - last) * 1e-9
        self.max_tick_gap = max(self.max_tick_gap, gap)
        return gap

    def note_states_age(self, age: float) -> None:
        """Record the age [s] of the states a tick used."""
        self.max_states_age = max(self.max_states_age, age)

    def forget_last_tick(self) -> None:
        """Count no gap across a clock switch."""
        self.last_tick = None

    def values(self) -> dict:
        """Return the status values ``max_tick_gap`` and ``max_states_age`` [s], as text."""
        return {StatusKey.MAX_TICK_GAP: f'{self.max_tick_gap:.4f}',
                StatusKey.MAX_STATES_AGE: f'{self.max_states_age:.4f}'}
