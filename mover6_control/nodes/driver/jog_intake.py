"""
The driver's /JointJog intake: each JointJog commanded as joint velocities, or refused.

A valid JointJog while the driver is not active is not commanded: counted (``ignored``, with
the reason), not refused (a controller that streams before activation is no bad input). A refused
JointJog changes nothing: the previous command ages out after ``command_timeout`` and the arm
holds. Refused are: displacements, no names, unequal lengths, a name twice, an unknown name, a
non-finite value, a fraction beyond [-1, 1] (fraction_of_max) or a speed beyond
``JOG_REFUSE_FACTOR`` times the joint's maximum (rad_per_s; a speed between one and that many
times its maximum is clipped to it and counted). ``JogCounts`` keeps what /diagnostics tells:
the JointJogs received, refused (by reason), clipped and superseded (replaced before a cycle used
them: a flood), with the last refusal's reason.
"""

from typing import Callable, Sequence

from control_msgs.msg import JointJog
from mover6_control.errors import error_code, InvalidInputError
from mover6_control.nodes.messages.conversions import joint_jog_from_msg

JOG_REFUSE_FACTOR = 2.0
"""rad_per_s: a JointJog faster than this many times a joint's maximum speed is refused."""


class JogRefused(InvalidInputError):
    """A JointJog the driver does not take; ``reason`` (its code) is its name on /diagnostics."""

    def __init__(self, reason: str, message: str) -> None:
        super().__init__(message, reason)
        self.reason = reason


class JogCounts:
    """What the intake counts, read by the report publisher (module docstring)."""

    def __init__(self) -> None:
        self.received = 0
        self.refused = 0
        self.refused_by = {}          # reason -> JointJogs refused for it
        self.last_refusal = ''
        self.clipped = 0
        self.superseded = 0
        self.ignored = 0              # taken while the driver is not active: not commanded
        self.last_ignored = ''
        self.pending = False          # a JointJog waits for the next cycle

    def taken_by_cycle(self) -> None:
        """Note that a cycle took the pending command (control thread)."""
        self.pending = False


class JogIntake:
    """
    Check each JointJog and hand its velocities to ``command``, or refuse it.

    ``names`` and ``max_speed`` [rad/s] are the joints', in driver order; ``jog_units`` is
    rad_per_s or fraction_of_max; ``speed_override()`` gives the live override of
    fraction_of_max; ``blocked()`` says why no JointJog is commanded now ('' when they are);
    ``command(qd)`` commands the velocities [rad/s]; ``on_refusal()`` asks for /diagnostics now.
    """

    def __init__(self, names: Sequence[str], max_speed: Sequence[float], jog_units: str,
                 speed_override: Callable[[], float], blocked: Callable[[], str],
                 command: Callable[[list], None], on_refusal: Callable[[], None]) -> None:
        self.names = tuple(names)
        self.max_speed = tuple(max_speed)
        self.jog_units = jog_units
        self.speed_override = speed_override
        self.blocked = blocked
        self.command = command
        self.on_refusal = on_refusal
        self.counts = JogCounts()

    def on_jog(self, msg: JointJog) -> None:
        """Command the velocities of a JointJog, or refuse it with the reason on /diagnostics."""
        counts = self.counts
        counts.received += 1
        try:
            qd, clipped = self.jog_velocities(msg)
        except JogRefused as err:
            counts.refused += 1
            counts.refused_by[err.reason] = counts.refused_by.get(err.reason, 0) + 1
            counts.last_refusal = str(err)[:200]
            self.on_refusal()
            raise                       # refused: the node's guard logs and counts it
        why = self.blocked()
        if why:
            counts.ignored += 1
            counts.last_ignored = why
            return
        counts.clipped += clipped
        if counts.pending:
            counts.superseded += 1
        counts.pending = True
        self.command(qd)

    def jog_velocities(self, msg: JointJog) -> tuple[list[float], int]:
        """Return (joint velocities [rad/s] in driver order, joints clipped); raise JogRefused."""
        try:
            jog = joint_jog_from_msg(msg)           # checked once, refused with its code
            indices = jog.indices(self.names)
        except InvalidInputError as err:
            raise JogRefused(error_code(err), str(err)) from None
        qd = [0.0] * len(self.names)
        clipped = 0
        override = self.speed_override()
        for name, i, value in zip(jog.names, indices, jog.velocities):
            top = self.max_speed[i]
            if self.jog_units == 'fraction_of_max':
                if abs(value) > 1.0 + 1e-9:
                    raise JogRefused('out_of_range', f'JointJog {name} at {value:.6g} is no '
                                     'fraction of its maximum speed (fraction_of_max: -1..1)')
                qd[i] = float(value) * top * override
            else:
                if abs(value) > JOG_REFUSE_FACTOR * top:
                    raise JogRefused('out_of_range', f'JointJog {name} at {value:.6g} rad/s is '
                                     f'beyond {JOG_REFUSE_FACTOR:g} x its maximum speed '
                                     f'{top:.4f} rad/s')
                clipped += abs(value) > top
                qd[i] = float(value)
        return qd, clipped
