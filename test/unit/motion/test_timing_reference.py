"""
The continuous timing gives the same durations as before it was made faster (issue 12, item 7).

The reference values were computed by ``time_parameterize`` as it was before the backward and
forward passes ran on precomputed per-grid-point lists and ``BlendedPath.evaluate`` ran in one
batch (commit e00e776), on the seeded paths of ``case`` below: the new code must reproduce
them to 1e-9 relative (it is the same grid, the same constraints and the same arithmetic, so in
practice they are bit for bit the same).
"""

from mover6_control.motion import time_optimal
import numpy as np
import pytest

V = np.array([0.524, 0.524, 0.524, 0.524, 0.698, 1.745])

# (seed, duration [s], time at the middle waypoint [s]) from the code before the change.
REFERENCE = [
    (0, 1.238841661102498, 1.238841661102498),
    (1, 0.9773880628788637, 0.46875407570972605),
    (2, 3.7810781318339783, 2.2932061503682695),
    (3, 6.3032320214981175, 3.4155134940862952),
    (4, 69.5911849721375, 35.65093495323643),
    (5, 145.59478064907276, 72.97934057816084),
    (6, 139.08168668695666, 71.79817779362143),
    (7, 353.3889909011309, 172.77414968648898),
    (8, 0.7921595657403155, 0.7921595657403155),
    (9, 6.059331675287344, 2.539242606099523),
    (10, 6.619346429262488, 4.050807372996774),
    (11, 18.85889233130579, 9.728139246774084),
    (12, 39.439978013949656, 19.3280365220285),
    (13, 119.71669530286756, 60.9915731817801),
    (14, 189.68029696923122, 91.86582595479707),
    (15, 378.8636447958668, 192.41392794578272),
    (16, 897.167889600128, 454.10507510129185),
    (17, 426.32626799234583, 224.94593234982588),
]


def case(seed):
    """Return ``Q, v_max, a_max, kwargs`` of reference case ``seed``: a seeded random walk."""
    rng = np.random.default_rng(seed)
    kind = seed % 8
    m = (2, 3, 8, 20, 60, 100, 150, 300)[kind] if seed < 16 else (1000, 60)[seed - 16]
    Q = np.cumsum(rng.normal(scale=rng.uniform(0.02, 0.3), size=(m, 6)), axis=0)
    v = V * rng.uniform(0.5, 2.0)
    a = rng.uniform(0.3, 3.0, size=6)
    kwargs = {}
    if kind == 2:
        Q[3] = Q[1]                                  # a full reversal: the arm stops there
    if kind == 3:
        kwargs['max_deviation'] = 0.05
    if kind == 4:
        kwargs['qd_start'] = rng.normal(scale=0.2, size=6)
    if kind == 5:
        kwargs['n_grid'] = 700
    if (seed >= 8 and kind in (1, 3)) or seed == 17:
        kwargs['j_max'] = rng.uniform(2.0, 10.0)
    return Q, v, a, kwargs


@pytest.mark.parametrize('seed, duration, middle', REFERENCE)
def test_durations_match_the_implementation_before_the_speed_up(seed, duration, middle):
    Q, v, a, kwargs = case(seed)
    traj = time_optimal.time_parameterize(Q, v, a, **kwargs)
    times = np.asarray(traj.waypoint_times)
    assert traj.duration == pytest.approx(duration, rel=1e-9, abs=0.0)
    assert times[times.size // 2] == pytest.approx(middle, rel=1e-9, abs=0.0)


@pytest.mark.parametrize('seed', [5, 6, 7, 16])
def test_long_paths_keep_the_limits_between_grid_points(seed):
    Q, v, a, kwargs = case(seed)
    traj = time_optimal.time_parameterize(Q, v, a, **kwargs)
    t = np.linspace(0.0, traj.duration, 200001)
    _, qd, qdd = traj.sample(t)
    assert np.all(np.abs(qd) <= v) and np.all(np.abs(qdd) <= a)
