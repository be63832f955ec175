"""The stated equivalence (model/equivalence.toml) against the record of its commit's outputs made
in this environment (``data/trajectory-<digest>.json``), and the record's own rules: a record of
another environment or other settings is not used, and a changed digest is found and named."""

from __future__ import annotations

import json

import pytest

NOT_RECORDED = 3  # trajectory_identity --recorded: no record made in this environment


@pytest.mark.slow
def test_the_stated_equivalence_holds_bit_for_bit_against_the_record_of_its_commit(stated_commit, identity):
    """The current source's entry (if any): its commit's model/ has the stated digest, and every
    output of trajectory_identity.py's cases is identical between the record of that commit's outputs
    made in this environment and this code (where there is none, test_trajectory_equivalence.py runs
    the commit)."""
    entry, _, record = stated_commit
    if not record.exists():
        pytest.skip(f"no record of commit {entry['commit'][:12]}'s outputs: test_trajectory_equivalence.py runs it")
    run = identity("--recorded", str(record))
    if run.returncode == NOT_RECORDED:
        pytest.skip(f"{run.stdout.strip()}: test_trajectory_equivalence.py runs commit {entry['commit'][:12]}")
    assert run.returncode == 0 and "IDENTICAL" in run.stdout, run.stdout + run.stderr


@pytest.mark.slow
def test_a_record_is_used_only_in_its_own_environment_and_a_changed_digest_is_named(tmp_path, stated_commit,
                                                                                    identity):
    """A record of other settings is not used (status 3, nothing run); against this environment's
    record, one changed digest and one missing array are found and named in their case."""
    entry, _, record = stated_commit
    if not record.exists():
        pytest.skip(f"no record of commit {entry['commit'][:12]}'s outputs")
    held = json.loads(record.read_text())
    other = tmp_path / "other.json"
    other.write_text(json.dumps({**held, "records": [{**r, "seeds": 5} for r in held["records"]]}))
    run = identity("--recorded", str(other))
    assert run.returncode == NOT_RECORDED and "no record made in this environment" in run.stdout, run.stdout + run.stderr
    for r in held["records"]:
        r["arrays"]["seed 0 worn|final/q"] = "0" * 64
        del r["arrays"]["kinematics ideal|table/t"]
    changed = tmp_path / "changed.json"
    changed.write_text(json.dumps(held))
    run = identity("--recorded", str(changed))
    if run.returncode == NOT_RECORDED:
        pytest.skip(f"{record.name} holds no record made in this environment: {run.stdout.strip()}")
    rows = {line.split("  ")[0].strip(): line for line in run.stdout.splitlines()}
    assert run.returncode == 1 and "DIFFERENT: 2 arrays differ" in run.stdout, run.stdout + run.stderr
    assert "final/q (digest differs)" in rows["seed 0 worn"] and "table/t only in this" in rows["kinematics ideal"]
