"""One BLAS thread in wearbench's own process (``wearbench.compute.threads``): inside the block every
BLAS numpy and scipy loaded reports one thread, the limits before it come back after it, and the
command line and the public workflows run inside it. Read back from the libraries themselves
(threadpoolctl's ``threadpool_info``), not from our own bookkeeping."""

from __future__ import annotations

import argparse

import pytest
from threadpoolctl import threadpool_info, threadpool_limits
from wearbench.compute.threads import one_blas_thread
from wearbench.validation.workflows.session_set import SessionSet

import wearbench
from wearbench import cli

pytestmark = pytest.mark.no_kernels


def blas_threads() -> dict[str, int]:
    return {pool["filepath"]: pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"}


@pytest.fixture
def two_threads():
    """Two BLAS threads around the test (the suite itself runs on one), when the libraries allow it."""
    with threadpool_limits(limits=2, user_api="blas"):
        if set(blas_threads().values()) != {2}:
            pytest.skip(f"this machine's BLAS would not take two threads: {blas_threads()}")
        yield


def test_inside_the_block_numpy_and_scipy_run_one_thread_and_the_limits_come_back_after(two_threads):
    before = blas_threads()
    with one_blas_thread():
        inside = blas_threads()
    assert len(inside) >= 2, inside  # numpy's and scipy's own OpenBLAS (or one shared BLAS and another)
    assert set(inside.values()) == {1}
    assert blas_threads() == before


def test_a_command_runs_on_one_blas_thread(two_threads, monkeypatch):
    seen = []

    def parser(command: str | None = None) -> argparse.ArgumentParser:
        p = argparse.ArgumentParser()
        p.add_argument("command")
        p.set_defaults(func=lambda args: seen.append(blas_threads()))
        return p

    monkeypatch.setattr(cli, "build_parser", parser)
    assert cli.main(["probe"]) == 0
    assert seen and set(seen[0].values()) == {1}
    assert set(blas_threads().values()) == {2}


def test_the_public_workflows_run_on_one_blas_thread(two_threads, monkeypatch):
    seen = []

    class Stop(Exception):
        pass

    def sessions(*args, **kwargs):
        seen.append(blas_threads())
        raise Stop

    monkeypatch.setattr(SessionSet, "of", sessions)
    with pytest.raises(Stop):
        wearbench.identify(["a.mcap"])
    assert seen and set(seen[0].values()) == {1}
    assert set(blas_threads().values()) == {2}
