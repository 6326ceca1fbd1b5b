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


def test_each_frame_is_stamped_when_it_is_taken_not_before_a_long_drain():
    # The first frame counts from the clock read before the drain (a server held up with
    # frames waiting trips no watchdog); each later one from the clock when it is taken: a
    # drain that takes 0.3 s a frame does not stamp the last frame 0.6 s in the past.
    channel = f'can_sim_test_{uuid.uuid4().hex}'
    arm = build_arm()
    reads = iter([10.0, 10.3, 10.6, 10.9])
    server_bus = can.Bus(interface='virtual', channel=channel)
    client = open_bus('virtual', channel)
    server = BusServer(arm, server_bus, clock=lambda: next(reads))
    stamps = []
    receive = arm.receive

    def recording(can_id, data, now):
        stamps.append(now)
        return receive(can_id, data, now)
    arm.receive = recording
    try:
        for counter in (1, 2, 3):
            client.send(can.Message(arbitration_id=protocol.command_id(1),
                                    data=protocol.encode_setpoint(0, counter),
                                    is_extended_id=False))
        server.poll(1.0)
        assert stamps == [10.0, 10.3, 10.6]
        assert arm.modules[0].status()['setpoint'] == 0
    finally:
        client.shutdown()
        server_bus.shutdown()
