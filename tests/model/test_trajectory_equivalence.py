"""model/equivalence.toml: a stated equivalence is a checked claim, and it keys results as stated.

The slow tests extract the stated commit with git, check its model digest, and run
benchmarks/model/trajectory_identity.py: every output must be bit for bit the same as that commit's.
The commit's outputs are recorded (``data/trajectory-<digest>.json``: the SHA-256 of every array,
per environment); where a record was made in this environment, test_trajectory_record.py compares
this code with it, and the commit is not run here.
"""

from __future__ import annotations

import pytest
from wearbench.model.digest import (
    model_results_digest,
    model_source_digest,
    results_digest,
    stated_equivalences,
)


@pytest.mark.no_kernels
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


@pytest.mark.no_kernels
def test_results_are_keyed_on_the_stated_digest():
    stated = stated_equivalences()
    source = model_source_digest()
    expected = stated[source]["results_of"] if source in stated else source
    assert model_results_digest() == results_digest(source, stated) and results_digest(expected, stated) == model_results_digest()


@pytest.mark.slow
@pytest.mark.own_kernels  # the stated commit's model, compiled in its own folder
def test_the_stated_equivalence_holds_bit_for_bit_against_its_commit(stated_commit, identity):
    """The current source's entry (if any), where no record of its commit's outputs was made in this
    environment: that commit and this code both run the cases, and every output is identical."""
    entry, base, record = stated_commit
    if record.exists() and identity("--has-record", str(record)).returncode == 0:
        pytest.skip(f"{record.name} holds this environment's record of commit {entry['commit'][:12]}'s "
                    "outputs: test_trajectory_record.py compares this code with it")
    run = identity("--baseline", str(base))
    assert run.returncode == 0 and "IDENTICAL" in run.stdout, run.stdout + run.stderr
