"""Bench emulators: the transport-free :class:`~wearbench.hardware.emulators.device.BenchDevice`
(the ``sim`` backend), and real peers around it on a pseudo-terminal (``serial_server``) and on the
python-can virtual bus (``can_server``, with a CANopen CiA 402 drive)."""
