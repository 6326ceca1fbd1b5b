"""
Everything ``scripts/launch.sh`` evaluates before it starts a node, from one Python process.

``python3 -m mover6_control.tools.launch_shell -- ARGS`` prints shell assignments: ``prefix`` (the
package's install prefix), the stack's values and its ``start_stack`` function for ARGS
(``mover6_control.stack``), the loopback-only DDS exports unless the user chose their own
(``nodes.runtime.local_dds``), the table of essential and helper nodes (``node_roles``), and
``namespace`` checked by ROS's naming rules (``nodes.runtime.names``). One interpreter instead of
one per part: each start of Python with the package costs 0.1-0.5 s of the launch's way to a
stack that takes goals. Exit codes: 2 for a bad option or namespace (the reason printed), 1 when
the package is not built or the DDS profile cannot be written.
"""

import os
import shlex
import sys
from typing import Optional

MISSING = 'launch.sh: package mover6_control not found: build and source it (./run.sh launch)'


def main(argv: Optional[list[str]] = None) -> int:
    """Print the assignments for launch.sh's arguments ``argv`` (after ``--``); return 0."""
    from ament_index_python.packages import get_package_prefix, PackageNotFoundError
    from mover6_control import node_roles, stack
    from mover6_control.errors import InvalidInputError
    from mover6_control.nodes.runtime import local_dds, names

    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ['--']:
        argv = argv[1:]
    try:
        prefix = get_package_prefix('mover6_control')
    except PackageNotFoundError:
        print(MISSING, file=sys.stderr)
        return 1
    values = stack.shell(argv)                      # a bad option: exit 2 with the choices
    try:
        exports = local_dds.default_environment(os.environ)
    except local_dds.LocalDdsError as err:
        print(err, file=sys.stderr)
        return 1
    try:
        namespace = names.check_namespace(stack.parse_shell(argv)['namespace'])
    except InvalidInputError as err:
        print(err, file=sys.stderr)
        return 2
    sys.stdout.write(f'prefix={shlex.quote(prefix)}\n' + values
                     + ''.join(f'export {k}={shlex.quote(v)}\n' for k, v in exports.items())
                     + node_roles.shell() + f'namespace={shlex.quote(namespace)}\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
