"""Hardware-in-the-loop mock tests for a lab's own code: the emulated bench as pytest fixtures.

Installing wearbench installs the pytest plugin :mod:`wearbench.testing.plugin` (entry point
``pytest11``), so any test suite gets the fixtures ``serial_bench``, ``can_bench``,
``canopen_bench``, ``record_session`` and ``wearbench_bench`` (``pytest --fixtures`` lists them),
the ``realtime`` marker and the ``--wearbench-*`` options. What the fixtures use is importable
for code outside pytest: :class:`FaultPlan`, :func:`start_bench`/:class:`EmulatedBench`,
:func:`record`, and the assertions :func:`assert_valid_mcap`, :func:`assert_no_sample_lost`,
:func:`assert_identifies`. The top layer, like the command line: it imports every layer below.
"""

from wearbench.testing.assertions import (
    assert_identifies,
    assert_no_sample_lost,
    assert_valid_mcap,
    event_time,
)
from wearbench.testing.emulated import EmulatedBench, close_all, open_benches, start_bench
from wearbench.testing.faults import FaultPlan
from wearbench.testing.recording import (
    RecordedSession,
    assert_same_blocks,
    record,
    recorded_blocks,
    sent_from_blocks,
    sent_from_device,
    sent_from_serial_log,
)

__all__ = [
    "EmulatedBench",
    "FaultPlan",
    "RecordedSession",
    "assert_identifies",
    "assert_no_sample_lost",
    "assert_same_blocks",
    "assert_valid_mcap",
    "close_all",
    "event_time",
    "open_benches",
    "record",
    "recorded_blocks",
    "sent_from_blocks",
    "sent_from_device",
    "sent_from_serial_log",
    "start_bench",
]
