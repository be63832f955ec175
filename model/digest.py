"""Content digest of the model package's source, the key that ties cached results to the physics.

Anything computed by the model and kept on disk (emulator signal tables, ensemble realisations,
sweep results) is keyed on :func:`model_source_digest`, so a changed model never replays an old
result. Imports only the standard library.
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path

__all__ = ["model_source_digest", "package_source_digest"]


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
