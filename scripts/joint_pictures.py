"""
Draw the positive direction of each Mover6 joint from the URDF: docs/images/joint1..6.png.

Each picture shows the arm (config/mover6.urdf's chain, ``kinematics.forward``) at a start pose
in grey and with one joint turned +30 deg in blue, the joint's axis in red with the turn's
direction (right-hand rule) as a curved arrow, and a short marker on the tool so that the wrist's
turns show. ``first_run`` asks the operator to compare the real arm's motion with them.
Run: ``./run.sh exec python scripts/joint_pictures.py [OUT_DIR]``.
"""

import math
import os
import sys

import matplotlib
matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
from mover6_control.kinematics.arm import mover6  # noqa: E402
from mover6_control.kinematics.forward import fk_frames_batch  # noqa: E402
import numpy as np  # noqa: E402

START = np.radians([0.0, 0.0, 0.0, 0.0, 45.0, 0.0])
TURN = math.radians(30.0)


def points(arm, q):
    """Return the base, every joint frame's origin and a tool marker's end (k, 3) [m]."""
    frames = fk_frames_batch(arm, q[None, :])[0]
    tip = frames[-1]
    marker = tip[:3, 3] + 0.06 * tip[:3, 0]
    return np.vstack([[0.0, 0.0, 0.0], frames[:, :3, 3], marker])


def draw(arm, i, path):
    """Draw joint ``i`` (0-based) turning positive; save to ``path``."""
    fig = plt.figure(figsize=(5, 5))
    ax = fig.add_subplot(projection='3d')
    q1 = START.copy()
    q1[i] += TURN
    for q, colour, label in ((START, '0.6', 'start'), (q1, 'tab:blue', f'joint{i + 1} +30 deg')):
        p = points(arm, q)
        ax.plot(p[:-1, 0], p[:-1, 1], p[:-1, 2], '-o', color=colour, lw=3, ms=4, label=label)
        ax.plot(p[-2:, 0], p[-2:, 1], p[-2:, 2], '-', color=colour, lw=2)
    frame = fk_frames_batch(arm, START[None, :])[0][i]
    # Joint i's frame before its own turn: the axis is the same either way.
    axis = frame[:3, :3] @ arm.axes[i]
    origin = frame[:3, 3]
    ax.quiver(*origin, *(0.12 * axis), color='tab:red', lw=2, arrow_length_ratio=0.2)
    # A curved arrow about the axis, counter-clockwise seen from the axis' tip.
    u = np.cross(axis, [0.0, 0.0, 1.0] if abs(axis[2]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    t = np.linspace(0.0, 1.5 * math.pi, 40)
    ring = origin + 0.06 * axis + 0.05 * (np.outer(np.cos(t), u) + np.outer(np.sin(t), v))
    ax.plot(ring[:, 0], ring[:, 1], ring[:, 2], color='tab:red', lw=1.5)
    head = ring[-1] - ring[-2]
    ax.quiver(*ring[-1], *(head / np.linalg.norm(head) * 0.02), color='tab:red', lw=1.5)
    ax.set_xlabel('x (forward) [m]')
    ax.set_ylabel('y (left) [m]')
    ax.set_zlabel('z (up) [m]')
    ax.set_xlim(-0.1, 0.5)
    ax.set_ylim(-0.3, 0.3)
    ax.set_zlim(0.0, 0.6)
    ax.view_init(elev=20, azim=-60)
    ax.set_title(f'joint{i + 1}: positive turn (grey -> blue);\n'
                 'red: its axis, the turn right-handed about it', fontsize=9)
    ax.legend(loc='upper left', fontsize=8)
    fig.savefig(path, dpi=80)
    plt.close(fig)


def main(out_dir):
    """Draw the six pictures into ``out_dir``."""
    arm = mover6('hardware')
    os.makedirs(out_dir, exist_ok=True)
    for i in range(arm.n_joints):
        draw(arm, i, os.path.join(out_dir, f'joint{i + 1}.png'))
        print(os.path.join(out_dir, f'joint{i + 1}.png'))


if __name__ == '__main__':
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        os.path.dirname(os.path.abspath(__file__)), '..', 'docs', 'images'))
