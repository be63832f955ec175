"""Bench acquisition: motor drives and acceleration sources (``drivers``, one module per backend in
``backends``), the session recorder (``recorder``) with its plan and result records (``session``),
the MCAP session file (``layout``, ``session_writer``; read back, in either layout, with
``session_file.read_session``; ``layout1`` decodes sessions recorded before the protobuf layout),
the live view (``live``), ``summary`` and ``recover``."""
