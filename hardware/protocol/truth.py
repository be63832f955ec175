"""An emulated bench's truth, checkable by a host that is not told it: the marks in its device name.

A bench emulator (never real hardware) names itself ``wearbench emulator BENCH`` and, when it can, adds
``truth J=CCCCCC/WWWWWW ...``: for each clearance joint J a mark of its true radial clearance and one of
its true wear. A mark is the first 6 hex digits of a SHA-256 over the bench's name, the joint and a
canonical value (the clearance in 0.1 um steps; the wear as the SHA-256 of the worn-surface file, or
``new``), so equal marks mean equal values and the name does not tell the value: a host checks what it
is about to claim (``wearbench record --clearance/--wear``) against the emulator's truth, and a session
that keeps the device name does not hand the analysis its answer. The serial emulator sends the name in
its INFO reply (SERIAL.md); the in-process ``sim`` backend puts it in its rig's ``truth`` entry.
Imports nothing of wearbench.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Mapping

__all__ = ["EMULATOR", "MAX_NAME", "announce", "clearance_mark", "is_emulator", "read_marks", "wear_mark"]

EMULATOR = "wearbench emulator"  # how every name an emulator gives begins
MAX_NAME = 200  # bytes of a device name the INFO message carries
_MARKS = re.compile(r" truth((?: [^ =/]+=[0-9a-f]{6}/[0-9a-f]{6})+)$")


def _mark(bench: str, joint: str, what: str, value: str) -> str:
    return hashlib.sha256(f"{bench}\x00{joint}\x00{what}\x00{value}".encode()).hexdigest()[:6]


def clearance_mark(bench: str, joint: str, clearance: float) -> str:
    """The mark of radial clearance ``clearance`` (m) at ``joint`` of bench ``bench`` (0.1 um steps)."""
    return _mark(bench, joint, "clearance", str(round(float(clearance) * 1e7)))


def wear_mark(bench: str, joint: str, digest: str | None) -> str:
    """The mark of the wear at ``joint``: ``digest`` the SHA-256 (hex) of its worn-surface file, None new."""
    return _mark(bench, joint, "wear", digest or "new")


def announce(bench: str, marks: Mapping[str, tuple[str, str]]) -> str:
    """The emulator's device name: ``wearbench emulator BENCH truth J=C/W ...`` (marks by joint, as
    (clearance mark, wear mark)); without the marks when they would not fit the INFO message, or a
    joint's name would not parse back."""
    name = f"{EMULATOR} {bench}"
    marked = name + " truth" + "".join(f" {j}={c}/{w}" for j, (c, w) in marks.items())
    if not marks or len(marked.encode()) > MAX_NAME or read_marks(marked) != dict(marks):
        return name
    return marked


def is_emulator(name: str) -> bool:
    """Whether a device ``name`` is a wearbench emulator's."""
    return name.startswith(EMULATOR + " ")


def read_marks(name: str) -> dict[str, tuple[str, str]] | None:
    """The marks in an emulator's device ``name`` by joint; None when it has none (or is not one)."""
    if not is_emulator(name):
        return None
    found = _MARKS.search(name)
    if found is None:
        return None
    return {j: (c, w) for j, c, w in (re.fullmatch(r"([^=]+)=(\w{6})/(\w{6})", item).groups()
                                      for item in found.group(1).split())}
