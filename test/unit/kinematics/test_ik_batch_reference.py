"""
The batch closed form gives the same branches as a plain per-pose, per-branch reference.

``ik_closed_form_batch`` drops a branch as soon as one of its joints is unsolvable or outside
the limits and solves the rest on flat arrays; the reference below solves every pose and every
one of its 8 branches on floats, one step after the other (the steps of the module docstring:
wrist centre, q1, q3, q2, the wrist by subproblems 2 and 1), aliases each joint nearest
``q_ref`` and checks limits and forward kinematics as the batch documents. Both must give the
same valid masks and the same angles on the valid branches (to rounding: 1e-13 rad divided
by the branch's conditioning, which is 1e-12 rad on all but near-singular branches).
"""

import math

from mover6_control.kinematics.arm import minibot, mover6
from mover6_control.kinematics.forward import fk, fk_batch
from mover6_control.kinematics.ik_closed_form import (_wrap, ik_closed_form_batch,
                                                      solve_candidates)
from mover6_control.kinematics.wrist import VERIFY_TOL, wrist_geometry
import numpy as np
import pytest

ARMS = {'mover6': mover6(), 'mover6_hardware': mover6('hardware'), 'minibot': minibot()}


def _rot(w, q, v):
    """Rotate ``v`` about the unit ``w`` by ``q`` (Rodrigues)."""
    w, v = np.asarray(w), np.asarray(v)
    return (v * math.cos(q) + np.cross(w, v) * math.sin(q)
            + w * np.dot(w, v) * (1.0 - math.cos(q)))


def _normal(v, w):
    """Return ``v`` without its part along the unit ``w``."""
    return v - np.dot(v, w) * w


def _roots(a, b, c):
    """Return both roots of ``a cos t + b sin t = c``, whether solvable, ``hypot(a, b)``."""
    rho = math.hypot(a, b)
    delta = math.acos(min(1.0, max(-1.0, c / (rho if rho > 1e-12 else 1.0))))
    phi = math.atan2(b, a)
    return ((phi + delta, phi - delta), abs(c) <= rho + 1e-12, rho), math.sin(delta)


def _angle(w, u, v):
    """Return the angle about ``w`` that turns ``u`` towards ``v`` (subproblem 1) and |u_perp|."""
    up = _normal(u, w)
    return math.atan2(np.dot(np.cross(w, up), v), np.dot(up, v)), np.linalg.norm(up)


