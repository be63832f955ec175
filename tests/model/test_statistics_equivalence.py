"""The statistics-equivalence gate's own parts (``wearbench.studies.equivalence``, what
benchmarks/model/statistics_equivalence.py runs): the Holm correction on hand-computed values and a
setting's name read back into ``simulate``'s keywords (the absolute error scales themselves are the
model's, tested in test_tolerances.py)."""

from __future__ import annotations

import numpy as np
import pytest
from wearbench.studies import equivalence

pytestmark = pytest.mark.no_kernels


def test_holm_against_hand_values():
    # sorted 0.01, 0.03, 0.04, 0.5 times 4, 3, 2, 1: 0.04, 0.09, 0.08 -> 0.09 (monotone), 0.5
    adj = equivalence.holm(np.array([0.01, 0.04, 0.03, 0.5]))
    assert adj == pytest.approx([0.04, 0.09, 0.09, 0.5])
    assert equivalence.holm(np.array([0.6, 0.9])).max() == 1.0  # capped


@pytest.mark.parametrize(("tolerances", "scales", "options", "keywords"), [
    (None, None, {"method": "default"}, {"method": "default"}),
    ((1e-5, 1e-8), None, {"method": "default", "rtol": 1e-5, "atol": 1e-8},
     {"method": "default", "rtol": 1e-5, "atol": 1e-8}),
    (None, (1e-6, 3e-6), {"method": "default", "scales": (1e-6, 3e-6)},
     {"method": "default", "rtol": 0.0, "atol": (1e-6, 3e-6)}),
])
def test_a_setting_is_read_back_from_its_name(tolerances, scales, options, keywords):
    assert equivalence.setting(equivalence.label("default", tolerances, scales)) == options
    assert equivalence.keywords(options) == keywords
