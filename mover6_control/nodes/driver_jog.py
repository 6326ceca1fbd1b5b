"""
The driver node's /JointJog input: each JointJog commanded as joint velocities, or refused.

A refused JointJog changes nothing: the previous command ages out after ``command_timeout`` and
the arm holds. Refused are: displacements, no names, unequal lengths, a name
twice, an unknown name, a non-finite value, a fraction beyond [-1, 1] (fraction_of_max) or a
speed beyond ``JOG_REFUSE_FACTOR`` times the joint's maximum (rad_per_s; a speed between one
and that many times its maximum is clipped to it and counted). /diagnostics counts the JointJogs
received, refused (by reason), clipped and superseded (replaced before a cycle used them: a
flood), with the last refusal's reason.

``JogInput`` is a part of ``driver_node.DriverNode`` (its state is the node's, set in
``DriverNode.__init__``); it is not used on its own.
"""

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


class JogInput:
    """The /JointJog input of ``DriverNode`` (module docstring)."""

    def on_jog(self, msg: JointJog) -> None:
        """Command the velocities of a JointJog, or refuse it with the reason on /diagnostics."""
        self.jogs += 1
        try:
            qd, clipped = self.jog_velocities(msg)
        except JogRefused as err:
            self.refused += 1
            self.refused_by[err.reason] = self.refused_by.get(err.reason, 0) + 1
            self.last_refusal = str(err)[:200]
            self._notify()
            raise                       # refused: the node's guard logs and counts it
        self.clipped += clipped
        if self._jog_pending:
            self.superseded += 1
        self._jog_pending = True
        self.driver.set_velocity(qd)

    def jog_velocities(self, msg: JointJog) -> tuple[list[float], int]:
        """Return (joint velocities [rad/s] in driver order, joints clipped); raise JogRefused."""
        try:
            jog = joint_jog_from_msg(msg)           # checked once, refused with its code
            indices = jog.indices(self.names)
        except InvalidInputError as err:
            raise JogRefused(error_code(err), str(err)) from None
        qd = [0.0] * len(self.names)
        clipped = 0
        override = self.get_parameter('speed_override').value
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
