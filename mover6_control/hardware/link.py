"""
The arm driver's watch on its link to the adapter: lost, reopened with back-off, back.

A bus that can lose its device (the USB2CAN adapter, ``usb2can.Usb2CanBus``: ``connected``
False after a failed read or write) is reopened by ``LinkWatch.poll`` at growing intervals
(``BACKOFF`` doubling up to ``BACKOFF_MAX``): a device that is gone is not hammered, one that
comes back is found within ``BACKOFF_MAX``. A bus without ``connected`` (python-can's own
interfaces) is always up here: its errors are counted by the driver, not taken for a lost link.
What the driver does meanwhile (hold, forget every position, read them again, stay not enabled)
is the driver's (``hardware.driver``); this part only keeps the link's state and its text.
"""

from __future__ import annotations

from typing import Optional

import can

BACKOFF = 0.1
"""[s] the first wait before a lost link is reopened; it doubles at each failed attempt."""
BACKOFF_MAX = 2.0
"""[s] the longest wait between two attempts to reopen."""


class LinkWatch:
    """The state of the link to ``bus``: up, or lost since when, and the next attempt."""

    def __init__(self, bus: can.BusABC, backoff: float = BACKOFF,
                 backoff_max: float = BACKOFF_MAX) -> None:
        """Watch ``bus``; reopen it ``backoff`` [s] after a loss, doubling to ``backoff_max``."""
        self.bus = bus
        self.backoff = float(backoff)
        self.backoff_max = float(backoff_max)
        self.lost_at: Optional[float] = None     # when the loss was seen [s], None: up
        self.attempts = 0                        # attempts to reopen since the loss
        self.losses = 0                          # links lost so far
        self.recoveries = 0                      # links reopened so far
        self.last_outage = 0.0                   # [s] the last loss to its reopening
        self._next = 0.0

    def is_up(self) -> bool:
        """Tell whether the bus has its device (always, for a bus that cannot lose it)."""
        return bool(getattr(self.bus, 'connected', True))

    def lost(self, now: float) -> bool:
        """Return True when the link went since the last call at ``now`` [s] (a new loss)."""
        if self.lost_at is not None or self.is_up():
            return False
        self.lost_at, self.attempts = now, 0
        self.losses += 1
        self._next = now + self.backoff
        return True

    def poll(self, now: float) -> bool:
        """While lost, try to reopen when due at ``now`` [s]; return True once it is back."""
        if self.lost_at is None:
            return False
        if now < self._next:
            return False
        self.attempts += 1
        if self.bus.reopen():
            self.last_outage = now - self.lost_at
            self.lost_at = None
            self.recoveries += 1
            return True
        self._next = now + min(self.backoff * 2 ** self.attempts, self.backoff_max)
        return False

    def reason(self, now: float) -> str:
        """Return why the arm holds while the link is lost ('' while it is up)."""
        if self.lost_at is None:
            return ''
        why = getattr(self.bus, 'link_error', '') or 'the adapter went'
        return (f'link to the CAN adapter lost {now - self.lost_at:.1f} s ago ({why}): the '
                f'modules stop on their watchdog; reopening (attempt {self.attempts}, next in '
                f'{max(0.0, self._next - now):.1f} s); once back every position is read again '
                'and the arm stays disabled until reset and enable')
