"""Content addresses of tasks and the result cache they key: equal keys mean the same computation by
the same model code, and a result stored under a key is served instead of computing it again.

Results are pickled under :func:`cache_dir` (``$WEARBENCH_CACHE``, default ``~/.cache/wearbench``),
one file per key, written atomically; a truncated or stale file is a miss. Imports the standard
library, numpy and the model's results digest.
"""

from __future__ import annotations

import contextlib
import dataclasses
import enum
import hashlib
import json
import math
import os
import pickle
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from wearbench.bench.content import cache_folder
from wearbench.model.digest import model_results_digest

__all__ = ["LAYOUT_VERSION", "MISSING", "cache_dir", "cache_load", "cache_store", "cached", "task_key"]

LAYOUT_VERSION = 1  # bump when the cached result layout changes: every key changes with it


def _canonical(x: Any) -> Any:
    """``x`` as plain JSON data that is equal exactly when the inputs are (arrays by digest)."""
    if x is None or isinstance(x, (bool, str, int)):
        return x
    if isinstance(x, float):
        return x if math.isfinite(x) else {"__float__": repr(x)}
    if isinstance(x, np.generic):
        return _canonical(x.item())
    if isinstance(x, np.ndarray):
        a = np.ascontiguousarray(x)
        return {"__ndarray__": hashlib.sha256(a.tobytes()).hexdigest(), "dtype": a.dtype.str,
                "shape": list(a.shape)}
    if isinstance(x, Path):
        return {"__path__": x.as_posix()}
    if isinstance(x, enum.Enum):
        return {"__enum__": f"{type(x).__qualname__}.{x.name}"}
    if isinstance(x, (bytes, bytearray)):
        return {"__bytes__": hashlib.sha256(x).hexdigest()}
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return {"__dataclass__": f"{type(x).__module__}.{type(x).__qualname__}",
                **{f.name: _canonical(getattr(x, f.name)) for f in dataclasses.fields(x)}}
    if isinstance(x, Mapping):
        items = [(_canonical(k), _canonical(v)) for k, v in x.items()]
        if all(isinstance(k, str) for k, _ in items):
            return {"__map__": dict(sorted(items))}
        return {"__map__": sorted(([k, v] for k, v in items), key=lambda kv: json.dumps(kv, sort_keys=True))}
    if isinstance(x, (list, tuple)):
        return [_canonical(v) for v in x]
    if isinstance(x, (set, frozenset)):
        return {"__set__": sorted((_canonical(v) for v in x), key=lambda v: json.dumps(v, sort_keys=True))}
    if callable(x) and hasattr(x, "__qualname__"):
        return {"__callable__": f"{x.__module__}.{x.__qualname__}"}
    raise TypeError(f"task_key: cannot address a {type(x).__name__} ({x!r:.60}); expected numbers, text, "
                    "paths, numpy arrays, dataclasses, mappings or sequences of these")


def task_key(*parts: Any) -> str:
    """SHA-256 (hex) over the canonical JSON of ``parts``, the model's results digest and the cache
    layout version: equal keys mean the same computation by model code with the same outputs."""
    doc = {"layout": LAYOUT_VERSION, "model": model_results_digest(), "parts": [_canonical(p) for p in parts]}
    return hashlib.sha256(json.dumps(doc, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


# ---- the result cache ----------------------------------------------------------------------


def cache_dir() -> Path:
    """``$WEARBENCH_CACHE`` (default ``~/.cache/wearbench``)``/results``."""
    return cache_folder("results")


def _cache_path(key: str) -> Path:
    return cache_dir() / key[:2] / f"{key}.pkl"


MISSING = object()  # what cache_load returns for a key it does not hold


def cached(key: str) -> bool:
    """Whether the result cache holds a result under ``key`` (without reading it)."""
    return _cache_path(key).is_file()


def cache_load(key: str) -> Any:
    path = _cache_path(key)
    try:
        with path.open("rb") as f:
            return pickle.load(f)
    except FileNotFoundError:
        return MISSING
    except Exception:  # noqa: BLE001 - a truncated or stale file is a miss: recomputed and rewritten
        return MISSING


def cache_store(key: str, value: Any) -> None:
    path = _cache_path(key)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{key[:12]}-", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            pickle.dump(value, f, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
