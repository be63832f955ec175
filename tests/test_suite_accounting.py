"""The suite's own accounting (``tests/conftest.py``): each test's CPU goes into the JUnit XML beside
its time, its own and that of the processes it waited for, and not the time it waited."""

from __future__ import annotations

import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from .conftest import KERNELS_READY

pytestmark = pytest.mark.no_kernels

SPIN = "import time\nend = time.process_time() + 0.3\nwhile time.process_time() < end:\n    pass\n"


def test_a_tests_cpu_is_recorded_beside_its_time(tmp_path):
    (tmp_path / "test_spin.py").write_text(
        "import subprocess, sys, time\n\n\n"
        "def test_spin_in_a_child_spin_here_then_sleep():\n"
        f"    subprocess.run([sys.executable, '-c', {SPIN!r}], check=True)\n"
        + "".join(f"    {line}\n" for line in SPIN.splitlines())
        + "    time.sleep(0.5)\n")
    junit = tmp_path / "junit.xml"
    tests = str(Path(__file__).parent)  # tests/conftest.py as the plugin "conftest"
    env = {k: v for k, v in os.environ.items() if k != KERNELS_READY}  # not the run's shared compile
    env["PYTHONPATH"] = os.pathsep.join([tests, os.environ.get("PYTHONPATH", "")])
    # no BLAS thread team started at import: on idle cores its threads spin beside the test's own CPU
    # (about 0.1 s, in the setup's import of numpy and threadpoolctl), which no wall time holds
    env.update(OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "conftest",
                          f"--junitxml={junit}", "test_spin.py"], check=False, cwd=tmp_path, capture_output=True,
                         text=True, env=env)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    [case] = ET.parse(junit).getroot().iter("testcase")
    [cpu] = [float(p.get("value")) for p in case.iter("property") if p.get("name") == "cpu"]
    assert 0.6 <= cpu <= float(case.get("time")) - 0.4, (cpu, case.get("time"))  # both spins, not the sleep
