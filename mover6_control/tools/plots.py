"""
Plots as PNG files: time laws, joint trajectories against limits, desired vs realised 3D path.

Uses matplotlib's object API with the Agg canvas (no pyplot, no display, no global state).
Each function writes one PNG and returns its path.
"""

import os
from typing import Optional, Sequence

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from mover6_control.control.planners import plan_motion
from mover6_control.control.profiles import LawConfig
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import ArmModel
from mover6_control.kinematics.forward import fk_batch
from mover6_control.motion.metrics import max_deviation_from_polyline
from mover6_control.validation import as_finite_array
import numpy as np


def _save(fig, path):
    path = os.fspath(path)
    folder = os.path.dirname(path)
    if folder:
        os.makedirs(folder, exist_ok=True)
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=100)
    return path


def plot_time_law(laws: object, path: str, n: int = 501) -> str:
    """
    Plot ``s(tau)`` and its first three derivatives for each law.

    As the Jacobians and trajectories report's Fig. 5.

    ``laws`` is one time law, a sequence of them, or a dict label -> law.
    """
    if hasattr(laws, 'evaluate'):
        laws = [laws]
    items = list(laws.items()) if isinstance(laws, dict) else [(law.name, law) for law in laws]
    if not items:
        raise InvalidInputError('plot_time_law needs at least one law')
    tau = np.linspace(0.0, 1.0, int(n))
    fig = Figure(figsize=(10, 7))
    axes = fig.subplots(2, 2).ravel()
    labels = ['s(tau)', "s'(tau)", "s''(tau)", "s'''(tau)"]
    for k, ax in enumerate(axes):
        for label, law in items:
            ax.plot(tau, law.evaluate(tau, k), label=label)
        ax.set_xlabel('tau')
        ax.set_ylabel(labels[k])
        ax.grid(True)
    axes[0].legend(fontsize='small')
    fig.suptitle('Time laws and their derivatives')
    fig.tight_layout()
    return _save(fig, path)


def plot_joint_trajectories(t: np.ndarray, Q: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                            path: str, QD: Optional[np.ndarray] = None,
                            QDD: Optional[np.ndarray] = None,
                            names: Optional[Sequence[str]] = None) -> str:
    """
    Plot joint positions (m, n) [rad] over ``t`` (m,) [s] with dashed joint limits (n,).

    Velocity and acceleration panels are added when ``QD`` / ``QDD`` (m, n) are given
    (the Mover6 report Fig. 5-7, the Jacobians and trajectories report Fig. 6-10).
    """
    Q = as_finite_array(Q, (None, None), 'Q')
    m, n = Q.shape
    t = as_finite_array(t, (m,), 't')
    lower = np.asarray(lower, dtype=float).reshape(n)
    upper = np.asarray(upper, dtype=float).reshape(n)
    names = list(names) if names is not None else [f'joint{i + 1}' for i in range(n)]
    panels = [('position [rad]', Q)]
    if QD is not None:
        panels.append(('velocity [rad/s]', as_finite_array(QD, (m, n), 'QD')))
    if QDD is not None:
        panels.append(('acceleration [rad/s^2]', as_finite_array(QDD, (m, n), 'QDD')))
    fig = Figure(figsize=(10, 3.2 * len(panels)))
    axes = np.atleast_1d(fig.subplots(len(panels), 1, sharex=True))
    colors = [f'C{i}' for i in range(n)]
    for ax, (label, data) in zip(axes, panels):
        for i in range(n):
            ax.plot(t, data[:, i], color=colors[i], label=names[i])
        ax.set_ylabel(label)
        ax.grid(True)
    for i in range(n):
        for bound in (lower[i], upper[i]):
            if np.isfinite(bound):
                axes[0].axhline(bound, color=colors[i], linestyle='--', linewidth=0.8)
    axes[0].legend(fontsize='small', ncol=min(n, 6))
    axes[-1].set_xlabel('time [s]')
    fig.suptitle('Joint trajectories (dashed: joint limits)')
    fig.tight_layout()
    return _save(fig, path)


def plot_path_3d(desired: np.ndarray, realised: np.ndarray, path: str,
                 waypoints: Optional[np.ndarray] = None) -> str:
    """Plot the desired tool path (k, 3) [m] against the realised one (m, 3), as Fig. 1 does."""
    desired = as_finite_array(desired, (None, 3), 'desired')
    realised = as_finite_array(realised, (None, 3), 'realised')
    fig = Figure(figsize=(7, 6))
    ax = fig.add_subplot(projection='3d')
    ax.plot(*desired.T, 'b-', label='desired path')
    ax.plot(*realised.T, 'r--', label='realised path')
    if waypoints is not None:
        wp = as_finite_array(waypoints, (None, 3), 'waypoints')
        ax.scatter(*wp.T, color='g', s=12, label='waypoints')
    ax.set_xlabel('x [m]')
    ax.set_ylabel('y [m]')
    ax.set_zlabel('z [m]')
    ax.legend()
    fig.tight_layout()
    return _save(fig, path)