def reference(arm, T, q_ref, within_limits):
    """
    Return the 8 branches (8, 6) of one pose, their mask (8,) and conditioning (8,).

    One branch at a time. The conditioning is the smallest of 1, the sines of the arccos
    angles of q1 and q3 and the wrist's lever (|z| normal to w4): near 0 the branch is near
    a shoulder, elbow or wrist singularity, where rounding grows as its inverse.
    """
    geo = wrist_geometry(arm)
    w, r, p0 = geo.omega, geo.r, geo.wrist_point
    R_goal = T[:3, :3]
    p = R_goal @ geo.wrist_in_tip + T[:3, 3]
    out, mask, cond = np.zeros((8, 6)), np.zeros(8, dtype=bool), np.ones(8)
    v = p - r[0]
    c = np.dot(w[1], p0 - r[0]) - np.dot(v, w[0]) * np.dot(w[0], w[1])
    (q1s, ok1, rho1), s1 = _roots(np.dot(v, w[1]) - np.dot(v, w[0]) * np.dot(w[0], w[1]),
                                  -np.dot(np.cross(w[0], v), w[1]), c)
    if rho1 < 1e-9:                                                  # shoulder singularity
        q1s, ok1 = (q_ref[0], q_ref[0]), ok1 or abs(c) < 1e-9
    e = _normal(r[2] - r[1], w[1])
    u = _normal(p0 - r[2], w[1])
    for branch in range(8):
        shoulder, elbow, flip = branch >> 2, (branch >> 1) & 1, branch & 1
        q1 = q1s[shoulder]
        p1 = r[0] + _rot(w[0], -q1, p - r[0])
        d = _normal(p1 - r[1], w[1])
        (q3s, ok3, _), s3 = _roots(np.dot(e, u), np.dot(e, np.cross(w[2], u)),
                                   (np.dot(d, d) - np.dot(e, e) - np.dot(u, u)) / 2.0)
        q3 = q3s[elbow]
        x = r[2] + _rot(w[2], q3, p0 - r[2])
        q2, _ = _angle(w[1], x - r[1], p1 - r[1])
        # The wrist turns R_w = R03^T R_goal M^T; it needs R_w w6 and R_w x6.
        tv, tx = (_rot(w[2], -q3, _rot(w[1], -q2, _rot(w[0], -q1, R_goal @ geo.M[:3, :3].T @ g)))
                  for g in (w[5], geo.x6))
        s45, s56 = np.dot(w[3], w[4]), np.dot(w[4], w[5])
        alpha = (s45 * s56 - np.dot(w[3], tv)) / (s45 ** 2 - 1.0)
        beta = (s45 * np.dot(w[3], tv) - s56) / (s45 ** 2 - 1.0)
        n45 = np.cross(w[3], w[4])
        gamma2 = (1.0 - alpha ** 2 - beta ** 2 - 2.0 * alpha * beta * s45) / np.dot(n45, n45)
        ok_w = gamma2 > -1e-9
        z = alpha * w[3] + beta * w[4] + (1 - 2 * flip) * math.sqrt(max(gamma2, 0.0)) * n45
        q5, _ = _angle(w[4], w[5], z)
        q4, lever = _angle(w[3], z, tv)
        if lever < 1e-9:                                             # wrist singularity
            q4 = q_ref[3]
        q6, _ = _angle(w[5], geo.x6, _rot(w[4], -q5, _rot(w[3], -q4, tx)))
        q = np.array([q1, q2, q3, q4, q5, q6])
        q = q_ref + _wrap(q - q_ref)
        valid = ok1 and ok3 and ok_w
        if within_limits:
            up, down = q + 2.0 * np.pi, q - 2.0 * np.pi
            q = np.where((q < arm.lower) & (up >= arm.lower) & (up <= arm.upper), up, q)
            q = np.where((q > arm.upper) & (down >= arm.lower) & (down <= arm.upper), down, q)
            valid = valid and arm.within_limits(q, tol=1e-9)
        if valid:
            diff = fk(arm, q)[:3] - T[:3]
            valid = (np.sum(diff[:, 3] ** 2) < VERIFY_TOL ** 2
                     and np.sum(diff[:, :3] ** 2) < 8.0 * math.sin(VERIFY_TOL / 2.0) ** 2)
        out[branch], mask[branch] = q, valid
        cond[branch] = min(1.0, s1, s3, lever)
    return out, mask, cond


@pytest.mark.parametrize('name', sorted(ARMS))
@pytest.mark.parametrize('within_limits', [True, False])
def test_same_masks_and_angles_as_the_plain_reference(name, within_limits):
    arm = ARMS[name]
    rng = np.random.default_rng(3)
    Q = rng.uniform(arm.lower, arm.upper, (300, 6))
    T = fk_batch(arm, Q)
    q_ref = np.where(np.arange(300)[:, None] % 2, rng.uniform(arm.lower, arm.upper, (300, 6)), 0.0)
    S, ok = ik_closed_form_batch(arm, T, within_limits, q_ref, chunk=64)
    for k in range(len(T)):
        ref, mask, cond = reference(arm, T[k], q_ref[k], within_limits)
        assert np.array_equal(ok[k], mask), k
        # Rounding, amplified near a singular branch by 1 / cond: at most 1e-13 rad times
        # that (1e-12 rad on every branch with cond >= 0.1).
        gap = np.abs(S[k][mask] - ref[mask]).max(axis=1, initial=0.0)
        assert np.all(gap * cond[mask] < 1e-13), (k, gap, cond[mask])


def test_singular_poses_and_the_branches_left_out():
    arm = ARMS['mover6']
    q_ref = np.array([0.1, 0.0, 0.0, -0.6, 0.0, 0.2])
    configurations = np.array([[0.3, 0.2, -0.4, 0.7, 0.0, -0.5],     # wrist singularity: q5 = 0
                               [0.0, 0.5, 0.2, 0.1, 0.9, 0.3]])
    T = fk_batch(arm, configurations)
    S, ok, used = solve_candidates(arm, wrist_geometry(arm), T, np.tile(q_ref, (2, 1)),
                                   return_ref_used=True)
    assert used.tolist() == [True, False]
    for k in range(2):
        ref, mask, cond = reference(arm, T[k], q_ref, True)
        assert np.array_equal(ok[k], mask) and mask.any()
        gap = np.abs(S[k][mask] - ref[mask]).max(axis=1)
        assert np.all(gap * cond[mask] < 1e-13)
        # The branches dropped before the FK check (here all that are not valid) hold q_ref.
        assert np.array_equal(S[k][~ok[k]], np.tile(q_ref, ((~ok[k]).sum(), 1)))
