"""
Record the stack's topics into a rosbag2 MCAP recording: ``./run.sh record [-o BAG] [TOPICS]``.

Checks the path first (a path that cannot be written: the reason, exit code 2, nothing started),
then runs the recorder node (``nodes/recorder/node.py``) in the foreground until Ctrl-C. Without
TOPICS it records the stack's topics (``parameters.RECORDED_TOPICS``); ``--namespace`` records
those of a namespaced stack.
"""

import argparse
import os
import sys
from typing import Optional, Sequence

from mover6_control.errors import InvalidInputError
from mover6_control.nodes.recorder.bag_writer import check_bag_path
from mover6_control.nodes.recorder.node import default_path
from mover6_control.nodes.runtime.names import check_namespace
from mover6_control.parameters import RECORDED_TOPICS


def recorder_command(path: str, topics: Sequence[str] = (), namespace: str = '') -> list[str]:
    """Return the command line of the recorder node writing ``path``."""
    from ament_index_python.packages import get_package_prefix
    exe = os.path.join(get_package_prefix('mover6_control'), 'lib', 'mover6_control',
                       'recorder')
    cmd = [exe, '--ros-args', '-p', f'path:={path}']
    if topics:
        cmd += ['-p', 'topics:=' + ' '.join(topics)]
    if namespace:
        cmd += ['-r', f'__ns:={namespace}']
    return cmd


def main(argv: Optional[list[str]] = None) -> int:
    """Check the path, then become the recorder."""
    parser = argparse.ArgumentParser(prog='record', description=__doc__.split('\n\n')[0])
    parser.add_argument('topics', nargs='*',
                        help='topics to record (default: ' + ' '.join(RECORDED_TOPICS) + ')')
    parser.add_argument('-o', '--output', default=None,
                        help='recording folder, which must not exist (default: '
                             'rosbag2_<date>-<time> here, as ros2 bag record)')
    parser.add_argument('--namespace', default='', help="the stack's namespace (e.g. /arm1)")
    args = parser.parse_args(argv)
    try:
        path = check_bag_path(args.output or default_path())
        namespace = check_namespace(args.namespace)
    except InvalidInputError as err:
        print(f'record: {err}; nothing started', file=sys.stderr)
        return 2
    cmd = recorder_command(path, args.topics, '' if namespace == '/' else namespace)
    os.execv(cmd[0], cmd)


if __name__ == '__main__':
    sys.exit(main())
