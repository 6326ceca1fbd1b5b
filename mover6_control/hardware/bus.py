"""
Open the arm's CAN bus by interface name: python-can's interfaces, or the CPR USB2CAN adapter.

``cpr_usb2can`` opens ``Usb2CanBus`` (the vendor's serial adapter, ``usb2can.py``); every other
name goes to ``can.Bus`` (``socketcan`` for PEAK and other SocketCAN adapters, ``pcan``,
``virtual`` for tests, ...). An unknown name fails here with the list of the known ones, before
any device is touched.
"""

from __future__ import annotations

import can
from can.interfaces import VALID_INTERFACES
from mover6_control.errors import InvalidInputError
from mover6_control.hardware.protocol import BITRATE
from mover6_control.hardware.usb2can import Usb2CanBus

USB2CAN = 'cpr_usb2can'


def interfaces() -> tuple[str, ...]:
    """Return the interface names ``open_bus`` accepts, sorted."""
    return tuple(sorted(set(VALID_INTERFACES) | {USB2CAN}))


def open_bus(interface: str, channel: str, bitrate: int = BITRATE,
             **kwargs: object) -> can.BusABC:
    """Open and return the bus; InvalidInputError for an unknown interface or a bad bit rate."""
    if not isinstance(interface, str) or interface not in interfaces():
        raise InvalidInputError(f'can_interface must be one of {list(interfaces())}, '
                                f'got {interface!r}')
    if isinstance(bitrate, bool) or not isinstance(bitrate, int) or bitrate <= 0:
        raise InvalidInputError(f'bitrate must be a positive int [bit/s], got {bitrate!r}')
    if interface == USB2CAN:
        return Usb2CanBus(channel, **kwargs)
    return can.Bus(interface=interface, channel=channel, bitrate=bitrate, **kwargs)
