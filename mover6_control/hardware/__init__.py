"""
The real arm, without ROS: the Mover6's CAN protocol, joint scaling, bus adapters, the driver.

``protocol`` and ``scaling`` are pure (bytes and numbers in, bytes and numbers out). ``usb2can``
and ``bus`` open a bus (python-can by interface name, or the vendor's CPR USB2CAN serial adapter
through pyserial); ``driver`` runs the one control thread at the driver cycle (its parts:
``driver_state``, ``setpoints``, ``driver_replies``, ``driver_requests``). This layer imports
only the base modules; the driver node (``nodes/driver/node.py``) owns a driver and is
its only ROS face.
"""
