"""The sequence check names the kind of a break (the recorder's drop and repeat events take it, not a
parse of the note), and the one gap rule: a step longer than 1.5 sample periods."""

from __future__ import annotations

import numpy as np
import pytest
from wearbench.acquisition.sequence import GAP_PERIODS, SequenceBreak, SequenceCheck, gaps

pytestmark = pytest.mark.no_kernels


def test_the_check_returns_the_kind_of_a_break_with_its_note():
    check = SequenceCheck()
    assert check.check("acc", 0, 100) is None
    assert check.check("acc", 1, 100) is None
    drop = check.check("acc", 4, 100)
    assert drop == SequenceBreak("drop", "acc: 2 block(s) missing before sequence 4")
    repeat = check.check("acc", 2, 100)
    assert repeat is not None and repeat.kind == "repeat" and "sequence 2 repeated or out of order" in repeat.note
    assert (check.dropped, check.dropped_samples, check.repeated, check.blocks) == (2, 200, 1, 4)


def test_one_missing_sample_is_a_gap_and_clock_jitter_is_not():
    rate = 10_000.0
    t = np.arange(50) / rate
    t = np.delete(t, 20)  # one sample missing: a step of 2 periods
    t[30:] += 0.4 / rate  # and a late clock by 0.4 period: a step of 1.4 periods
    found = gaps(np.diff(t), rate)
    assert GAP_PERIODS == 1.5
    assert np.flatnonzero(found).tolist() == [19]
