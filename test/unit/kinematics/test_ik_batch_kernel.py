"""
The compiled batch solve on the paths the Mover6 and the miniBOT do not take.

Both arms turn every joint about a frame axis and have w3 = w2 exactly, so the FK check's
Rodrigues turn and the turn about w3 in full (``sigma = 0``) of ``ik_batch_kernel`` are only
reached by other descriptions of an arm. Here the Mover6 is described with some joint frames
tilted (the origin turned, the axis and the next origin turned back: the same arm): the batch
must give the solutions that the one-pose solver (``ik_one_pose``, its own FK check by the
product of exponentials) gives.
"""

from dataclasses import replace

from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk_batch
from mover6_control.kinematics.ik_closed_form import (_fk_chain, _plan, _wrap, ik_closed_form,
                                                      ik_closed_form_batch)
from mover6_control.kinematics.wrist import wrist_geometry
import numpy as np
import pytest


def tilted(arm, tilts):
    """Return ``arm`` with joint i's frame turned by ``tilts[i]`` [rad] about x (same arm)."""
    origins, axes, tool = arm.origins.copy(), arm.axes.copy(), arm.tool.copy()
    for i, angle in tilts.items():
        c, s = np.cos(angle), np.sin(angle)
        turn = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, c, -s, 0.0], [0.0, s, c, 0.0],
                         [0.0, 0.0, 0.0, 1.0]])
        origins[i] = origins[i] @ turn
        axes[i] = turn[:3, :3].T @ axes[i]
        if i + 1 < arm.n_joints:
            origins[i + 1] = turn.T @ origins[i + 1]
        else:
            tool = turn.T @ tool
    return replace(arm, origins=origins, axes=axes, tool=tool)


def deduplicated(sols, q_ref):
    """Return ``sols`` without repeats, sorted by distance to ``q_ref`` (as ``ik_closed_form``)."""
    if len(sols) == 0:
        return sols
    gap = np.abs(_wrap(sols[:, None] - sols[None])).max(axis=-1)
    sols = sols[~np.tril(gap <= 1e-9, k=-1).any(axis=1)]
    return sols[np.argsort(np.linalg.norm(sols - q_ref, axis=1), kind='stable')]


@pytest.mark.parametrize('within_limits', [True, False])
def test_tilted_frames_give_the_one_pose_solutions(within_limits):
    arm = tilted(mover6(), {0: 0.3, 2: 0.4, 4: -0.5, 5: 0.2})
    assert (_fk_chain(arm)[3] == -1).sum() == 4            # four joints turn by Rodrigues
    assert _plan(wrist_geometry(arm)).k[4] == 0.0          # w3 is not exactly +-w2: sigma 0
    rng = np.random.default_rng(5)
    Q = rng.uniform(arm.lower, arm.upper, (200, 6))
    T = fk_batch(arm, Q)
    q_ref = np.where(np.arange(200)[:, None] % 2, rng.uniform(arm.lower, arm.upper, (200, 6)),
                     0.0)
    S, ok = ik_closed_form_batch(arm, T, within_limits, q_ref)
    for k in range(len(T)):
        one = ik_closed_form(arm, T[k], within_limits=within_limits, q_ref=q_ref[k])
        batch = deduplicated(S[k][ok[k]], q_ref[k])
        assert one.shape == batch.shape, k
        assert np.allclose(one, batch, rtol=0.0, atol=1e-9), k
        if within_limits:
            assert np.abs(_wrap(batch - Q[k])).max(axis=1).min() < 1e-8, k    # its generator
