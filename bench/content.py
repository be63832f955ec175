"""What a bench *is* for a result: the one content key and the one file digest.

Every cache of computed physics (ensembles, emulator tables, study and sweep tasks) keys a bench on
:func:`bench_key`: everything the model's motion depends on, and the tolerances its draws come from;
not the bench's name, file, text, description, hardware, emulator, compute or analysis settings, the motor's
limits or what a sensor records (range, sensitivity, rate, the stated chain). Files (worn surfaces) count by the
SHA-256 of what they hold, floats exactly.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from wearbench.bench.schema import Bench

__all__ = ["NOT_PHYSICS", "bench_key", "cache_folder", "canonical", "file_digest"]


def cache_folder(kind: str) -> Path:
    """Where one kind of cached content lives: ``$WEARBENCH_CACHE/kind`` (default ``~/.cache/wearbench``)."""
    return Path(os.environ.get("WEARBENCH_CACHE") or Path.home() / ".cache" / "wearbench") / kind

# fields of the bench's dataclasses left out of its content (see the module docstring)
NOT_PHYSICS = frozenset({"name", "path", "source", "sha256", "description", "emulator", "hardware", "states",
                         "motor", "tolerances", "scheduler", "analysis", "range", "sensitivity", "sample_rate", "chain"})


def file_digest(path: str | Path) -> str:
    """SHA-256 (hex) of the bytes of the file at ``path``."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def canonical(x: Any) -> Any:
    """A JSON-able canonical form of ``x``: dataclasses by field (minus :data:`NOT_PHYSICS`), floats
    exactly (hex), files by the SHA-256 of what they hold, arrays by their bytes."""
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return {f.name: canonical(getattr(x, f.name)) for f in dataclasses.fields(x) if f.name not in NOT_PHYSICS}
    if isinstance(x, Mapping):
        return {str(k): canonical(v) for k, v in sorted(x.items(), key=lambda kv: str(kv[0]))}
    if isinstance(x, (list, tuple)):
        return [canonical(v) for v in x]
    if isinstance(x, bool) or x is None or isinstance(x, (str, int)):
        return x
    if isinstance(x, float):
        return float(x).hex()
    if isinstance(x, Path):
        return {"sha256": file_digest(x)}
    if isinstance(x, np.ndarray):
        return {"array": hashlib.sha256(np.ascontiguousarray(x).tobytes()).hexdigest(), "shape": list(x.shape)}
    raise TypeError(f"bench content: cannot key a {type(x).__name__}")


def bench_key(bench: Bench) -> str:
    """SHA-256 (hex) of the content of ``bench`` that physics depends on, and of its tolerances."""
    content = {"bench": canonical(bench), "tolerances": canonical(dataclasses.asdict(bench.tolerances))}
    return hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()