def plot_joint_velocities(t: np.ndarray, QD: np.ndarray, velocity_limits: np.ndarray, path: str,
                          names: Optional[Sequence[str]] = None) -> str:
    """Plot joint velocities (m, n) [rad/s] over ``t`` (m,) [s] with dashed +- limits (n,)."""
    QD = as_finite_array(QD, (None, None), 'QD')
    m, n = QD.shape
    t = as_finite_array(t, (m,), 't')
    limits = np.broadcast_to(np.asarray(velocity_limits, dtype=float), (n,))
    names = list(names) if names is not None else [f'joint{i + 1}' for i in range(n)]
    fig = Figure(figsize=(10, 4))
    ax = fig.add_subplot()
    for i in range(n):
        ax.plot(t, QD[:, i], color=f'C{i}', label=names[i])
        for sign in (-1.0, 1.0):
            ax.axhline(sign * limits[i], color=f'C{i}', linestyle='--', linewidth=0.8)
    ax.set_xlabel('time [s]')
    ax.set_ylabel('velocity [rad/s]')
    ax.grid(True)
    ax.legend(fontsize='small', ncol=min(n, 6))
    fig.suptitle('Joint velocities (dashed: velocity limits)')
    fig.tight_layout()
    return _save(fig, path)


def profile_metrics(arm: ArmModel, profile: str, q_start: np.ndarray, waypoints: np.ndarray,
                    dt: float = 1e-3) -> dict:
    """
    Return the figures of ``profile``'s plan (offline, at rest at ``q_start``) on ``waypoints``.

    ``duration`` [s]; the peaks over every joint of speed [rad/s], acceleration [rad/s^2] and jerk
    [rad/s^3] by differences of the sampled velocity every ``dt`` [s] (an acceleration step, as
    in the synchronised and trapezoidal laws, shows as step / ``dt``); ``deviation`` [m]: the
    largest distance of the flange from the straight line between the first and last pose.
    """
    plan = plan_motion(LawConfig(profile=profile), q_start, waypoints, arm.velocity_limits)
    t = np.arange(0.0, plan.duration + dt, dt)
    samples = [plan.sample(ti) for ti in t]
    q = np.array([s[0] for s in samples])
    qd = np.array([s[1] for s in samples])
    qdd = np.diff(qd, axis=0) / dt
    qddd = np.diff(qdd, axis=0) / dt
    points = fk_batch(arm, q)[:, :3, 3]
    line = fk_batch(arm, np.stack([np.asarray(q_start, float), waypoints[-1]]))[:, :3, 3]
    return {'profile': profile, 'duration': float(plan.duration),
            'peak_speed': float(np.max(np.abs(qd))),
            'peak_acceleration': float(np.max(np.abs(qdd))),
            'peak_jerk': float(np.max(np.abs(qddd))) if qddd.size else 0.0,
            'deviation': float(max_deviation_from_polyline(points, line)),
            't': t, 'qd': qd}


def plot_profile_comparison(rows: list[dict], path: str, title: str = '') -> str:
    """
    Plot one profile family side by side: speed of the fastest joint over time, and bars.

    ``rows`` are ``profile_metrics`` results. Top: max |qd| over the joints against time per
    profile; below: duration, peak speed, peak acceleration, peak jerk and path deviation.
    """
    if not rows:
        raise InvalidInputError('plot_profile_comparison needs at least one profile')
    fig = Figure(figsize=(12, 7), layout='constrained')
    grid = fig.add_gridspec(2, 5)
    ax = fig.add_subplot(grid[0, :])
    for row in rows:
        ax.plot(row['t'], np.max(np.abs(row['qd']), axis=1), label=row['profile'])
    ax.set_xlabel('t [s]')
    ax.set_ylabel('fastest joint |qd| [rad/s]')
    ax.set_title(title)
    ax.legend(fontsize='small')
    names = [row['profile'] for row in rows]
    bars = (('duration', 'duration [s]', 1.0), ('peak_speed', 'peak speed [rad/s]', 1.0),
            ('peak_acceleration', 'peak acc. [rad/s^2]', 1.0),
            ('peak_jerk', 'peak jerk [rad/s^3]', 1.0), ('deviation', 'path dev. [mm]', 1e3))
    for k, (key, label, scale) in enumerate(bars):
        axk = fig.add_subplot(grid[1, k])
        axk.bar(range(len(rows)), [row[key] * scale for row in rows])
        axk.set_xticks(range(len(rows)), names, rotation=70, fontsize='small')
        axk.set_title(label, fontsize='small')
        if key == 'peak_jerk':
            axk.set_yscale('log')
    return _save(fig, path)
