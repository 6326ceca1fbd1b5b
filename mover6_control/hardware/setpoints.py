"""
The arm driver's set-point integrator: joint velocities into position set-points, in ticks.

Each cycle ``integrate`` moves one joint's set-point by its commanded velocity over the cycle,
in fractional ticks (a slow wrist command still moves J5 and J6; the wire gets the nearest
tick), clamped to the joint's tick limits and to the measured position plus or minus
``max_lag``. A clamp only ever shortens the cycle's step: it never moves a set-point further
than the commanded motion of one cycle, nor against it, so a joint found outside its limits (or
further than ``max_lag`` from its set-point) moves only inward, at the commanded speed, instead
of jumping to the bound. The set-point starts at the measured position and keeps tracking it
whenever the joint is not enabled or is told to (after start, a reset, a fault, referencing,
set zero): never a jump. A joint latched silent keeps the last set-point it was sent until a
reset (its last measured position is stale: a module that still hears would step back to it).
At rest (a zero command) the set-point is the whole tick on the wire, so
a later move of whole ticks lands on whole ticks. ``plausible`` tells a reply whose position
the joint cannot have reached from one it may have.
"""

from __future__ import annotations

from mover6_control.hardware.driver_state import FOLLOWING, JointRecord


def integrate(j: JointRecord, v: float, dt: float, frozen: bool, limit_set: str,
              max_lag: float) -> None:
    """
    Move the set-point of ``j`` by ``v`` [rad/s] over ``dt`` [s]; set ``j.velocity`` [rad/s].

    ``frozen``: the arm holds (the set-point stays, velocity zero). ``limit_set`` names the
    joint limits, ``max_lag`` [rad] how far the set-point may run from the measured position.
    """
    if j.ticks is None:
        return
    if j.fault and j.setpoint is not None:
        # Latched silent: the last measured position is stale, and the module (which may still
        # hear) is at or on its way to the last set-point sent: that one stays until a reset.
        j.velocity = 0.0
        return
    if j.track or j.setpoint is None or j.state() not in FOLLOWING:
        j.setpoint = float(j.ticks)      # never a jump: start from where the joint is
        j.track = j.state() not in FOLLOWING
        j.velocity = 0.0
        return
    if frozen:
        j.velocity = 0.0
        return
    if v == 0.0:
        # At rest the set-point is the whole tick on the wire (nothing sent changes), so
        # a later move of whole ticks lands on whole ticks, not a rounding away from them.
        j.setpoint = float(round(j.setpoint))
        j.velocity = 0.0
        return
    lo, hi = j.scale.tick_limits(limit_set)
    lag = max_lag * abs(j.scale.ticks_per_rad)
    # The bounds, each widened to take in the set-point where it is: a clamp shortens the
    # step, it never makes one (low <= setpoint <= high).
    low = min(max(lo, j.ticks - lag), j.setpoint)
    high = max(min(hi, j.ticks + lag), j.setpoint)
    target = min(max(j.setpoint + v * dt * j.scale.ticks_per_rad, low), high)
    j.velocity = j.scale.to_rad(target - j.setpoint) / dt if dt > 0 else 0.0
    j.setpoint = target


def plausible(j: JointRecord, ticks: int, now: float, max_lag: float, cycle: float) -> bool:
    """
    Return False for a reply at ``now`` [s] whose position ``ticks`` the joint cannot reach.

    A driven joint (or one latched silent, its set-point frozen until a reset) follows its
    set-point, which never runs more than ``max_lag`` [rad] ahead of the position: it is within
    ``max_lag`` plus twice its maximum speed over one ``cycle`` [s] of the set-point, and two
    ticks of rounding. The bound does not grow while the module is silent (the arm then holds:
    a long silence makes no jump plausible). Before a set-point, from the last reply: the same
    over the time since it.
    """
    if j.ticks is None or j.reply_time is None or j.relearn:
        return True            # nothing to compare with (a reset or set zero since)
    if not j.fault and (j.track or j.state() not in FOLLOWING):
        return True            # not driven: the set-point follows the measured position
    if j.setpoint is not None:
        reach = max_lag + 2.0 * j.scale.max_speed * cycle
        return abs(ticks - j.setpoint) <= reach * abs(j.scale.ticks_per_rad) + 2
    reach = max_lag + 2.0 * j.scale.max_speed * max(now - j.reply_time, cycle)
    return abs(ticks - j.ticks) <= reach * abs(j.scale.ticks_per_rad) + 2
