"""Content digest of the model package's source, the key that ties cached results to the physics.

Anything computed by the model and kept on disk (emulator signal tables, ensemble realisations,
sweep results) is keyed on :func:`model_results_digest`, so a changed model never replays an old
result: the source digest, unless ``equivalence.toml`` states (and a test checks) that this source
reproduces an earlier one's every output bit for bit. Imports only the standard library.
"""

from __future__ import annotations

import functools
import hashlib
import tomllib
from pathlib import Path

__all__ = ["model_results_digest", "model_source_digest", "package_source_digest", "stated_equivalences"]

EQUIVALENCE_FILE = Path(__file__).with_name("equivalence.toml")


def package_source_digest(folder: Path) -> str:
    """SHA-256 (hex) over the source of every module (``*.py``) in ``folder``, in name order."""
    digest = hashlib.sha256()
    for path in sorted(folder.glob("*.py")):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


@functools.cache
def model_source_digest() -> str:
    """SHA-256 (hex) over the source of every module of ``wearbench.model``: its physics (batches,
    studies and figures live in other packages and do not change it)."""
    return package_source_digest(Path(__file__).parent)


def stated_equivalences(path: Path = EQUIVALENCE_FILE) -> dict[str, dict[str, str]]:
    """``{digest: {"results_of": earlier digest, "commit": the commit holding that source}}`` from
    ``equivalence.toml`` (none if the file is absent)."""
    if not path.exists():
        return {}
    entries = tomllib.loads(path.read_text()).get("equivalent", [])
    out = {}
    for i, e in enumerate(entries):
        if not {"digest", "results_of", "commit"} <= e.keys():
            raise ValueError(f"{path}: [[equivalent]] entry {i + 1} has {sorted(e)}: expected digest, results_of "
                             "and commit")
        out[e["digest"]] = {"results_of": e["results_of"], "commit": e["commit"]}
    return out


def results_digest(source: str, equivalences: dict[str, dict[str, str]]) -> str:
    """The digest whose results ``source`` reproduces: followed back through ``equivalences`` to a
    source with no earlier equivalent (a cycle is an error)."""
    seen = {source}
    while source in equivalences:
        source = equivalences[source]["results_of"]
        if source in seen:
            raise ValueError(f"{EQUIVALENCE_FILE}: the equivalences run in a circle through {source[:12]}")
        seen.add(source)
    return source


@functools.cache
def model_results_digest() -> str:
    """The key of everything the model computes: :func:`model_source_digest`, or the earlier source
    digest whose outputs it reproduces bit for bit (``equivalence.toml``)."""
    return results_digest(model_source_digest(), stated_equivalences())
