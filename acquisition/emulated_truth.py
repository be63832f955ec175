"""What a session's labels claim against what an emulated bench is (``wearbench record --clearance/--wear``).

On a real bench the labels are the lab's word: nothing checks them. An emulated bench has a truth, and
a session labelled with anything else records one state under the name of another. The emulators tell
a host the marks of their truth in their device name (``hardware/protocol/truth.py``; the serial
emulator in its INFO reply, the ``sim`` backend in its rig's ``truth`` entry): :func:`check_labels`
compares the labels with them, so ``record`` refuses labels an emulator does not play. (The ``sim``
backend's truth can be set from the labels before it starts: ``wearbench record`` does that; see
``cli/record.py``.) CAN emulators run in the host's own process on the python-can ``virtual`` bus and
carry no name; their truth is what the code that built them gave them.
Imports the bench content digests, the protocol's truth marks and the drivers' Rig.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from wearbench.acquisition.drivers import Rig
from wearbench.bench.content import file_digest
from wearbench.bench.schema import Bench
from wearbench.hardware.protocol.truth import clearance_mark, is_emulator, read_marks, wear_mark

__all__ = ["check_labels", "emulator_name"]


def emulator_name(rig: Rig) -> str | None:
    """The emulator's name (with its truth marks, if it gives them) of ``rig``; None for a device that is
    not a wearbench emulator."""
    return next((rig.info[k] for k in ("truth", "device") if is_emulator(rig.info.get(k, ""))), None)


def check_labels(rig: Rig, bench: Bench, clearances: Mapping[str, float],
                 wear: Mapping[str, Path | None]) -> str | None:
    """Check a session's labels (radial clearances m and worn-surface files, None for new, by joint)
    against the truth of the emulated bench behind ``rig``.

    Returns None when there is nothing to check (no labels, or a device that is no emulator), else the
    sentence saying they agree. Raises ValueError, one line naming the option, joint and value, when a
    label disagrees with the emulator's truth, or when the emulator does not give its marks."""
    name = emulator_name(rig)
    if name is None or not (clearances or wear):
        return None
    where = f"the emulated bench behind the {rig.backend} backend ({name.split(' truth ')[0]})"
    marks = read_marks(name)
    if marks is None:
        raise ValueError(f"--clearance/--wear: refused: {where} does not give the marks of its truth (a bench whose "
                         "joint names do not fit its device name), so the labels cannot be checked; record without "
                         "them")
    claims = [("--clearance", j, f"{c * 1e3:g}mm", "clearance", 0, clearance_mark(bench.name, j, c))
              for j, c in clearances.items()]
    claims += [("--wear", j, "new" if w is None else str(w), "wear", 1,
                wear_mark(bench.name, j, None if w is None else file_digest(w))) for j, w in wear.items()]
    for option, joint, value, what, i, mark in claims:
        if joint not in marks or marks[joint][i] != mark:
            raise ValueError(f"{option} {joint}={value}: refused: {where} has another {what} at {joint}; an "
                             "emulator's truth is set where it runs ('wearbench emulate BENCH --serial --state "
                             "NAME', or its [emulator.truth]) and a host cannot change it, as it cannot wear a real "
                             f"bench: record without {option}, or start the emulator in the state you label")
    return f"--clearance/--wear agree with the truth of {where} (checked by its marks)"
