"""Assertions a lab writes again otherwise: the file is a valid MCAP other tools open, no sample was
lost between the device and the file, the session identifies as the state it should.

Each raises ``AssertionError`` with a message naming the file and what differs. Imports the
acquisition and validation layers and :mod:`wearbench.testing.mcap_readers`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from wearbench.acquisition.session_file import Session, read_session
from wearbench.compute.options import QUIET
from wearbench.testing import mcap_readers
from wearbench.testing.recording import (
    STREAMS,
    RecordedSession,
    Sent,
    assert_same_blocks,
    recorded_blocks,
)

__all__ = ["assert_identifies", "assert_no_sample_lost", "assert_valid_mcap", "event_time"]


def _path(recorded: RecordedSession | Session | str | Path) -> Path:
    return Path(recorded.path if isinstance(recorded, (RecordedSession, Session)) else recorded)


def assert_valid_mcap(recorded: RecordedSession | Session | str | Path, *, node: bool | None = None) -> None:
    """The file is a finished MCAP that the Python ``mcap`` readers open with every CRC checked,
    whose log times never go back (``mcap doctor --strict-message-order``), and that @mcap/core's
    indexed reader (what Foxglove opens files with) reads with the same messages per topic.

    ``node``: True requires Node.js (the npm packages are installed once into
    ``$WEARBENCH_CACHE/node``), False checks with Python only, None (default) uses node when it is
    on PATH.
    """
    path = _path(recorded)
    assert mcap_readers.is_finished_mcap(path), f"{path}: not a finished MCAP file (no footer magic)"
    folder = None
    if node is not False:
        try:
            folder = mcap_readers.install()
        except mcap_readers.NodeMissing:
            if node:
                raise
    problems = mcap_readers.check([path], folder)
    assert not problems, "\n".join(problems)


def event_time(recorded: RecordedSession | Session, kind: str) -> float | None:
    """Device time (s) of the first event of ``kind`` in the session (e.g. "stall", "disconnect"),
    or None when there is none."""
    s = recorded.session if isinstance(recorded, RecordedSession) else recorded
    hits = s.events[s.events.kind == kind]
    return None if hits.empty else float(hits.time.iloc[0] + s.origin)


def assert_no_sample_lost(recorded: RecordedSession | Session | str | Path, sent: Sent | None = None, *,
                          until: float | None = None, min_blocks: int = 1) -> dict[str, int]:
    """No sample was lost between the device and the file.

    With ``sent`` (what the emulator sent, :meth:`EmulatedBench.sent`): every recorded block is
    bit for bit the block sent with its sequence number, and every block sent from the first one
    recorded up to device time ``until`` (s; default: the last block recorded) is in the file,
    so a fault at ``until`` kept every sample before it. Without ``sent`` (real hardware): the
    sequence numbers of each stream have no gap and the file's quality record counts no drop.
    Returns the blocks recorded per stream.
    """
    path = _path(recorded)
    rec = recorded_blocks(path)
    if sent is not None:
        counts = assert_same_blocks(path, sent, min_blocks=min_blocks)
        if until is not None:
            for stream in STREAMS:
                first = min(rec[stream])
                due = [s for s, (t, *_rest) in sent[stream].items() if s >= first and t <= until]
                missing = sorted(set(due) - set(rec[stream]))
                assert not missing, (f"{path}: {stream}: {len(missing)} blocks sent before t = {until:.6g} s and "
                                     f"not recorded (first: {missing[:5]})")
        return counts
    session = read_session(path)
    counts = {}
    for stream in STREAMS:
        seqs = sorted(rec[stream])
        assert len(seqs) >= min_blocks, f"{path}: {stream}: only {len(seqs)} blocks recorded"
        gaps = np.flatnonzero(np.diff(seqs) != 1)
        assert not len(gaps), (f"{path}: {stream}: sequence numbers jump after "
                               f"{[seqs[i] for i in gaps[:5]]} (blocks lost)")
        assert session.quality[stream]["dropped"] == 0, f"{path}: {stream}: {session.quality[stream]}"
        counts[stream] = len(seqs)
    return counts


def assert_identifies(recorded: RecordedSession | Session | str | Path, state: str, *, p_min: float = 0.9,
                      candidates: str | Path | Sequence[Any] | None = None,
                      ensembles: Mapping[str, Any] | None = None, **assess: Any):
    """The session identifies as candidate ``state`` with posterior probability >= ``p_min``.

    ``candidates``: a ``[[state]]`` TOML file or ``WearState``s (default: the states of the bench
    recorded in the session); ``ensembles`` ({state: Ensemble}) skips building them; other keywords
    go to :func:`wearbench.validation.workflows.assess.assess_sessions`. Returns the ``Identification``.
    """
    from wearbench.validation.workflows.assess import assess_sessions

    path = _path(recorded)
    (assessed,) = assess_sessions([path], candidates=candidates, ensembles=ensembles, compute=QUIET, **assess)
    r = assessed.identification
    p = r.posterior.get(state)
    assert p is not None, f"{path}: {state!r} is not a candidate state: {sorted(r.posterior)}"
    ranked = ", ".join(f"{k} {v:.3f}" for k, v in sorted(r.posterior.items(), key=lambda kv: -kv[1]))
    assert p >= p_min, f"{path}: identifies as {state!r} with p {p:.3f} < {p_min} (verdict {r.verdict!r}; {ranked})"
    return r
