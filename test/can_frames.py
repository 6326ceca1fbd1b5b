"""Frames to and from the simulated Mover6's modules, for the tests of can_sim (unit and e2e)."""

import can
from mover6_control.hardware import protocol
from ros_testing import wait_until


def replies_of(bus, count, stamp, timeout=5.0):
    """
    Receive ``count`` replies with timestamp ``stamp`` within ``timeout`` [s].

    Return {reply ID: Reply}. A module echoes a set-point's counter and answers a command with 0:
    ``stamp`` picks the answers to one round of frames.
    """
    out = {}

    def more():
        msg = bus.recv(0.05)
        if msg is not None:
            reply = protocol.decode_reply(bytes(msg.data[:msg.dlc]))
            if reply.timestamp == stamp:
                out[msg.arbitration_id] = reply
        return len(out) >= count
    wait_until(more, timeout, period=0.0)
    return out


def send_all(bus, data):
    """Send ``data`` to every module."""
    for joint in protocol.JOINTS:
        bus.send(can.Message(arbitration_id=protocol.command_id(joint), data=data,
                             is_extended_id=False))


def setpoint_all(bus, arm_positions, counter):
    """Send every module a set-point at the given wire positions."""
    for joint, p in zip(protocol.JOINTS, arm_positions):
        bus.send(can.Message(arbitration_id=protocol.command_id(joint),
                             data=protocol.encode_setpoint(int(p), counter),
                             is_extended_id=False))
