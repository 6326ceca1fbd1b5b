"""
The frames the arm driver sends, in the order it queued them, at most one every ``gap`` seconds.

The vendor's driver writes one frame, then sleeps 5 ms (``Bus.cpp``; its CPRog configuration
says a 5 ms gap too): ``gap`` is the driver's ``frame_gap``. Every frame gets a sequence number
when it is queued; frames go out in that order, so a reply that echoes a set-point with a higher
number than a command's came after the module took the command. A frame may also wait for a time
(``not_before``: the second frame of enable, referencing and set zero, 20 ms after the first);
the frames behind it wait with it, so the order holds. Each frame sent also goes to the frame
log, if there is one (``is_rx`` False, wall-clock time).
"""

from __future__ import annotations

from collections import deque
import time
from typing import Optional

import can


class Outbox:
    """Queue frames for ``bus`` and send them in order, ``gap`` [s] apart."""

    def __init__(self, bus: can.BusABC, gap: float,
                 frame_log: Optional[can.Listener] = None) -> None:
        """Send on ``bus``; ``gap`` [s] >= 0 between two frames; log each to ``frame_log``."""
        self.bus = bus
        self.gap = float(gap)
        self.frame_log = frame_log
        self.seq = 0                  # the sequence number of the last frame queued
        self.tx_errors = 0
        self.error = ''
        self.sent_at = {}             # can_id -> when a frame last went to it [s]
        self._queue = deque()         # (not_before [s], can_id, data)
        self._last: Optional[float] = None

    def put(self, can_id: int, data: bytes, not_before: float = float('-inf')) -> int:
        """Queue one frame, to go no sooner than ``not_before`` [s]; return its sequence."""
        self.seq += 1
        self._queue.append((not_before, can_id, bytes(data)))
        return self.seq

    def __len__(self) -> int:
        """Return how many frames wait."""
        return len(self._queue)

    def next_due(self) -> Optional[float]:
        """Return when the next frame may go [s], or None when none waits."""
        if not self._queue:
            return None
        due = self._queue[0][0]
        if self._last is not None:
            due = max(due, self._last + self.gap)
        return due

    def send_due(self, now: float) -> int:
        """Send the frames whose time has come at ``now`` [s]; return how many went."""
        sent = 0
        while self._queue:
            due = self.next_due()
            if due > now + 1e-9:
                break
            _, can_id, data = self._queue.popleft()
            self.send_now(can_id, data)
            self.sent_at[can_id] = self._last = now
            sent += 1
        return sent

    def send_now(self, can_id: int, data: bytes) -> None:
        """Send one frame at once, past the queue (the driver's last frames when it closes)."""
        msg = can.Message(arbitration_id=can_id, is_extended_id=False, data=data, is_rx=False,
                          timestamp=time.time())
        try:
            self.bus.send(msg)
        except can.CanError as err:
            self.tx_errors += 1
            self.error = f'send failed: {err}'
            return
        if self.frame_log is not None:
            self.frame_log(msg)

    def clear(self) -> None:
        """Drop every frame that waits."""
        self._queue.clear()
