"""numba cache safety: a cached kernel recompiles when a function it calls in another module changes.

numba's own ``cache=True`` keys a kernel on its own file only; ``wearbench.model.jit_cache`` keys the
cache directory on the digest of the whole model package. The check runs a copy of the package in
subprocesses: compile and cache, edit the callee (``surface_tables.depth_eval``, called by
``worn_contact.worn_contact``), run again and see the new physics.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import wearbench.model as model_pkg

PROBE = r"""
import json, sys
sys.meta_path = [f for f in sys.meta_path if "editable" not in repr(f).lower()]
sys.path.insert(0, sys.argv[1])
import numpy as np
import wearbench.model
from numba.core import config
from wearbench.model.worn_contact import worn_contact
assert wearbench.model.__file__.startswith(sys.argv[1]), wearbench.model.__file__
depths = np.full(100, 1e-5)  # uniform wear 10 um on the bearing, new journal
psi, f, hb, hj, sb, sj = worn_contact(depths, 100, np.zeros(100), 100, 7e-4, 0.3, 0.0, 0.0, 6e-4)
print(json.dumps({"overlap": f, "hb": hb, "cache": config.CACHE_DIR,
                  "loaded": sorted(str(k) for k in worn_contact.stats.cache_hits)}))
"""


def _run(root: Path) -> dict:
    # the copy caches in its own __pycache__ (where stale caches are removed), whatever NUMBA_CACHE_DIR says
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    out = subprocess.run([sys.executable, "-c", PROBE, str(root)], capture_output=True, text=True, timeout=300,
                         check=False, env=env)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.slow
@pytest.mark.own_kernels  # a copy of the model, compiled in the copy's __pycache__
def test_editing_a_callee_recompiles_the_cached_kernel(tmp_path):
    src = Path(model_pkg.__file__).parent
    import wearbench.bench as bench_pkg

    pkg = tmp_path / "wearbench"
    shutil.copytree(src, pkg / "model", ignore=shutil.ignore_patterns("__pycache__"))
    # a regular package: the checkout's own wearbench/ (the cwd, first on a `python -c` path) would win over a
    # namespace portion and hide the copy
    (pkg / "__init__.py").write_text("")
    # the model stands on the bench layer only (tests/test_architecture.py)
    shutil.copytree(Path(bench_pkg.__file__).parent, pkg / "bench", ignore=shutil.ignore_patterns("__pycache__"))
    first = _run(tmp_path)
    assert first["hb"] == pytest.approx(1e-5, rel=1e-12)
    assert first["overlap"] == pytest.approx(7e-4 - 1e-5, rel=1e-12)
    again = _run(tmp_path)
    assert again["cache"] == first["cache"] and again["loaded"], "second run should load the cached kernel"
    # the callee doubles every depth: a kernel cached on its own file alone would still see 10 um
    callee = pkg / "model" / "surface_tables.py"
    text = callee.read_text()
    edited = text.replace("    return h, dh * scale, d2h * scale * scale",
                          "    return 2.0 * h, 2.0 * dh * scale, 2.0 * d2h * scale * scale")
    assert edited != text
    callee.write_text(edited)
    after = _run(tmp_path)
    assert after["cache"] != first["cache"]
    assert after["hb"] == pytest.approx(2e-5, rel=1e-12)
    assert after["overlap"] == pytest.approx(7e-4 - 2e-5, rel=1e-12)
    assert not Path(first["cache"]).exists(), "the stale cache is removed"
