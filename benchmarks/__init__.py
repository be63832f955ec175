"""Benchmarks: scripts that answer one question each and print a table, run from the repository root
as modules (``python -m benchmarks.validation.identify --help``); with ``--json PATH`` a script also
writes its result for the documentation's results pages (``benchmarks.result_json``). Grouped by what
they measure: ``model`` (speed against error, where a revolution's time goes), ``acquisition``
(recording, session files, emulators), ``validation`` (identification, estimation, windows),
``compute`` (batches on the compute layer)."""
