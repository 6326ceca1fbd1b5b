"""
A path's collision check is the check of each of its samples (issue 32, round 3).

The checker reads MuJoCo's contacts of every sample in one loop (one read of the contact list
per sample with contacts, the sample index of each contact made from the counts at the end).
Whatever it does inside, a path's verdict must be the one its samples give one by one: the
first colliding sample, its shapes and depth, and each kind's smallest clearance.
"""

from mover6_control.collision.checker import CollisionChecker, CollisionSettings, densify
from mover6_control.kinematics.arm import mover6
import numpy as np
import pytest

ARM = mover6()
KEEP_OUT = (0.15, -0.2, 0.0, 0.45, 0.2, 0.25)


def sample_by_sample(checker, Q):
    """Return (index of the first colliding sample or None, its check, clearances) one by one."""
    checks = [checker.check_configurations(q[None]) for q in Q]
    first = next((k for k, check in enumerate(checks) if not check.free), None)
    clearance = {kind: min(check.clearance[kind] for check in checks)
                 for kind in checks[0].clearance}
    return first, (checks[first] if first is not None else None), clearance


def random_paths(seed, count):
    """Return ``count`` dense joint paths through random in-limit waypoints (seeded)."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        waypoints = rng.uniform(ARM.lower, ARM.upper, (4, ARM.n_joints))
        yield densify(waypoints, 0.02)[0]


@pytest.mark.parametrize('keep_out', [(0.0,) * 6, KEEP_OUT], ids=['no box', 'keep-out box'])
def test_a_path_check_is_the_check_of_its_samples(keep_out):
    checker = CollisionChecker(ARM, CollisionSettings(keep_out=keep_out))
    colliding = free = 0
    for Q in random_paths(32, 12):
        check = checker.check_configurations(Q)
        first, alone, clearance = sample_by_sample(checker, Q)
        assert check.clearance == clearance
        assert check.n_samples == len(Q)
        if first is None:
            free += 1
            assert check.free
            continue
        colliding += 1
        assert check.first.sample == first
        assert check.first.shapes == alone.first.shapes
        assert check.first.kind == alone.first.kind
        assert check.first.depth == alone.first.depth
        np.testing.assert_array_equal(check.first.q, Q[first])
    # Both verdicts were exercised.
    assert colliding > 0 and free > 0


def test_no_samples_and_samples_without_contacts():
    checker = CollisionChecker(ARM)
    empty = checker.check_configurations(np.zeros((0, ARM.n_joints)))
    assert empty.free and empty.n_samples == 0
    # Folded towards the table and stretched up: the clearances of the two together are the
    # smaller of each, whichever sample reported contacts.
    Q = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 0.0], [0.0, 1.2, 0.8, 0.0, 1.0, 0.0]])
    both = checker.check_configurations(Q)
    one = [checker.check_configurations(q[None]) for q in Q]
    assert both.clearance == {kind: min(c.clearance[kind] for c in one)
                              for kind in both.clearance}
