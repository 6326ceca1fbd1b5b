"""
Whether collision settings put the arm into collision where it stands: the parameter check.

A keep-out box, a table margin or a tool that the arm is already inside would leave it unable
to move (every motion starts in collision) or, worse, let a user believe a zone is guarded that
the arm stands in. The planner and the controller refuse such a set of their collision
parameters (``keep_out_boxes``, ``table_margin``, ``tool_shape``, ``tool_size``,
``collision_check``) with ``StandingCheck.check``, through their set-parameters check
(``nodes.runtime.params.declare``), at start and on every set: the link or shape, what it is
in, and how deep [mm].

Where the arm stands: the latest valid joint positions the node has, or, before any came, the
configurations it knows (the simulator's start and home configuration, ``initial_q``'s default).
A set that leaves the arm no deeper in collision than the settings in force is taken, so a box
the arm stands in can be shrunk or removed, and one that does not concern the collision
parameters never fails here. ROS-free.
"""

from __future__ import annotations

import threading

from mover6_control.collision.checker import CollisionChecker, CollisionSettings, ESCAPE_TOLERANCE
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import ArmModel
import numpy as np

# The parameter a contact of each kind comes from (a contact with the tool: the tool's).
PARAMETER_OF_KIND = {'keep_out': 'keep_out_boxes', 'table': 'table_margin',
                     'self': 'collision_check'}


class StandingCheck:
    """
    Refuse collision settings that put ``arm`` into collision where it stands.

    ``known`` are the configurations (k, n) [rad] checked while no joint positions are known.
    Keeps the checkers of the last two settings it was asked about (the ones in force and the
    ones of a set), so a set that does not change them costs one MuJoCo collision pass each.
    Safe to call from several threads.
    """

    def __init__(self, arm: ArmModel, known: np.ndarray):
        """Check ``arm``'s shapes; ``known`` (k, n) [rad] where it stands before any states."""
        self.arm = arm
        self.known = np.asarray(known, dtype=float).reshape(-1, arm.n_joints)
        self._lock = threading.Lock()
        self._checkers = {}

    def _checker(self, settings: CollisionSettings) -> CollisionChecker:
        checker = self._checkers.get(settings)
        if checker is None:
            checker = CollisionChecker(self.arm, settings)
            self._checkers = {**dict(list(self._checkers.items())[-1:]), settings: checker}
        return checker

    def deepest(self, settings: CollisionSettings, q: np.ndarray):
        """Return the deepest ``checker.Contact`` of ``settings`` at ``q`` (n,), or None."""
        if not settings.enabled:
            return None
        with self._lock:
            check = self._checker(settings).check_configurations(np.asarray(q)[None])
        return check.first

    def check(self, settings: CollisionSettings, q_now: np.ndarray | None = None,
              in_force: CollisionSettings | None = None) -> None:
        """
        Raise ``InvalidInputError`` (code ``in_collision``) when ``settings`` collide the arm.

        ``q_now`` (n,) [rad] is where the arm stands (None: not known, the ``known``
        configurations are checked); ``in_force`` the settings in force (None: none yet, at
        start). Taken when ``settings`` equal ``in_force``, or leave every configuration free,
        or no deeper in collision than ``in_force`` does.
        """
        if settings == in_force or not settings.enabled:
            return
        if q_now is not None and not np.all(np.isfinite(q_now)):
            q_now = None
        where = ('where the arm stands' if q_now is not None
                 else 'at the start configuration (no joint states yet)')
        configurations = self.known if q_now is None else np.asarray(q_now, float)[None]
        for q in configurations:
            contact = self.deepest(settings, q)
            if contact is None:
                continue
            before = None if in_force is None else self.deepest(in_force, q)
            if before is not None and contact.depth <= before.depth + ESCAPE_TOLERANCE:
                continue
            raise InvalidInputError(refusal(contact, settings.table_margin, where),
                                    code='in_collision')


def refusal(contact, table_margin: float, where: str) -> str:
    """Return why a ``checker.Contact`` refuses the settings: the parameter, shapes, depth."""
    a, b = contact.shapes
    tool = 'tool' in (a + ' ' + b).split()
    name = 'tool_shape/tool_size' if tool else PARAMETER_OF_KIND[contact.kind]
    mm = contact.depth * 1e3
    if contact.kind == 'table':
        into = f'into the table margin ({table_margin * 1e3:.1f} mm)'
    elif contact.kind == 'keep_out':
        into = f'inside {b}'
    else:
        into = f'into {b}'
    return (f'{name} puts the arm in collision {where}: {a} is {mm:.1f} mm {into} '
            f'(joints {np.round(contact.q, 3).tolist()} rad)')
