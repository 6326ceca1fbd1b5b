"""
The one guard every callback of every node runs through: bad input is refused, the node goes on.

A callback that raises inside rclpy's executor ends the executor's spin, and with it the node's
process (one ``/pose_goal`` with a NaN in its quaternion would end the markers node, and the
launcher then the whole stack). Each node makes one ``CallbackGuard`` and creates
its subscriptions, services, timers and parameter callbacks through it (``subscription``,
``service``, ``timer``, ``set_check``, ``after_set``; ``action_callbacks`` for an action
server's goal and cancel callbacks). A callback that raises is then one refused input:

- the reason is logged (at most once a second per source, with how many were refused since);
- it is counted by source (the resolved topic or service name), and the counts, the last
  reason and its code are published on ``~/guard`` (diagnostic_msgs/DiagnosticStatus,
  transient local) once a second;
- a service answers with ``success`` false and the reason (where its response has them), a
  parameter set is refused with it, an action goal or cancel request is rejected; rclpy's own
  parameter services, made with the node, are guarded the same way when the guard is made;
- nothing else: the callback checks its input before it changes anything or publishes (a
  message is converted and validated where it enters), so a refused input changes nothing.

The code of a refusal is the error's type (``errors.error_code``): ``invalid_input`` and the
core's other codes for a ``Mover6Error``, ``internal_error`` for any other exception, which is
a bug of the node's input checks (logged with its traceback) but never the end of the node.
"""

import time
import traceback
from typing import Any, Callable, Optional

from diagnostic_msgs.msg import DiagnosticStatus
from mover6_control.errors import error_code
from mover6_control.nodes.messages.conversions import make_status
from mover6_control.nodes.runtime.qos import STATUS_QOS
from mover6_control.validation import short_text
from rcl_interfaces.msg import SetParametersResult
from rclpy.action import CancelResponse, GoalResponse
from rclpy.node import Node

LOG_PERIOD = 1.0          # [s] at most one log line per source this often
GUARD_STATUS_PERIOD = 1.0  # [s] ~/guard is published this often


