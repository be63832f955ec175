"""synthetic/truths.py: a truth's run covers the session recorded of it, so a session holds the start
of the run, the same whatever the run's length, and never its wrap (the crossfade back to its start)."""

from __future__ import annotations

import math

import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.hardware.emulators.signal import FADE
from wearbench.synthetic.truths import record_state, truth_revolutions
from wearbench.validation import load_session

pytestmark = pytest.mark.slow  # a model run of each truth, a few seconds each

CYCLES = 6


@pytest.mark.parametrize(("name", "faults"), [
    ("ninebar-testbed", {}),
    ("ninebar-testbed", {"index_lost_at": "3 s"}),  # the recorder turns 2 revolutions more, waiting for it
    ("slider-crank", {}),  # 5000 rpm: 46 revolutions of ramp and hold before it records
], ids=["test-bed", "test-bed-index-lost", "slider-crank"])
def test_a_session_ends_before_its_truths_run_wraps(tmp_path, name, faults):
    """The encoder counts the crank's turns from the device's start, as the table plays them (both
    benches turn the crank at the motor's speed): the last angle recorded lies before the crossfade."""
    bench = load_bench(shipped_bench(name))
    path = tmp_path / "session.mcap"
    revolutions = truth_revolutions(bench, CYCLES)
    try:
        record_state(bench, bench.states[0], 5, path, backend="sim", cycles=CYCLES, revolutions=revolutions,
                     faults=faults)
    except RuntimeError:
        assert faults  # a session whose index is lost ends without its last cycle
    turned = load_session(path).encoder["angle"].iloc[-1] / (2 * math.pi)
    assert CYCLES < turned < revolutions - FADE / (2 * math.pi), (turned, revolutions)
