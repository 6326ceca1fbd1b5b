"""
A frame log of one goal on the CAN-level Mover6, opened with python-can's own reader.

``can_sim`` on a pty, the driver on it with ``frame_log`` (candump's log format, python-can's
writer), the controller and the planner as processes; one README goal (10 cm along x from home).
Once the stack has stopped (the driver closes the log), ``can.LogReader`` reads the file: every
frame with its direction (T sent, R received), the set-points that moved the arm, and every reply
whole: ``data[5]`` (the echoed set-point counter) and ``data[6]`` (read by no driver) as the
modules sent them.
"""

import can
from mover6_control.hardware import protocol
from mover6_control.kinematics.arm import mover6
from mover6_control.nodes.messages.conversions import status_values
from mover6_control.tools.goal_cli import GoalClient
from mover6_control.tools.goal_convention import poses_from_numbers
import pytest
from ros_testing import CanSimProcess, ready_client, Stack

pytestmark = pytest.mark.e2e

ARM = mover6('hardware')
GOAL = poses_from_numbers([0.445, 0.0, 0.4425, 0.0, 0.0, 0.0], quat=False, arm=ARM)[-1]
# As scripts/launch.sh --hardware can-sim --limit-set hardware starts it.
OPTIONS = {'hardware': 'can_sim', 'limit_set': 'hardware'}


def test_a_frame_log_of_one_goal_reads_back_with_python_cans_reader(tmp_path):
    log = tmp_path / 'frames.log'
    with CanSimProcess(tmp_path, tmp_path / 'mover6-can') as sim:
        with Stack(tmp_path, options=dict(OPTIONS, can_channel=sim.link),
                   driver={'frame_log': str(log)},        # MOVER6_DRIVER_ARGS="-p frame_log:=..."
                   names=('driver', 'controller', 'planner')) as stack:
            with ready_client(stack, lambda: GoalClient(name='frame_log_client'),
                              timeout=60.0) as client:
                assert client.spin_until(
                    lambda: status_values(client.controller_status).get('state') == 'idle',
                    30.0), stack.report()
                outcome = client.send_pose(GOAL, timeout=60.0)
                assert outcome.arrived, f'{outcome}\n{stack.report()}'
    frames = list(can.LogReader(str(log)))
    sent = [f for f in frames if not f.is_rx]
    read = [f for f in frames if f.is_rx]
    assert {f.arbitration_id for f in sent} == {protocol.command_id(n) for n in protocol.JOINTS}
    assert {f.arbitration_id for f in read} == {protocol.reply_id(n) for n in protocol.JOINTS}
    commands = [protocol.decode_command(bytes(f.data)) for f in sent]
    kinds = {c.kind for c in commands}
    assert {'disable', 'reset', 'enable', 'setpoint'} <= kinds
    # The goal (along x: joints 2, 3 and 5) moved the arm: joint 2's module got set-points at
    # many positions.
    j2 = {c.position for f, c in zip(sent, commands)
          if c.kind == 'setpoint' and f.arbitration_id == protocol.command_id(2)}
    assert len(j2) > 10
    # Every reply whole, as the module sent it: the counters it echoed in data[5] are set-points'
    # counters sent to it, data[6] is in the log too.
    assert all(len(f.data) == 8 for f in read)
    counters = {(f.arbitration_id, f.data[6]) for f in sent if f.data[:2] == b'\x14\x00'}
    echoes = [(f.arbitration_id - 1, f.data[5]) for f in read if f.data[5]]
    assert echoes and all(e in counters for e in echoes)
    replies = [protocol.decode_reply(bytes(f.data)) for f in read]
    assert all(r.spare == f.data[6] for r, f in zip(replies, read))
    print(f'FIGURE frame_log: one goal, {len(sent)} frames sent (T), {len(read)} read (R), '
          f'{len(j2)} positions of joint 2; read back with can.LogReader from {log}')