class CallbackGuard:
    """Run a node's callbacks so that none can end the node (module docstring)."""

    def __init__(self, node: Node, name: Optional[str] = None):
        """Guard the callbacks of ``node``; its ``~/guard`` status is named ``name``."""
        self.node = node
        self.name = name or node.get_name()
        self.refused = {}            # source -> inputs refused
        self.failed = 0              # of those, refused for an internal error (a bug)
        self.last = ('', '', '')     # (source, code, reason) of the latest refusal
        self._logged = {}            # source -> (monotonic time of its last log, refused then)
        self.pub = node.create_publisher(DiagnosticStatus, '~/guard', STATUS_QOS)
        # rclpy's own services (the parameter services made with the node): a SetParameters
        # whose value has an unknown type raised ValueError in them and ended the node.
        for service in node.services:
            service.callback = self.wrap(service.service_name, service.callback, refused_response)
        self.timer(GUARD_STATUS_PERIOD, self.publish)
        self.publish()

    # --- the wrapper ----------------------------------------------------------------------

    def wrap(self, source: str, callback: Callable, on_refusal: Optional[Callable] = None
             ) -> Callable:
        """
        Return ``callback`` guarded: an exception is a refused input of ``source``.

        ``on_refusal(code, reason, *args)``, when given, makes the guarded callback's return
        value after a refusal (a service's response, a parameter set's result).
        """
        def guarded(*args: Any) -> Any:
            try:
                return callback(*args)
            except Exception as err:  # noqa: B902 - the one place a callback may not raise
                code, reason = self.refuse(source, err)
                return None if on_refusal is None else on_refusal(code, reason, *args)
        guarded.__name__ = getattr(callback, '__name__', source)
        return guarded

    def refuse(self, source: str, err: Exception) -> tuple[str, str]:
        """Count and log the refusal of an input of ``source`` for ``err``; return (code, why)."""
        code = error_code(err)
        reason = short_text(f'{type(err).__name__}: {err}' if code == 'internal_error'
                            else str(err))
        self.refused[source] = self.refused.get(source, 0) + 1
        self.failed += code == 'internal_error'
        self.last = (source, code, reason)
        now = time.monotonic()
        since, count = self._logged.get(source, (None, 0))
        if since is None or now - since >= LOG_PERIOD:
            more = self.refused[source] - count - 1
            extra = f' ({more} more refused since the last report)' if more > 0 else ''
            text = f'{source}: refused ({code}): {reason}{extra}'
            if code == 'internal_error':
                self.node.get_logger().error(f'{text}\n{traceback.format_exc()}')
            else:
                self.node.get_logger().warning(text)
            self._logged[source] = (now, self.refused[source])
        return code, reason

    # --- what the nodes create through it ------------------------------------------------

    def subscription(self, msg_type: type, topic: str, callback: Callable, qos: Any,
                     on: Optional[Node] = None, **kwargs: Any) -> Any:
        """Create a subscription of ``on`` (default the node) whose callback is guarded."""
        node = on or self.node
        source = node.resolve_topic_name(topic)
        return node.create_subscription(msg_type, topic, self.wrap(source, callback), qos,
                                        **kwargs)

    def service(self, srv_type: type, name: str, callback: Callable,
                on: Optional[Node] = None, **kwargs: Any) -> Any:
        """Create a service whose callback is guarded: a refusal answers with the reason."""
        node = on or self.node
        source = node.resolve_service_name(name)
        return node.create_service(srv_type, name, self.wrap(source, callback, refused_response),
                                   **kwargs)

    def timer(self, period: float, callback: Callable, on: Optional[Node] = None,
              source: Optional[str] = None, **kwargs: Any) -> Any:
        """Create a timer whose callback is guarded."""
        node = on or self.node
        source = source or f'timer {getattr(callback, "__name__", "")}'.strip()
        return node.create_timer(period, self.wrap(source, callback), **kwargs)

    def set_check(self, callback: Callable) -> Callable:
        """Add an on-set-parameters callback; one that raises refuses the set with the reason."""
        guarded = self.wrap('set parameters', callback, refused_set)
        self.node.add_on_set_parameters_callback(guarded)
        return guarded

    def after_set(self, callback: Callable) -> None:
        """Add a post-set-parameters callback (guarded: it cannot end the node)."""
        self.node.add_post_set_parameters_callback(self.wrap('parameters set', callback))

    def action_callbacks(self, goal: Callable, cancel: Callable) -> dict:
        """Return an action server's ``goal_callback`` and ``cancel_callback``, guarded."""
        return {'goal_callback': self.wrap('action goal', goal,
                                           lambda *_: GoalResponse.REJECT),
                'cancel_callback': self.wrap('action cancel', cancel,
                                             lambda *_: CancelResponse.REJECT)}

    # --- the status ------------------------------------------------------------------------

    def total(self) -> int:
        """Return how many inputs were refused so far."""
        return sum(self.refused.values())

    def values(self) -> dict:
        """Return the status values: the counts (in all, failed, by source) and the last one."""
        source, code, reason = self.last
        values = {'refused': self.total(), 'internal_errors': self.failed,
                  'last_source': source, 'last_code': code, 'last_reason': reason}
        values.update({f'refused {s}': n for s, n in sorted(self.refused.items())})
        return values

    def publish(self) -> None:
        """Publish ``~/guard``: the counts so far."""
        counts = (self.total(), self.failed)
        level = 'OK' if not counts[0] else 'WARN'
        text = (f'{counts[0]} inputs refused ({counts[1]} internal errors)' if counts[0]
                else 'no input refused')
        self.pub.publish(make_status(f'{self.name} guard', level, text, self.values()))


def refused_response(code: str, reason: str, request: Any, response: Any) -> Any:
    """
    Return a service's response after a refusal: ``success`` false, ``message`` why.

    A parameter set (SetParameters, SetParametersAtomically) answers each parameter refused.
    """
    text = f'refused ({code}): {reason}'
    if hasattr(response, 'success'):
        response.success = False
    if hasattr(response, 'message'):
        response.message = text
    if hasattr(response, 'results') and hasattr(request, 'parameters'):
        response.results = [SetParametersResult(successful=False, reason=text)
                            for _ in request.parameters]
    if hasattr(response, 'result') and hasattr(request, 'parameters'):
        response.result = SetParametersResult(successful=False, reason=text)
    return response


def refused_set(code: str, reason: str, parameters: Any) -> SetParametersResult:
    """Return the result of a parameter set refused for ``reason``."""
    return SetParametersResult(successful=False, reason=f'refused ({code}): {reason}')
