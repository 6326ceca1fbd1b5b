"""
Which of the launched nodes are essential and which are helpers: the one table.

An essential node is the arm or what commands it: the simulated arm (``sim_bridge``), the
CAN-level Mover6 and the driver on it (``can_sim``, ``driver``) and the ``controller``. Without
one of them the arm cannot be driven safely, so its exit stops the stack (the controller's last
zero command, the driver's disable, the bridge's halt after its command timeout): the launchers
report it and stop every node. A helper only shows, plans or records: the
``planner``, the ``state_publisher`` (or robot_state_publisher), the ``markers``, the
``recorder``, the ``console`` and RViz. A helper that exits is reported and
started again after ``restart_delay`` (doubling from ``RESTART_DELAY`` to ``MAX_RESTART_DELAY``,
back to the first delay once it ran ``STEADY_RUN``); the arm and the controller go on.

``scripts/launch.sh`` reads this table (``python -m mover6_control.node_roles shell``) and
``launch/mover6.launch.py`` imports it: a helper gets launch_ros's ``respawn`` with
``RESTART_DELAY``, an essential node ends the launch when it exits.
"""

from __future__ import annotations

import sys

ESSENTIAL = ('sim_bridge', 'can_sim', 'driver', 'controller')
HELPERS = ('planner', 'state_publisher', 'robot_state_publisher', 'markers', 'recorder',
           'console', 'rviz2')
# Whole seconds (launch.sh counts them in shell arithmetic).
RESTART_DELAY = 1           # [s] before a helper that exited is started again, the first time
MAX_RESTART_DELAY = 30      # [s] the longest delay: a helper that keeps failing, once per this
STEADY_RUN = 60             # [s] a helper that ran this long starts from the first delay again


def is_essential(name: str) -> bool:
    """Return True for an essential node; raise ``KeyError`` for a node of neither kind."""
    if name in ESSENTIAL:
        return True
    if name in HELPERS:
        return False
    raise KeyError(f'{name} is in neither ESSENTIAL nor HELPERS (mover6_control.node_roles)')


def restart_delay(restarts: int) -> int:
    """Return the delay [s] before restart number ``restarts`` (0: the first) of a helper."""
    delay = RESTART_DELAY
    for _ in range(restarts):
        delay = min(2 * delay, MAX_RESTART_DELAY)
    return delay


def shell() -> str:
    """Return the table as shell assignments (what launch.sh evaluates)."""
    return (f"ESSENTIAL='{' '.join(ESSENTIAL)}'\nHELPERS='{' '.join(HELPERS)}'\n"
            f'RESTART_DELAY={RESTART_DELAY}\nMAX_RESTART_DELAY={MAX_RESTART_DELAY}\n'
            f'STEADY_RUN={STEADY_RUN}\n')


if __name__ == '__main__':
    if sys.argv[1:] != ['shell']:
        sys.exit('usage: python -m mover6_control.node_roles shell')
    sys.stdout.write(shell())
