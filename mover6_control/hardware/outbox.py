"""
The frames the arm driver sends, in the order it queued them, at most one every ``gap`` seconds.

The vendor's driver writes one frame, then sleeps 5 ms (``Bus.cpp``; its CPRog configuration
says a 5 ms gap too): ``gap`` is the driver's ``frame_gap``. Every frame gets a sequence number
when it is queued; frames go out in that order, so a reply that echoes a set-point with a higher
number than a command's came after the module took the command. Each frame is planned when it is
queued, ``gap`` after the frame before it (or at ``not_before``: the second frame of enable,
referencing and set zero, 20 ms after the first; the frames behind it wait with it, so the order
holds). A control thread that wakes late sends every frame whose plan has passed at once: a
late thread catches up instead of falling further behind each cycle (one frame per late wake-up
would leave the last modules of a cycle without their set-points, and their watchdogs would
trip). Each frame sent also goes to the frame
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
        self._queue = deque()         # (planned [s], can_id, data)
        self._plan_tail = float('-inf')  # when the last frame queued is planned to go [s]

    def put(self, can_id: int, data: bytes, now: float,
            not_before: float = float('-inf')) -> int:
        """
        Queue one frame at ``now`` [s], to go no sooner than ``not_before``; return its sequence.

        It is planned ``gap`` after the frame queued before it, and not before ``now``.
        """
        self.seq += 1
        self._plan_tail = max(now, not_before, self._plan_tail + self.gap)
        self._queue.append((self._plan_tail, can_id, bytes(data)))
        return self.seq

    def __len__(self) -> int:
        """Return how many frames wait."""
        return len(self._queue)

    def next_due(self) -> Optional[float]:
        """Return when the next frame is planned to go [s], or None when none waits."""
        return self._queue[0][0] if self._queue else None

    def send_due(self, now: float) -> int:
        """Send every frame whose planned time has come at ``now`` [s]; return how many went."""
        sent = 0
        while self._queue and self._queue[0][0] <= now + 1e-9:
            _, can_id, data = self._queue.popleft()
            self.send_now(can_id, data)
            self.sent_at[can_id] = now
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
