"""Fixtures for the hardware tests: the test bed bench and emulator configs built from raw tables."""

from __future__ import annotations

import pytest
from wearbench.hardware.emulators.config import EmulatorConfig


@pytest.fixture(scope="session")
def testbed(wearbench_bench):
    """The shipped test bed (the plugin's ``wearbench_bench``)."""
    return wearbench_bench


@pytest.fixture
def make_config(testbed):
    def make(**sections) -> EmulatorConfig:
        table = {"signal": "none", **sections}
        return EmulatorConfig.from_table(table, bench=testbed)
    return make
