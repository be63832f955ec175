"""Fixtures for the acquisition tests: the test-bed bench and emulator configs. The comparison of a
session file with what an emulator sent is the pytest plugin's (``wearbench.testing``)."""

from __future__ import annotations

import pytest
from wearbench.testing import (
    assert_same_blocks,
    recorded_blocks,
    sent_from_blocks,
    sent_from_device,
    sent_from_serial_log,
)

FAST = 62.0  # rad/s: 20 cycles in about 2 s (the motor's limit is 600 rpm)
HARMONIC = {"signal": "harmonic", "cache": False}

__all__ = ["FAST", "HARMONIC", "assert_same_blocks", "recorded_blocks", "sent_from_can", "sent_from_device",
           "sent_from_serial_log"]


@pytest.fixture(scope="session")
def bench(wearbench_bench):
    """The shipped test bed (the plugin's ``wearbench_bench``)."""
    return wearbench_bench


def sent_from_can(emulator) -> dict:
    """What a ``CanEmulator`` sent, block by block."""
    return sent_from_blocks(emulator.sent)
