"""
The frame log keeps every reply byte for byte, the ones the driver does not use included.

A module's reply carries ``data[5]`` (the echoed counter) and ``data[6]`` (read by no driver,
the vendor's neither): the log has them as they came, with the frame's direction. The real
``ArmDriver`` on python-can's ``virtual`` bus, python-can's own writer and reader.
"""

import can
from mover6_control.hardware import protocol as p
from mover6_control.hardware.bus import open_frame_log
from mover6_control.hardware.driver import ArmDriver
from mover6_control.hardware.scaling import load_joints

_, JOINTS = load_joints()


def test_reply_bytes_5_and_6_are_logged_as_the_module_sent_them(tmp_path):
    path = tmp_path / 'frames.log'
    module = can.Bus(interface='virtual', channel='frame_log_bytes')
    driver = ArmDriver(can.Bus(interface='virtual', channel='frame_log_bytes'), JOINTS,
                       clock=lambda: 0.0, frame_log=open_frame_log(str(path)))
    try:
        reply = p.encode_reply(0x04, 1234, 0x2A, 0x81, spare=0xA5)
        module.send(can.Message(arbitration_id=p.reply_id(3), data=reply,
                                is_extended_id=False))
        driver.step(0.0)
        driver.send_due(1.0)
    finally:
        driver.close()
        module.shutdown()
    frames = list(can.LogReader(str(path)))
    read = [f for f in frames if f.is_rx]
    assert [(f.arbitration_id, bytes(f.data)) for f in read] == [(p.reply_id(3), reply)]
    assert read[0].data[5] == 0x2A and read[0].data[6] == 0xA5
    sent = [f for f in frames if not f.is_rx]
    assert sent and all(f.arbitration_id in {p.command_id(n) for n in p.JOINTS} for f in sent)
