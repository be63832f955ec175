"""The one output-file policy of every command that writes a file or a folder of files.

- An existing file is never replaced unless the user asked for it (``force``, the ``--force`` option).
- A file that holds an MCAP session is never written over by anything but a session, even with
  ``force``; a session replacing a session (``record --force``, ``recover --force``) says so on stderr.
- What is written goes to a temporary name beside the target and is renamed over it only when
  complete, so a failure (an error, Ctrl-C, a full disk) leaves the old file as it was.

:func:`check_output` refuses before the work starts (one line naming the option, the path and what
to do); :func:`output_file` and :func:`output_folder` are the temporary-name writers, and
:func:`save_npz` the one for a program's own .npz files (numpy, imported when called). Imports the
standard library only.
"""

from __future__ import annotations

import os
import shutil
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["MCAP_MAGIC", "check_output", "holds_session", "output_file", "output_folder", "remove_unfinished",
           "save_npz"]

MCAP_MAGIC = b"\x89MCAP0\r\n"

# the temporary names being written in this process: what a forced exit (os._exit after Ctrl-C, which
# skips every finally) removes, so nothing unfinished is left beside the outputs
_UNFINISHED: set[Path] = set()


def _remove(tmp: Path) -> None:
    if tmp.is_dir():
        shutil.rmtree(tmp, ignore_errors=True)
    else:
        tmp.unlink(missing_ok=True)


def remove_unfinished() -> None:
    """Remove the temporary files and folders this process is still writing (its way out, on a forced
    exit); the finished outputs and the old ones they would replace stay as they are."""
    for tmp in list(_UNFINISHED):
        _remove(tmp)
    _UNFINISHED.clear()


@contextmanager
def _unfinished(tmp: Path) -> Iterator[Path]:
    """``tmp`` is a temporary name for the block: removed when the block ends, however it ends (an
    error, an interrupt; a forced exit through :func:`remove_unfinished`); rename it away inside the
    block to keep what it holds."""
    _UNFINISHED.add(tmp)
    try:
        yield tmp
    finally:
        _UNFINISHED.discard(tmp)
        _remove(tmp)


def holds_session(path: str | Path) -> bool:
    """True if ``path`` is a file that starts like an MCAP file (a recorded session, finished or not)."""
    try:
        with open(path, "rb") as fh:
            return fh.read(len(MCAP_MAGIC)) == MCAP_MAGIC
    except OSError:
        return False


def check_output(path: str | Path, *, force: bool = False, option: str = "--out", session: bool = False,
                 folder: bool = False) -> Path:
    """Refuse to write ``path`` (given as ``option``) where that would destroy something: an existing
    file unless ``force``; a session file unless the output is a ``session`` too (and ``force``); a
    folder where a file is expected and a file where a ``folder`` is expected; with ``folder``, a
    folder that already has files in it unless ``force``. Returns ``path``; raises ``OSError``
    subclasses whose text is the one line the user sees."""
    path = Path(path)
    what = "a folder" if folder else "a session file" if session else "a file"
    if path.is_dir() and not folder:
        raise IsADirectoryError(f"{option} {path}: is a folder; expected {what} name, "
                                f"e.g. {path / ('s.mcap' if session else 'out')}")
    if path.exists() and not path.is_dir() and holds_session(path) and not session:
        raise FileExistsError(f"{option} {path}: holds a recorded MCAP session; wearbench never "
                              f"writes {'a folder' if folder else 'other output'} over a session, even with "
                              "--force: choose another name")
    if folder and path.exists() and not path.is_dir():
        raise FileExistsError(f"{option} {path}: is a file; expected a folder: choose another "
                              "name, or move the file away")
    if folder and path.is_dir() and any(path.iterdir()) and not force:
        raise FileExistsError(f"{option} {path}: a folder with files in it exists; choose another "
                              "name, or pass --force to replace the files this command writes there")
    if not folder and path.exists() and not force:
        raise FileExistsError(f"{option} {path}: a file already exists there; choose another name, "
                              "or pass --force to replace it (the old file is kept until the new one is complete)")
    _check_writable(path, option, folder)
    return path


def _check_writable(path: Path, option: str, folder: bool) -> None:
    """Refuse, before any work, a place the output cannot be written: the nearest existing folder of
    ``path`` (where its temporary name goes) and, for an existing output folder, the folder itself;
    tried by writing a probe file (an unfinished name: a Ctrl-C never leaves it behind), so a read-only
    mount is refused for every user, root included."""
    places = [next(q for q in (path.parent, *path.parent.parents) if q.exists())]
    if folder and path.is_dir():
        places.append(path)
    for place in places:
        probe = place / f".wearbench-probe-{os.getpid()}"
        try:
            with _unfinished(probe):
                probe.touch(exist_ok=False)
        except OSError as exc:
            raise PermissionError(f"{option} {path}: cannot write in {place} ({exc.strerror}); choose another "
                                  "place") from None


def _temporary(path: Path) -> Path:
    """A name beside ``path`` for its unfinished content (same suffix: writers pick the format by it)."""
    return path.with_name(f".{path.stem}.partial-{os.getpid()}{path.suffix}")


def _say_replaced(path: Path) -> None:
    print(f"wearbench: replaced the session {path} (--force)", file=sys.stderr)


def save_npz(path: str | Path, **arrays) -> Path:
    """Write ``arrays`` as a compressed .npz at ``path`` through a temporary name beside it, renamed
    over ``path`` when complete: a failure half way leaves ``path`` as it was and nothing beside it.
    Whether ``path`` may be replaced is the caller's decision (:func:`output_file`)."""
    import numpy as np

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with _unfinished(_temporary(path)) as tmp:
        with open(tmp, "wb") as f:  # a file object: numpy appends ".npz" to a name that lacks it
            np.savez_compressed(f, **arrays)
        os.replace(tmp, path)
    return path


@contextmanager
def output_file(path: str | Path, *, force: bool = False, option: str = "--out",
                session: bool = False) -> Iterator[Path]:
    """Check ``path`` (:func:`check_output`), yield a temporary name beside it to write, and rename it
    over ``path`` when the block ends without an exception; on an exception the temporary file is
    removed and ``path`` is as it was."""
    path = check_output(path, force=force, option=option, session=session)
    path.parent.mkdir(parents=True, exist_ok=True)
    with _unfinished(_temporary(path)) as tmp:
        yield tmp
        check_output(path, force=force, option=option, session=session)  # nothing appeared meanwhile
        replaces_session = holds_session(path)
        os.replace(tmp, path)
    if replaces_session:
        _say_replaced(path)


@contextmanager
def output_folder(path: str | Path, *, force: bool = False, option: str = "--out") -> Iterator[Path]:
    """Like :func:`output_file` for a folder of results: yield a temporary folder beside ``path``; when
    the block ends without an exception, move each file written into ``path`` (replacing files of the
    same name; others there are left alone); on an exception nothing in ``path`` changes."""
    path = check_output(path, force=force, option=option, folder=True)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.partial-{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    with _unfinished(tmp):  # until every file is in place: a forced exit while moving them removes the rest
        yield tmp
        if not path.exists():
            os.replace(tmp, path)
            return
        for src in sorted(tmp.rglob("*")):
            dst = path / src.relative_to(tmp)
            if src.is_dir():
                if dst.exists() and not dst.is_dir():
                    check_output(dst, force=force, option=option, folder=True)
                dst.mkdir(exist_ok=True)
            else:
                check_output(dst, force=force, option=option)
                os.replace(src, dst)
