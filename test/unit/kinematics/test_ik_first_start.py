"""
The numeric IK's first start on floats: the batch's residual and Jacobian, and its outcome.

``ik_first_start.residual`` must give ``pose_residual_batch``'s error and geometric Jacobian
(the same product of exponentials, on floats), also at rotation errors near a half turn;
``first_start`` must solve reachable poses from a nearby start without the batch, and give up
(None) where the batch would re-seed: a pose out of reach.
"""

from dataclasses import replace

from mover6_control.kinematics.arm import minibot, mover6
from mover6_control.kinematics.forward import fk
from mover6_control.kinematics.ik_first_start import first_start, residual
from mover6_control.kinematics.ik_numeric import DEFAULT_WEIGHTS, pose_residual_batch, screw_chain
from mover6_control.kinematics.rotations import pose_from_xyzabc
import numpy as np
import pytest


def tilted():
    """Return a Mover6 whose joint axes are off the coordinate axes (Rodrigues turns)."""
    arm = mover6()
    axes = arm.axes + np.array([[0.1, -0.2, 0.0], [0.0, 0.0, 0.3], [0.2, 0.0, 0.1],
                                [0.0, 0.1, -0.1], [0.3, 0.0, 0.0], [0.0, -0.2, 0.2]])
    return replace(arm, axes=axes, name='tilted')


ARMS = {'mover6': mover6(), 'minibot': minibot(), 'tilted': tilted()}


@pytest.mark.parametrize('name', sorted(ARMS))
def test_residual_and_jacobian_are_the_batch_ones(name):
    arm = ARMS[name]
    rng = np.random.default_rng(3)
    chain = screw_chain(arm)
    for _ in range(50):
        q, q_goal = rng.uniform(arm.lower, arm.upper, (2, 6))
        T = fk(arm, q_goal)
        e, J = residual(arm, q.tolist(), T[:3, :3].reshape(-1).tolist(), tuple(T[:3, 3]))
        e_ref, J_ref = pose_residual_batch(chain, q[None], T)
        np.testing.assert_allclose(e, e_ref[0], rtol=0.0, atol=1e-12)
        np.testing.assert_allclose(J, J_ref[0], rtol=0.0, atol=1e-12)


def test_residual_near_a_half_turn():
    arm = ARMS['mover6']
    q = np.zeros(6)
    q_goal = np.array([0.0, 0.0, 0.0, 0.0, 0.0, np.pi - 1e-4])      # joint 6 turned ~pi
    arm = arm.with_limits(lower=np.full(6, -4.0), upper=np.full(6, 4.0))
    T = fk(arm, q_goal)
    e, _ = residual(arm, q.tolist(), T[:3, :3].reshape(-1).tolist(), tuple(T[:3, 3]))
    e_ref, _ = pose_residual_batch(screw_chain(arm), q[None], T)
    np.testing.assert_allclose(e, e_ref[0], rtol=0.0, atol=1e-9)


def test_solves_from_a_nearby_start_and_gives_up_out_of_reach():
    arm = ARMS['mover6']
    w = np.asarray(DEFAULT_WEIGHTS)
    limits = (arm.lower, arm.upper)
    q_goal = np.array([0.3, 0.4, -0.5, 0.2, 0.6, -0.3])
    out = first_start(arm, fk(arm, q_goal), q_goal + 0.05, w, (1e-6, 1e-6), limits, None,
                      1e-9, 0.1, None, 300, 12)
    assert out is not None
    q, pos, rot, iterations, _ = out
    np.testing.assert_allclose(q, q_goal, atol=1e-6)
    assert pos < 1e-6 and rot < 1e-6 and iterations >= 1
    far = pose_from_xyzabc(1.5, 0.0, 0.4, 0.0, 0.0, 0.0)
    assert first_start(arm, far, np.zeros(6), w, (1e-6, 1e-6), limits, None, 1e-9, 0.1,
                       None, 300, 12) is None
