"""
The udev rule shipped for the USB2CAN adapter: a stable name, ModemManager kept off it.

Read from config/99-mover6-can.rules: the rule that names the device, the install command in its
header and in docs/real_arm.md.
"""

import os

from mover6_control.resources import CONFIG_DIR
from source_tree import ROOT

RULES = os.path.join(CONFIG_DIR, '99-mover6-can.rules')


def rules():
    """Return the rule lines (no comments, no blank lines) of the shipped file."""
    with open(RULES) as f:
        return [line.strip() for line in f if line.strip() and not line.startswith('#')]


def test_the_tty_gets_a_stable_name_and_modem_manager_leaves_it_alone():
    tty = [line for line in rules() if 'SUBSYSTEM=="tty"' in line]
    assert len(tty) == 1
    assert 'SYMLINK+="mover6_can"' in tty[0]
    assert 'ENV{ID_MM_DEVICE_IGNORE}="1"' in tty[0] and 'GROUP="dialout"' in tty[0]
    assert all(line.count('==') + line.count('=') >= 2 for line in rules())


def test_the_install_command_is_written_down():
    install = 'sudo cp config/99-mover6-can.rules /etc/udev/rules.d/'
    with open(RULES) as f:
        assert install in f.read()
    with open(os.path.join(ROOT, 'docs', 'real_arm.md')) as f:
        page = f.read()
    assert install in page and 'udevadm control --reload-rules' in page
