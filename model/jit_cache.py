"""Where the model's numba kernels keep their on-disk cache: one directory per model-source digest.

numba's ``cache=True`` checks only the source file of the function it caches, not the functions it
calls from other modules, so after a change in ``contact.py`` a cached ``kernel.py`` kernel could
run the old contact law. Keying the cache directory on :func:`model_source_digest` (every module
of ``wearbench.model``) makes any change to the model's source compile afresh. Imports the
standard library, numba's config and ``digest`` only; must run before any kernel is decorated
(``wearbench.model.__init__`` calls :func:`configure_numba_cache` first).
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from wearbench.model.digest import model_source_digest

__all__ = ["configure_numba_cache", "numba_cache_dir"]

_PREFIX = "numba-"


def numba_cache_dir() -> Path:
    """The cache directory for this model source: ``$NUMBA_CACHE_DIR/wearbench-<digest>`` if the
    user set one, else ``model/__pycache__/numba-<digest>`` if writable, else
    ``$XDG_CACHE_HOME`` (or ``~/.cache``) ``/wearbench/numba-<digest>``."""
    key = _PREFIX + model_source_digest()[:16]
    user = os.environ.get("NUMBA_CACHE_DIR")
    if user:
        return Path(user) / ("wearbench-" + key)
    local = Path(__file__).parent / "__pycache__"
    try:
        local.mkdir(exist_ok=True)
        if os.access(local, os.W_OK):
            return local / key
    except OSError:
        pass
    home = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return home / "wearbench" / key


def configure_numba_cache() -> Path:
    """Point numba's cache at :func:`numba_cache_dir` (for kernels decorated from now on); in the
    package's own ``__pycache__`` also remove the caches of other model sources (and numba's
    unkeyed ones). Returns the directory."""
    from numba.core import config

    path = numba_cache_dir()
    path.mkdir(parents=True, exist_ok=True)
    config.CACHE_DIR = str(path)
    local = Path(__file__).parent / "__pycache__"
    if path.parent == local:
        for old in local.iterdir():
            if old.is_dir() and old.name.startswith(_PREFIX) and old != path:
                shutil.rmtree(old, ignore_errors=True)
            elif old.suffix in (".nbi", ".nbc"):
                old.unlink(missing_ok=True)
    return path
