"""
The one-pose closed form on floats answers as the batch solver does, pose for pose.

``ik_closed_form`` (one pose) runs ``ik_one_pose``; ``ik_closed_form_batch`` runs the array
steps. For the same pose, reference and limits setting both must give the same solutions
(after the single-pose call's de-duplication and sorting), at random poses, at random
references, without limits, at the shoulder and wrist singularities, and for poses out of
reach.
"""

from mover6_control.kinematics.arm import minibot, mover6
from mover6_control.kinematics.forward import fk, fk_batch
from mover6_control.kinematics.ik_closed_form import (_wrap, ik_closed_form,
                                                      ik_closed_form_batch)
from mover6_control.kinematics.ik_one_pose import ik_one_pose
from mover6_control.kinematics.rotations import pose_from_xyzabc
import numpy as np
import pytest

ARMS = {'mover6': mover6(), 'mover6_hardware': mover6('hardware'), 'minibot': minibot()}


def batch_answer(arm, T, within_limits, q_ref):
    """Return the batch solver's solutions for ``T``, de-duplicated and sorted as one pose's."""
    Q, ok = ik_closed_form_batch(arm, T[None], within_limits, q_ref)
    sols = Q[0][ok[0]]
    if len(sols) == 0:
        return sols
    gap = np.abs(_wrap(sols[:, None] - sols[None])).max(axis=-1)
    sols = sols[~np.tril(gap <= 1e-9, k=-1).any(axis=1)]
    return sols[np.argsort(np.linalg.norm(sols - q_ref, axis=1), kind='stable')]


@pytest.mark.parametrize('name', sorted(ARMS))
@pytest.mark.parametrize('within_limits', [True, False])
def test_same_solutions_as_the_batch_at_random_poses(name, within_limits):
    arm = ARMS[name]
    rng = np.random.default_rng(7)
    Q = rng.uniform(arm.lower, arm.upper, (150, 6))
    for i, T in enumerate(fk_batch(arm, Q)):
        q_ref = rng.uniform(arm.lower, arm.upper) if i % 2 else np.zeros(6)
        one = ik_closed_form(arm, T, within_limits=within_limits, q_ref=q_ref)
        ref = batch_answer(arm, T, within_limits, q_ref)
        assert one.shape == ref.shape, i
        assert np.allclose(one, ref, rtol=0.0, atol=1e-9), i
        if within_limits:
            assert any(np.allclose(q, Q[i], atol=1e-8) for q in one), i     # its generator


@pytest.mark.parametrize('q', [
    [0.3, 0.2, -0.4, 0.7, 0.0, -0.5],       # wrist singularity: q5 = 0
    [0.0, 0.5, 0.2, 0.1, 0.9, 0.3],
])
def test_same_solutions_at_singular_and_ordinary_configurations(q):
    arm = ARMS['mover6']
    T = fk(arm, np.array(q))
    q_ref = np.array([0.1, 0.0, 0.0, -0.6, 0.0, 0.2])
    one = ik_closed_form(arm, T, q_ref=q_ref)
    assert np.allclose(one, batch_answer(arm, T, True, q_ref), rtol=0.0, atol=1e-9)
    assert len(one) >= 1


def test_out_of_reach_has_no_solution_on_both_paths():
    arm = ARMS['mover6']
    T = pose_from_xyzabc(2.0, 0.0, 0.4, 0.0, 0.0, 0.0)
    assert ik_closed_form(arm, T).shape == (0, 6)
    assert ik_one_pose(arm, T.tolist(), [0.0] * 6) == []
    assert batch_answer(arm, T, True, np.zeros(6)).shape == (0, 6)


def test_wrap_is_the_plain_remainder_number_for_number():
    # _wrap takes the remainder only outside [-pi, pi): the same numbers as the plain formula.
    rng = np.random.default_rng(11)
    q = np.concatenate([rng.uniform(-20.0, 20.0, 5000), rng.uniform(-np.pi, np.pi, 5000),
                        [-np.pi, np.pi, np.nextafter(np.pi, 0.0), np.nextafter(-np.pi, -4.0),
                         0.0, -0.0, 3 * np.pi, -3 * np.pi]])
    plain = (q + np.pi) % (2.0 * np.pi) - np.pi
    assert np.array_equal(_wrap(q), plain)
    assert np.array_equal(_wrap(q.reshape(2, -1)), plain.reshape(2, -1))
    assert _wrap(np.float64(7.0)) == (7.0 + np.pi) % (2.0 * np.pi) - np.pi
