"""Small scenes for the model tests, written as bench files (the model builds scenes from data only);
the stated equivalence's commit and benchmarks/model/trajectory_identity.py for the equivalence tests."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from wearbench.bench.load import load_bench, parse_bench, shipped_bench
from wearbench.model.digest import model_source_digest, package_source_digest, stated_equivalences

ROOT = Path(__file__).resolve().parents[2]
RECORDS = Path(__file__).with_name("data")

DISC = """
driver = []
[bench]
name = "disc"
[operating]
speed = "0 rad/s"
gravity = ["0 m/s^2", "{g} m/s^2"]
[materials.steel]
youngs_modulus = "206 GPa"
poisson_ratio = 0.3
hardness = "217 MPa"
[contact]
law = "{law}"
restitution = {ce}
friction_coefficient = {cf}
[frame]
points = {{ O = ["0 m", "0 m"] }}
[[body]]
name = "disc"
mass = "1 kg"
inertia = "1e-4 kg*m^2"
points = {{ c = ["0 m", "0 m"] }}
[[joint]]
name = "J"
type = "revolute"
bodies = ["frame", "disc"]
points = ["O", "c"]
[joint.clearance]
bearing_body = "frame"
bearing_radius = "15 mm"
journal_radius = "14.5 mm"
bearing_material = "steel"
journal_material = "steel"
axial_length = "20 mm"
"""

PENDULUM = """
driver = []
[bench]
name = "pendulum"
[operating]
speed = "0 rad/s"
gravity = ["0 m/s^2", "-9.81 m/s^2"]
[frame]
points = { O = ["0 m", "0 m"], T = ["1 m", "1 m"] }
[[body]]
name = "bar"
length = "1 m"
mass = "1 kg"
inertia = "0.0833333333333 kg*m^2"
[[joint]]
name = "O"
type = "revolute"
bodies = ["frame", "bar"]
points = ["O", "start"]
"""


def disc_bench(g: float = 0.0, law: str = "lankarani-nikravesh", ce: float = 1.0, cf: float = 0.0):
    return parse_bench(DISC.format(g=g, law=law, ce=ce, cf=cf))


@pytest.fixture
def pendulum_bench():
    return parse_bench(PENDULUM)


@pytest.fixture(scope="session")
def ninebar():
    return load_bench(shipped_bench("ninebar"))


@pytest.fixture(scope="session")
def slider_crank():
    return load_bench(shipped_bench("slider-crank"))


@pytest.fixture
def identity() -> Callable[..., subprocess.CompletedProcess]:
    """benchmarks/model/trajectory_identity.py with these arguments, at its test size (1 revolution, 1 seed)."""
    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "benchmarks.model.trajectory_identity", *args, "--revolutions",
                               "1", "--seeds", "1"], cwd=ROOT, check=False, capture_output=True, text=True,
                              timeout=1800)
    return run


@pytest.fixture
def stated_commit(tmp_path) -> tuple[dict, Path, Path]:
    """The current model source's entry in model/equivalence.toml, its commit's package extracted
    with git (its model/ checked to have the stated digest), and the file for the record of that
    commit's outputs; skips where there is no entry or no commit to extract."""
    entry = stated_equivalences().get(model_source_digest())
    if entry is None:
        pytest.skip("no equivalence stated for this model source: its results are keyed on its own digest")
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip(f"{ROOT} is not a git checkout: the stated commit {entry['commit'][:12]} cannot be extracted")
    have = subprocess.run(["git", "-C", str(ROOT), "cat-file", "-e", f"{entry['commit']}^{{commit}}"],
                          check=False, capture_output=True)
    if have.returncode != 0:
        pytest.skip(f"commit {entry['commit'][:12]} is not in this clone (shallow?): clone with history to check it")
    base = tmp_path / "base"
    (base / "wearbench").mkdir(parents=True)
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", entry["commit"]], capture_output=True, check=True)
    # the package only: the commit's tests hold deliberately old session files, which this session's
    # check of every *.mcap under the temporary folders would read as ours
    subprocess.run(["tar", "-x", "-C", str(base / "wearbench"), "--exclude=tests", "--exclude=examples"],
                   input=archive.stdout, check=True)
    assert package_source_digest(base / "wearbench" / "model") == entry["results_of"], (
        f"model/equivalence.toml: commit {entry['commit'][:12]}'s model/ does not have digest "
        f"{entry['results_of'][:12]}")
    record = RECORDS / f"trajectory-{entry['results_of'][:16]}.json"
    assert not record.exists() or json.loads(record.read_text())["model"] == entry["results_of"], (
        f"{record} records another model")
    return entry, base, record
