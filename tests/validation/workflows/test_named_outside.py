"""The identification's note when the estimate's clearance interval excludes the named state's clearance."""

from types import SimpleNamespace

import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.validation.estimation.estimate import Interval
from wearbench.validation.workflows.measure import named_outside

pytestmark = pytest.mark.no_kernels


def _case(verdict: str, lo: float, hi: float, explains: bool = True):
    bench = load_bench(shipped_bench("ninebar-testbed"))
    a = SimpleNamespace(session=SimpleNamespace(bench=bench), identification=SimpleNamespace(verdict=verdict))
    mid = 0.5 * (lo + hi)
    est = SimpleNamespace(explains=explains, clearance=Interval(mid, mid, mid, lo, hi))
    return a, est


def test_a_bench_between_the_candidates_is_noted_where_the_named_clearance_is_outside():
    note = named_outside(*_case("0.3 mm new", 0.366e-3, 0.487e-3))  # the demo's 0.45 mm bench
    assert note and "0.426 mm [0.366-0.487]" in note and "0.3 mm new's 0.300 mm" in note


def test_no_note_inside_the_interval_for_undecided_or_unexplained():
    assert named_outside(*_case("0.3 mm new", 0.271e-3, 0.407e-3)) is None
    assert named_outside(*_case("undecided", 0.366e-3, 0.487e-3)) is None
    assert named_outside(*_case("0.3 mm new", 0.366e-3, 0.487e-3, explains=False)) is None
