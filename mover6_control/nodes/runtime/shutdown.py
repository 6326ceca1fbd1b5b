"""
Run one node in its process until SIGINT, SIGTERM or shutdown; then tear it down once, cleanly.

``ros2 launch`` (and a terminal's Ctrl-C) can deliver a signal twice: the terminal sends SIGINT
to the whole process group and launch forwards its own SIGINT to each node tens of milliseconds
later, then escalates to SIGTERM. With rclpy's own handlers the first signal shuts the context
down at once (too early for the controller's last zero JointJog) and the second lands inside
``destroy_node()`` as a ``KeyboardInterrupt``: exit code -2 and a half-destroyed node. Here rclpy
installs no handlers; ours only notes the first SIGINT or SIGTERM and does nothing on every later
one. It stays installed until teardown is over: switching to SIG_IGN in the handler lost a race
(a SIGINT that came while the SIGTERM before it was still waiting for its Python handler then
raised 'OSError: Signal 2 ignored due to race condition' in the main thread). The main thread
spins in short slices and checks the note between them (a Python signal handler runs only when
the main thread runs Python code, never inside the DDS wait). Teardown then runs to its end with
the context still valid, and the process exits 0. A slice runs every callback that comes in it
(``spin_until_future_complete`` on a future nobody completes), not one callback per call.
"""

import signal
import sys
from types import FrameType
from typing import Callable, Optional

from mover6_control.nodes.runtime import local_dds
import rclpy
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.experimental.events_executor import EventsExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
# Longest time [s] between a stop signal and the start of teardown (plus a running callback).
SPIN_SLICE = 0.1


class StopSignals:
    """Note the first SIGINT or SIGTERM; any later one does nothing (teardown must finish)."""

    def __init__(self):
        self.signum = None
        for signum in STOP_SIGNALS:
            signal.signal(signum, self.on_signal)

    def on_signal(self, signum: int, frame: Optional[FrameType]) -> None:
        """Record the first stop signal; a later one changes nothing."""
        if self.signum is None:
            self.signum = signum

    @staticmethod
    def ignore_from_now() -> None:
        """
        Ignore SIGINT and SIGTERM for the rest of the process (call it once teardown is done).

        The interpreter puts the default action back for a signal whose handler is a Python
        function when it exits, so a second signal in its last milliseconds would end the
        process with -2; SIG_IGN stays. ``signal.signal`` runs the handlers of signals already
        pending first; one that slips in during the switch itself raises ``OSError`` (the
        race): it was a repeated stop signal, and is dropped.
        """
        try:
            for signum in STOP_SIGNALS:
                signal.signal(signum, signal.SIG_IGN)
        except OSError:
            for signum in STOP_SIGNALS:
                signal.signal(signum, signal.SIG_IGN)

    @property
    def received(self) -> bool:
        """Return True once a stop signal came."""
        return self.signum is not None


def run_node(make_node: Callable[..., Node], args: Optional[list[str]] = None,
             make_executor: Callable[[], Executor] = EventsExecutor) -> None:
    """
    Init rclpy, make the node with ``make_node()``, spin it until a stop; destroy it, shut down.

    ``make_executor()`` gives the executor (a node whose services wait for hardware needs a
    multi-threaded one).

    Returns normally (exit code 0) on SIGINT, SIGTERM (once or repeatedly) and external
    shutdown; errors while making or running the node propagate. A node that sets ``fatal``
    (why it cannot go on, e.g. a tick thread that cannot run) is torn down the same way, then
    ``SystemExit`` with that reason ends the process with exit code 1, so a launcher sees it.
    A node asked for the local DDS configuration (``MOVER6_DDS=local``) that did not get it is
    not made: the reason is printed and the process exits with code 1 (``local_dds``).
    """
    stop = StopSignals()
    node = None
    try:
        local_dds.check_environment()
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
        if not stop.received:
            node = local_dds.make_checked_node(make_node)
            executor = make_executor()
            executor.add_node(node)
            while not stop.received and rclpy.ok() and not getattr(node, 'fatal', None):
                # Every callback of a slice in one call: spin_once returned to Python after each
                # (100 /joint_states a second), a wake-up and a loop pass per message.
                executor.spin_until_future_complete(Future(), timeout_sec=SPIN_SLICE)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except local_dds.LocalDdsError as err:
        print(f'[FATAL] {err}', file=sys.stderr, flush=True)
        raise SystemExit(1)
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        stop.ignore_from_now()
    fatal = getattr(node, 'fatal', None)
    if fatal:
        raise SystemExit(f'fatal: {fatal}')
