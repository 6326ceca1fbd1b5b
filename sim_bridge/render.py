"""
Pictures of the arm: an offscreen PNG of one configuration, an animated GIF of a recorded motion.

Rendering is offscreen through MuJoCo's ``Renderer``. Without a display set ``MUJOCO_GL=egl``
before MuJoCo is first imported (Debian: ``apt-get install -y libegl1 libgl1``); the command line
does that itself::

    python -m sim_bridge.render --q 0 0.4 0.3 0 0.6 0 --png arm.png
    python -m sim_bridge.render --gif motion.gif                  # a demo motion, simulated
    python -m sim_bridge.render --record motion.npz --gif out.gif   # arrays t (m,), q (m, n)

A recorded motion is positions ``Q`` (m, n) [rad] at increasing times (m,) [s]; frames are
sampled from it at ``fps`` by linear interpolation, so any recording rate works.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
import os
import sys

from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import ArmModel, LIMIT_SETS, mover6
import mujoco
import numpy as np
from sim_bridge.model import build_model, joint_qpos_addresses


def make_camera(lookat: Sequence[float] = (0.1, 0.0, 0.3), distance: float = 1.3,
                azimuth: float = 140.0, elevation: float = -20.0) -> mujoco.MjvCamera:
    """Return a free ``mujoco.MjvCamera`` looking at ``lookat`` [m] from ``distance`` [m]."""
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.lookat[:] = lookat
    camera.distance = distance
    camera.azimuth = azimuth
    camera.elevation = elevation
    return camera


def resample(times: np.ndarray, Q: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """
    Return frame times (k,) [s] and configurations (k, n) of a recording sampled at ``fps``.

    ``times`` (m,) must increase strictly; the frames start at ``times[0]`` and end at or
    before ``times[-1]``, positions interpolated linearly per joint.
    """
    times = np.asarray(times, dtype=float)
    Q = np.asarray(Q, dtype=float)
    if times.ndim != 1 or Q.ndim != 2 or len(times) != len(Q) or len(times) == 0:
        raise InvalidInputError(
            f'a recording needs times (m,) and Q (m, n), got {times.shape} and {Q.shape}')
    if not (np.all(np.isfinite(times)) and np.all(np.isfinite(Q))):
        raise InvalidInputError('a recording has non-finite values')
    if np.any(np.diff(times) <= 0.0):
        raise InvalidInputError('recording times must increase strictly')
    if not (np.isfinite(fps) and fps > 0.0):
        raise InvalidInputError(f'fps must be positive, got {fps}')
    k = int(np.floor((times[-1] - times[0]) * fps + 1e-9)) + 1
    t_frames = times[0] + np.arange(k) / fps
    Q_frames = np.column_stack([np.interp(t_frames, times, Q[:, j]) for j in range(Q.shape[1])])
    return t_frames, Q_frames


def render_frames(arm: ArmModel, Q: np.ndarray, width: int = 320, height: int = 240,
                  camera: mujoco.MjvCamera | None = None) -> list[np.ndarray]:
    """Return one RGB image (height, width, 3) uint8 per configuration of ``Q`` (k, n) [rad]."""
    Q = np.atleast_2d(np.asarray(Q, dtype=float))
    if Q.shape[1] != arm.n_joints:
        raise InvalidInputError(f'Q must have {arm.n_joints} columns, got shape {Q.shape}')
    model = build_model(arm)
    data = mujoco.MjData(model)
    qadr = joint_qpos_addresses(model, arm.joint_names)
    camera = camera or make_camera()
    frames = []
    with mujoco.Renderer(model, height, width) as renderer:
        for q in Q:
            data.qpos[qadr] = q
            mujoco.mj_kinematics(model, data)
            renderer.update_scene(data, camera)
            frames.append(renderer.render().copy())
    return frames


def save_png(arm: ArmModel, q: np.ndarray, path: str, width: int = 640, height: int = 480,
             camera: mujoco.MjvCamera | None = None) -> np.ndarray:
    """Render ``arm`` at ``q`` (n,) [rad] to a PNG file at ``path``; return the image."""
    from PIL import Image

    image = render_frames(arm, [arm.check_q(q)], width, height, camera)[0]
    Image.fromarray(image).save(path)
    return image


def save_gif(arm: ArmModel, times: np.ndarray, Q: np.ndarray, path: str, fps: float = 20.0,
             width: int = 320, height: int = 240,
             camera: mujoco.MjvCamera | None = None) -> int:
    """Render a recorded motion (times (m,) [s], Q (m, n) [rad]) to an animated GIF."""
    from PIL import Image

    _, Q_frames = resample(times, Q, fps)
    images = [Image.fromarray(f) for f in render_frames(arm, Q_frames, width, height, camera)]
    images[0].save(path, save_all=True, append_images=images[1:],
                   duration=int(round(1000.0 / fps)), loop=0)
    return len(images)


def demo_recording(arm: ArmModel, duration: float = 2.0,
                   rate: float = 50.0) -> tuple[np.ndarray, np.ndarray]:
    """Return (times, Q) of a simulated jog: every joint swings out and back, as recorded."""
    from sim_bridge.simulator import Simulator

    sim = Simulator(arm)
    amplitude = 0.8 * arm.velocity_limits
    times, Q = [sim.time], [sim.q]
    period = 1.0 / rate
    while sim.time < duration - 1e-9:
        v = amplitude * np.cos(2.0 * np.pi * sim.time / duration)
        sim.set_command(arm.joint_names, v, sim.time)
        sim.run_for(period)
        times.append(sim.time)
        Q.append(sim.q)
    return np.array(times), np.array(Q)


def main(argv: Sequence[str] | None = None) -> int:
    """Render a PNG and/or a GIF from the command line (see the module docstring)."""
    parser = argparse.ArgumentParser(description='Render the Mover6 offscreen (MuJoCo).')
    parser.add_argument('--q', type=float, nargs='+', help='configuration for --png [rad]')
    parser.add_argument('--png', help='write a PNG of --q (default: zeros)')
    parser.add_argument('--gif', help='write an animated GIF of --record or of a demo motion')
    parser.add_argument('--record', help='.npz with arrays t (m,) [s] and q (m, n) [rad]')
    parser.add_argument('--fps', type=float, default=20.0)
    parser.add_argument('--width', type=int, default=320)
    parser.add_argument('--height', type=int, default=240)
    parser.add_argument('--limit-set', default='hardware', choices=LIMIT_SETS)
    args = parser.parse_args(argv)
    if not (args.png or args.gif):
        parser.error('nothing to do: give --png and/or --gif')
    arm = mover6(args.limit_set)
    if args.png:
        q = np.zeros(arm.n_joints) if args.q is None else np.array(args.q)
        save_png(arm, q, args.png, args.width, args.height)
        print(f'wrote {args.png}')
    if args.gif:
        if args.record:
            with np.load(args.record) as rec:
                times, Q = rec['t'], rec['q']
        else:
            times, Q = demo_recording(arm)
        n = save_gif(arm, times, Q, args.gif, args.fps, args.width, args.height)
        print(f'wrote {args.gif} ({n} frames at {args.fps:g} fps)')
    return 0


def _ensure_offscreen_gl():
    """Re-run this command with ``MUJOCO_GL=egl`` when no GL backend or display is set."""
    if os.environ.get('MUJOCO_GL') or os.environ.get('DISPLAY'):
        return
    env = dict(os.environ, MUJOCO_GL='egl')
    os.execve(sys.executable, [sys.executable, '-m', 'sim_bridge.render'] + sys.argv[1:], env)


if __name__ == '__main__':
    _ensure_offscreen_gl()
    sys.exit(main())
