"""synthetic/truths.py: a truth's run covers the session recorded of it, so a session holds the start
of the run, the same whatever the run's length, and never its wrap (the crossfade back to its start)."""

from __future__ import annotations

import math

import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.hardware.emulators.signal import FADE
from wearbench.synthetic.truths import record_state, truth_revolutions
from wearbench.validation import load_session

pytestmark = pytest.mark.slow  # a model run of the truth: 10 revolutions of the test bed

CYCLES = 6


@pytest.mark.parametrize("faults", [{}, {"index_lost_at": "3 s"}], ids=["index", "index-lost"])
def test_a_session_ends_before_its_truths_run_wraps(tmp_path, faults):
    """The encoder counts the motor's turns from the device's start, as the table plays them: the last
    angle recorded lies before the crossfade, also when the index pulse stops and the recorder turns
    two revolutions more waiting for it (the longest a session plays)."""
    bench = load_bench(shipped_bench("ninebar-testbed"))
    path = tmp_path / "session.mcap"
    try:
        record_state(bench, bench.states[0], 5, path, backend="sim", cycles=CYCLES,
                     revolutions=truth_revolutions(CYCLES), faults=faults)
    except RuntimeError:
        assert faults  # a session whose index is lost ends without its last cycle
    turned = load_session(path).encoder["angle"].iloc[-1] / (2 * math.pi)
    assert CYCLES < turned < truth_revolutions(CYCLES) - FADE / (2 * math.pi), turned
