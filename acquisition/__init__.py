"""Bench acquisition: motor drives and acceleration sources (``drivers``, one module per backend in
``backends``), the session recorder (``recorder``), the MCAP session file (``layout``,
``session_writer``; read back with ``session_file.read_session``), ``summary`` and ``recover``."""
