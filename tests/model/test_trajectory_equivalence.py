"""model/equivalence.toml: a stated equivalence is a checked claim, and it keys results as stated.

The slow test extracts the stated commit with git, checks its model digest, and runs
benchmarks/model/trajectory_identity.py against it: every output must be bit for bit the same. The
stated commit's outputs are recorded (``data/trajectory-<digest>.json``: the SHA-256 of every array,
per environment); where a record was made in this environment, this code is compared with it and
the stated commit is not run again.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from wearbench.model.digest import (
    model_results_digest,
    model_source_digest,
    package_source_digest,
    results_digest,
    stated_equivalences,
)

ROOT = Path(__file__).resolve().parents[2]
RECORDS = Path(__file__).with_name("data")
NOT_RECORDED = 3  # trajectory_identity --recorded: no record made in this environment


def _identity(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "benchmarks.model.trajectory_identity", *args, "--revolutions", "1",
                           "--seeds", "1"], cwd=ROOT, check=False, capture_output=True, text=True, timeout=1800)


def test_results_digest_follows_the_stated_chain_and_nothing_else(tmp_path):
    eq = {"c": {"results_of": "b", "commit": "x"}, "b": {"results_of": "a", "commit": "y"}}
    assert results_digest("c", eq) == "a"
    assert results_digest("b", eq) == "a"
    assert results_digest("d", eq) == "d"  # an edited model matches no entry: its own digest
    with pytest.raises(ValueError, match="circle"):
        results_digest("a", {"a": {"results_of": "b", "commit": "x"}, "b": {"results_of": "a", "commit": "y"}})
    bad = tmp_path / "equivalence.toml"
    bad.write_text('[[equivalent]]\ndigest = "c"\nresults_of = "b"\n')
    with pytest.raises(ValueError, match=r"entry 1 has \['digest', 'results_of'\]: expected digest, results_of"):
        stated_equivalences(bad)
    assert stated_equivalences(tmp_path / "absent.toml") == {}


def test_results_are_keyed_on_the_stated_digest():
    stated = stated_equivalences()
    source = model_source_digest()
    expected = stated[source]["results_of"] if source in stated else source
    assert model_results_digest() == results_digest(source, stated) and results_digest(expected, stated) == model_results_digest()


@pytest.mark.slow
@pytest.mark.own_kernels  # the stated commit's model, compiled in its own folder
def test_the_stated_equivalence_holds_bit_for_bit(tmp_path, request):
    """The current source's entry (if any): its commit's model/ has the stated digest, and every
    output of trajectory_identity.py's cases is identical between that commit (run, or its record
    made in this environment) and this code."""
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
    if record.exists():
        assert json.loads(record.read_text())["model"] == entry["results_of"], f"{record} records another model"
        request.getfixturevalue("shared_kernels")  # this code only: its kernels are the run's shared ones
        run = _identity("--recorded", str(record))
        if run.returncode != NOT_RECORDED:
            assert run.returncode == 0 and "IDENTICAL" in run.stdout, run.stdout + run.stderr
            return
    run = _identity("--baseline", str(base))
    assert run.returncode == 0 and "IDENTICAL" in run.stdout, run.stdout + run.stderr


@pytest.mark.slow
def test_a_record_is_used_only_in_its_own_environment_and_a_changed_digest_is_named(tmp_path):
    """A record of other settings is not used (status 3, nothing run); against this environment's
    record, one changed digest and one missing array are found and named in their case."""
    [record] = RECORDS.glob("trajectory-*.json")
    held = json.loads(record.read_text())
    other = tmp_path / "other.json"
    other.write_text(json.dumps({**held, "records": [{**r, "seeds": 5} for r in held["records"]]}))
    run = _identity("--recorded", str(other))
    assert run.returncode == NOT_RECORDED and "no record made in this environment" in run.stdout, run.stdout + run.stderr
    for r in held["records"]:
        r["arrays"]["seed 0 worn|final/q"] = "0" * 64
        del r["arrays"]["kinematics ideal|table/t"]
    changed = tmp_path / "changed.json"
    changed.write_text(json.dumps(held))
    run = _identity("--recorded", str(changed))
    if run.returncode == NOT_RECORDED:
        pytest.skip(f"{record.name} holds no record made in this environment: {run.stdout.strip()}")
    rows = {line.split("  ")[0].strip(): line for line in run.stdout.splitlines()}
    assert run.returncode == 1 and "DIFFERENT: 2 arrays differ" in run.stdout, run.stdout + run.stderr
    assert "final/q (digest differs)" in rows["seed 0 worn"] and "table/t only in this" in rows["kinematics ideal"]
