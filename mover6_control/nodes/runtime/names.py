"""
Namespaces of a stack (two arms in one graph): checked by ROS's naming rules, one home.

``check_namespace`` takes what a user typed for ``namespace`` (launch.sh ``--namespace``, the
launch file's ``namespace:=``, ``./run.sh goal --namespace``), makes it absolute and refuses it
with the rule it breaks (rclpy's ``validate_namespace``: only letters, digits, ``_`` and ``/``
separators, no token starting with a digit, no ``//``, no trailing ``/``, at most 255
characters...). ``frame_prefix`` is the TF frame prefix of a namespace (``/arm1`` ->
``arm1/``), as robot_state_publisher's ``frame_prefix`` takes it.

``python -m mover6_control.nodes.runtime.names NS`` prints the checked namespace, or the reason and
exit code 2 (what launch.sh calls).
"""

import argparse
import sys
from typing import Optional

from mover6_control.errors import InvalidInputError
from rclpy.exceptions import InvalidNamespaceException
from rclpy.validate_namespace import validate_namespace


def check_namespace(namespace: str) -> str:
    """Return ``namespace`` made absolute ('' and '/' are the root), or raise saying why not."""
    text = (namespace or '').strip()
    if text in ('', '/'):
        return '/'
    if not text.startswith('/'):
        text = '/' + text
    try:
        validate_namespace(text)
    except InvalidNamespaceException as err:
        rule = str(err).split('\n')[0].removeprefix('Invalid namespace: ').rstrip(':')
        raise InvalidInputError(f'namespace {namespace!r} is not a ROS namespace: {rule}') \
            from None
    return text


def frame_prefix(namespace: str) -> str:
    """Return the TF frame prefix of a checked ``namespace`` ('' for the root)."""
    return '' if namespace == '/' else namespace.strip('/') + '/'


def namespace_from(argv: list[str]) -> tuple[Optional[str], list[str]]:
    """
    Return (the checked ``--namespace``, ``argv`` without it); (None, argv) when it is malformed.

    A malformed one is refused with the ROS naming rule it breaks (printed), before anything
    starts.
    """
    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument('--namespace', default='')
    known, rest = pre.parse_known_args(argv)
    try:
        return check_namespace(known.namespace), rest
    except InvalidInputError as err:
        print(f'goal: {err}', file=sys.stderr)
        return None, rest


def main(argv: Optional[list[str]] = None) -> int:
    """Print the checked namespace and its frame prefix, or the reason (exit code 2)."""
    args = sys.argv[1:] if argv is None else argv
    try:
        namespace = check_namespace(args[0] if args else '')
    except InvalidInputError as err:
        print(err, file=sys.stderr)
        return 2
    print(namespace, frame_prefix(namespace))
    return 0


if __name__ == '__main__':
    sys.exit(main())
