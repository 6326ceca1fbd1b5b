"""
run.sh's build step (scripts/run/build.sh ``colcon_build``): built again only for a change.

The function runs in bash on a throw-away copy of the tree's layout, with ``colcon`` and
``python`` replaced by shell functions that say they ran (the build itself is not the point).
"""

import os
import subprocess
import time

import pytest
from source_tree import ROOT

BUILD_SH = os.path.join(ROOT, 'scripts', 'run', 'build.sh')
WATCHED = ('mover6_control', 'sim_bridge', 'config', 'scripts', 'interfaces', 'launch')


@pytest.fixture
def tree(tmp_path):
    """Return (source root, workspace) built once: the stamp newer than every source."""
    src, ws = tmp_path / 'src', tmp_path / 'ws'
    for name in ('package.xml', 'setup.py', 'setup.cfg'):
        (src / name).parent.mkdir(parents=True, exist_ok=True)
        (src / name).write_text('')
    for name in WATCHED:
        (src / name).mkdir()
        (src / name / 'module.py').write_text('')
    (ws / 'install' / 'control_msgs').mkdir(parents=True)
    (ws / 'install' / 'tf2_msgs').mkdir(parents=True)
    assert builds(src, ws)                                # the first build writes the stamp
    (ws / 'colcon-ran').unlink()
    old = time.time() - 60.0
    for path in [src, *src.rglob('*')]:
        os.utime(path, (old, old))
    os.utime(ws / '.built', (old + 10.0, old + 10.0))   # built after every source, long ago
    assert not builds(src, ws)
    return src, ws


def builds(src, ws):
    """Return True when ``colcon_build`` would run colcon build on this tree."""
    script = f"""
        log() {{ :; }}
        colcon() {{ touch {ws}/colcon-ran; }}
        python() {{ return 0; }}
        ROOT={src} WS={ws}
        . {BUILD_SH}
        colcon_build
    """
    done = subprocess.run(['bash', '-c', script], capture_output=True, text=True, timeout=30)
    assert done.returncode == 0, done.stderr
    return (ws / 'colcon-ran').exists()


@pytest.mark.parametrize('generated', ['__pycache__/timing.cpython-311.pyc',
                                       '__pycache__/timing.kernel-12.py311.nbi',
                                       '__pycache__/timing.kernel-12.py311.1.nbc',
                                       'mover6_control.egg-info/PKG-INFO'])
def test_what_builds_and_tests_write_is_no_change(tree, generated):
    src, ws = tree
    path = src / 'mover6_control' / 'motion' / generated
    path.parent.mkdir(parents=True)
    path.write_text('')
    assert not builds(src, ws)


@pytest.mark.parametrize('changed', ['mover6_control/module.py', 'config/module.py',
                                     'setup.py', 'launch/new.launch.py'])
def test_a_changed_or_new_source_builds(tree, changed):
    src, ws = tree
    (src / changed).write_text('# changed')
    assert builds(src, ws)


def test_a_removed_source_builds(tree):
    src, ws = tree
    (src / 'sim_bridge' / 'module.py').unlink()
    assert builds(src, ws)
