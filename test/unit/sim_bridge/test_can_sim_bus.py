"""The CAN-level Mover6 in this process, answering over python-can's ``virtual`` interface."""

import threading
import uuid

import can
from can_frames import replies_of, send_all, setpoint_all
from mover6_control.hardware import protocol
from mover6_control.hardware.bus import open_bus
from sim_bridge.can_sim import build_arm, BusServer


def test_the_arm_answers_on_a_virtual_bus():
    channel = f'can_sim_test_{uuid.uuid4().hex}'
    arm = build_arm()
    server_bus = can.Bus(interface='virtual', channel=channel)
    client = open_bus('virtual', channel)
    stop = threading.Event()
    thread = threading.Thread(target=BusServer(arm, server_bus).serve, args=(stop,))
    thread.start()
    try:
        setpoint_all(client, [0, 0, 0, 0, 500, 509], 1)
        got = replies_of(client, 6, 1)
        assert sorted(got) == [protocol.reply_id(j) for j in protocol.JOINTS]
        assert [got[protocol.reply_id(j)].error_flags for j in protocol.JOINTS] == [0x1C] * 6
        assert got[protocol.reply_id(6)].position == 509
        send_all(client, protocol.RESET_ERRORS)
        setpoint_all(client, [0, 0, 0, 0, 500, 509], 2)
        got = replies_of(client, 6, 2)
        assert [got[protocol.reply_id(j)].error_flags for j in protocol.JOINTS] == [0x04] * 6
    finally:
        stop.set()
        thread.join(5.0)
        client.shutdown()
        server_bus.shutdown()
