"""
run.sh, the one entry point: its two set-up paths, tried in throw-away places.

The project's own environment is never touched: MOVER6_VENV and MOVER6_WS point into tmp_path.
"""

import os
import subprocess
import sys
import sysconfig

import pytest
from source_tree import ROOT

RUN_SH = os.path.join(ROOT, 'run.sh')

# A Python 3.12 as far as run.sh can tell: it reports its version, cannot import rclpy, and
# would make a venv if asked (so a test that finds none knows that none was asked for).
FAKE_PYTHON_312 = """#!/bin/sh
if [ "$1" = -m ] && [ "$2" = venv ]; then
    for a; do last=$a; done
    mkdir -p "$last"
    exit 0
fi
case "$2" in
    *version_info*) echo 3.12 ;;
    *) exit 1 ;;
esac
"""


def run_sh(args, env, cwd, timeout):
    """Run ``run.sh ARGS`` from ``cwd`` with exactly ``env``; return the completed process."""
    return subprocess.run([RUN_SH] + args, env=env, cwd=cwd, timeout=timeout,
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def base_env(tmp_path):
    """Return a bare environment with the venv and the workspace in ``tmp_path``."""
    return {
        'HOME': os.environ.get('HOME', str(tmp_path)),
        'PATH': '/usr/local/bin:/usr/bin:/bin',
        'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST',
        'ROS_DOMAIN_ID': os.environ.get('ROS_DOMAIN_ID', '42'),
        'MOVER6_VENV': str(tmp_path / 'venv'),
        'MOVER6_WS': str(tmp_path / 'ws'),
    }


@pytest.mark.parametrize('python', ['python3.12', 'missing'])
def test_without_ros_and_without_python_311_it_stops_before_making_anything(tmp_path, python):
    """No sourced ROS and a Python the PyPI ROS wheels do not fit: advice, exit 1, no venv."""
    fake = tmp_path / 'bin' / python
    if python != 'missing':
        fake.parent.mkdir()
        fake.write_text(FAKE_PYTHON_312)
        fake.chmod(0o755)
    env = dict(base_env(tmp_path), PYTHON=str(fake))
    done = run_sh(['setup'], env, tmp_path, timeout=30)
    assert done.returncode == 1, done.stderr
    if python == 'missing':
        assert 'no Python found' in done.stderr
    else:
        assert 'is Python 3.12' in done.stderr
    assert 'needs Python 3.11' in done.stderr
    assert 'source /opt/ros/jazzy/setup.bash' in done.stderr
    assert 'PYTHON=python3.11' in done.stderr
    assert not (tmp_path / 'venv').exists()
    assert not (tmp_path / 'ws').exists()


def package_site_and_prefix(name):
    """Return (the folder that holds package ``name``, its ament prefix)."""
    from ament_index_python.packages import get_package_prefix
    module = __import__(name)
    return os.path.dirname(os.path.dirname(module.__file__)), get_package_prefix(name)


def unique(paths):
    """Return ``paths`` without repeats, in order, joined for a PATH-like variable."""
    return os.pathsep.join(dict.fromkeys(p for p in paths if p))


def sourced_jazzy_env(tmp_path):
    """
    Return an environment that looks like one where ROS 2 Jazzy was sourced.

    The ROS is the one this test runs with (the PyPI wheels in the project venv, or a real
    install), control_msgs and tf2_msgs included, set out the way a setup.bash does:
    ROS_DISTRO, the prefix paths, PYTHONPATH, LD_LIBRARY_PATH. mover6_control is not in it.
    """
    rclpy_site, rclpy_prefix = package_site_and_prefix('rclpy')
    msgs_site, msgs_prefix = package_site_and_prefix('control_msgs')
    tf_site, tf_prefix = package_site_and_prefix('tf2_msgs')
    colcon_bin = os.path.dirname(subprocess.run(
        ['sh', '-c', 'command -v colcon'], stdout=subprocess.PIPE, text=True,
        check=True).stdout.strip())
    env = base_env(tmp_path)
    env.update({
        'ROS_DISTRO': 'jazzy',
        'AMENT_PREFIX_PATH': unique([msgs_prefix, tf_prefix, rclpy_prefix]),
        'CMAKE_PREFIX_PATH': unique([msgs_prefix, tf_prefix, rclpy_prefix]),
        # The libraries next to the ROS Python packages (numpy, mujoco, ...) stand in for the
        # system's Python packages.
        'PYTHONPATH': unique([msgs_site, tf_site, rclpy_site, sysconfig.get_paths()['purelib']]),
        'LD_LIBRARY_PATH': os.environ.get('LD_LIBRARY_PATH', ''),
        'PATH': unique([colcon_bin, env['PATH']]),
        'PYTHON': sys.executable,
        # Everything must already be there: this path installs nothing ROS, and a test must
        # not download.
        'PIP_NO_INDEX': '1',
    })
    return env, rclpy_site


def test_with_a_sourced_jazzy_it_uses_that_install(tmp_path):
    """
    The sourced-ROS path, set up for real in tmp_path (about 15 s).

    run.sh finds the sourced Jazzy, makes a venv on top of it that installs nothing ROS, builds
    only this package (control_msgs and tf2_msgs come with the sourced install), and its exec
    runs inside.
    """
    pytest.importorskip('rclpy')
    pytest.importorskip('control_msgs')
    env, rclpy_site = sourced_jazzy_env(tmp_path)
    probe = ('import rclpy, mover6_control, control_msgs.msg; '
             'print(rclpy.__file__); print(mover6_control.__file__)')
    done = run_sh(['exec', 'python', '-c', probe], env, tmp_path, timeout=240)
    assert done.returncode == 0, done.stderr
    assert 'using the sourced ROS 2 jazzy install' in done.stderr
    assert 'colcon build (.)' in done.stderr       # no interfaces: the sourced install has them
    rclpy_file, mover6_file = done.stdout.split()
    assert rclpy_file.startswith(rclpy_site + os.sep)
    assert mover6_file.startswith(str(tmp_path / 'ws' / 'install') + os.sep)
    with open(tmp_path / 'venv' / 'pyvenv.cfg') as f:
        assert 'include-system-site-packages = true' in f.read()
    with open(tmp_path / 'venv' / 'pip.log') as f:
        assert 'ros-jazzy' not in f.read()

    # Re-running is quick and changes nothing.
    again = run_sh(['exec', 'python', '-c', 'import rclpy, mover6_control'], env, tmp_path,
                   timeout=60)
    assert again.returncode == 0, again.stderr
    assert 'setting up' not in again.stderr
    assert 'colcon build' not in again.stderr
