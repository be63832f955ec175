"""Wire protocols of the bench: serial framing (``frames``, ``messages``, spec ``SERIAL.md``), CAN
frames (``wearbench.dbc``, ``can_frames``, spec ``CAN.md``) and the CiA 402 drive's ``cia402_drive.eds``.

The data records all transports carry are in ``blocks``. Nothing here imports the emulators.
"""
