"""
Exceptions shared by the ROS-free core.

Every error raised by the core on bad input is a ``ValueError`` subclass, so callers (the nodes)
can catch one type, log ``str(err)`` and drop the input.
"""


class Mover6Error(Exception):
    """Base of every exception the core raises on purpose."""


class InvalidInputError(Mover6Error, ValueError):
    """An argument has the wrong shape, a non-finite value or an out-of-range setting."""


class UnreachableError(Mover6Error, ValueError):
    """A pose or path cannot be reached; ``reason`` is a short machine-readable code."""

    def __init__(self, message: str, reason: str = 'unreachable',
                 details: dict | None = None) -> None:
        super().__init__(message)
        self.reason = reason
        self.details = dict(details or {})
