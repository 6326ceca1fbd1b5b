"""
Open the arm's CAN bus by interface name: python-can's interfaces, or the CPR USB2CAN adapter.

``cpr_usb2can`` opens ``Usb2CanBus`` (the vendor's serial adapter, ``usb2can.py``); every other
name goes to ``can.Bus`` (``socketcan`` for PEAK and other SocketCAN adapters, ``pcan``,
``virtual`` for tests, ...). An unknown name fails here with the list of the known ones, before
any device is touched. ``open_frame_log`` opens python-can's own writer for a frame log (by the
file's suffix: ``.log`` candump's log format with R/T for the direction, ``.asc``, ``.blf``,
``.csv`` ...), or refuses a path it cannot write with the reason.
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


def open_frame_log(path: str) -> can.Listener:
    """
    Return python-can's writer for ``path`` (chosen by its suffix; ``.log``: candump's format).

    InvalidInputError, with the reason, for a path that cannot be written or a suffix python-can
    has no writer for; nothing is left open then.
    """
    if not isinstance(path, str) or not path:
        raise InvalidInputError(f'frame_log must be a file path, got {path!r}')
    try:
        return can.Logger(path)
    except (OSError, ValueError) as err:
        raise InvalidInputError(f'frame_log {path!r} cannot be written: {err}') from None
