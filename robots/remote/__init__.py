"""A robot's devices used from another process: the calls, the values, and who serves them.

``devices.DeviceHost`` serves the devices of an open backend call by call; ``devices.remote_devices``
builds proxies with the same methods and constant attributes, so skills and the run cannot tell
them from local devices. Values travel as tagged JSON (``values``): floats, tuples, numpy arrays
and the readings of ``botstage.robots.interfaces`` arrive exactly as they left, so a distributed
simulation matches a local one byte for byte. The link between them is a protocol; botstage's
ROS 2 services carry it between processes.
"""
