"""Hardware-in-the-loop mock tests for a lab's own code: the emulated bench as pytest fixtures.

Installing wearbench installs the pytest plugin :mod:`wearbench.testing.plugin` (entry point
``pytest11``), so any test suite gets the fixtures ``serial_bench``, ``can_bench``,
``canopen_bench``, ``record_session`` and ``wearbench_bench`` (``pytest --fixtures`` lists them),
the ``realtime`` marker and the ``--wearbench-*`` options. What the fixtures use is importable
for code outside pytest: :class:`FaultPlan`, :func:`start_bench`/:class:`EmulatedBench`,
:func:`record`, and the assertions :func:`assert_valid_mcap`, :func:`assert_no_sample_lost`,
:func:`assert_identifies`. The top layer, like the command line: it imports every layer below.
"""

from importlib import import_module
from typing import Any

_WHERE = {
    "assertions": ("assert_identifies", "assert_no_sample_lost", "assert_valid_mcap", "event_time"),
    "emulated": ("EmulatedBench", "close_all", "open_benches", "start_bench"),
    "faults": ("FaultPlan",),
    "recording": ("RecordedSession", "assert_same_blocks", "record", "recorded_blocks", "sent_from_blocks",
                  "sent_from_device", "sent_from_serial_log"),
}
_MODULE = {name: module for module, names in _WHERE.items() for name in names}

__all__ = [*_WHERE["assertions"], *_WHERE["emulated"], *_WHERE["faults"], *_WHERE["recording"]]  # noqa: PLE0604


def __getattr__(name: str) -> Any:
    """Names load with their module on first use: the pytest plugin is imported by every pytest
    run, and wearbench's acquisition stack only when a test uses it."""
    if name not in _MODULE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(f"{__name__}.{_MODULE[name]}"), name)
    globals()[name] = value
    return value
