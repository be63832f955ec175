"""Every test gets its own result cache and no user compute config (tests never share results)."""

from __future__ import annotations

import pytest


@pytest.fixture(autouse=True)
def _isolated_compute(tmp_path, monkeypatch):
    monkeypatch.setenv("WEARBENCH_CACHE", str(tmp_path / "wearbench-cache"))
    monkeypatch.setenv("WEARBENCH_CONFIG", str(tmp_path / "no-user-config.toml"))
    monkeypatch.delenv("WEARBENCH_SCHEDULER", raising=False)
