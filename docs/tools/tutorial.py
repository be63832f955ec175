"""Run a documentation page's own command blocks, in order, in one folder.

The tutorial (``docs/tutorial/first-week.md``) is executable: ``tests/docs/test_tutorial.py`` and
``docs/tools/make_figures.py`` take its blocks from the page itself, so editing the page changes
what runs. Two kinds of fenced block count:

- a ``sh`` block is a shell script, run with ``bash -euo pipefail`` in the working folder;
- a ``python`` block is a Python script, run with this Python in the working folder (the how-to
  ``docs/how-to/python.md`` runs after the tutorial, on its sessions);
- a ``{code-block}`` with a ``:caption:`` that is a file name is written to that file first
  (the tutorial's emulator settings, ``wednesday.json``).

Every other block (``text`` output, ``toml`` excerpts) is shown, not run. Imports the standard
library only.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

FENCE = re.compile(r"^(?P<fence>`{3,}|~{3,})(?P<info>[^\n]*)\n(?P<body>.*?)^(?P=fence)[ \t]*$", re.MULTILINE | re.DOTALL)
OPTION = re.compile(r"^:(?P<key>[\w-]+):[ \t]*(?P<value>.*)$")
WRITES = ("--out", "--json", "--figure")  # options whose value is a file or folder the command writes


@dataclass(frozen=True)
class Block:
    kind: str  # "sh" or "python" (a script to run), or "file" (written to ``name``)
    text: str
    line: int  # where the block starts on the page (1-based)
    name: str = ""

    def writes(self) -> list[str]:
        """What the commands of an ``sh`` block name with --out, --json or --figure."""
        if self.kind != "sh":
            return []
        words = shlex.split(self.text.replace("\\\n", " "), comments=True)
        return [words[i + 1] for i, w in enumerate(words[:-1]) if w in WRITES]


def blocks(page: str | Path) -> list[Block]:
    """The runnable blocks of ``page``, in order."""
    text = Path(page).read_text(encoding="utf-8")
    out = []
    for m in FENCE.finditer(text):
        info, body = m["info"].strip(), m["body"]
        line = text.count("\n", 0, m.start()) + 1
        if info in ("sh", "python"):
            out.append(Block(info, body, line))
        elif info.startswith("{code-block}"):
            options, rest = {}, []
            for row in body.splitlines(keepends=True):
                hit = OPTION.match(row.strip()) if not rest else None
                if hit:
                    options[hit["key"]] = hit["value"].strip()
                else:
                    rest.append(row)
            name = options.get("caption", "")
            if name and re.fullmatch(r"[\w.-]+", name):
                out.append(Block("file", "".join(rest).lstrip("\n"), line, name))
    return out


@dataclass(frozen=True)
class Ran:
    block: Block
    seconds: float
    stdout: str
    stderr: str


class BlockFailed(AssertionError):
    pass


def run(page: str | Path, folder: str | Path, *, timeout: float = 1800, env: dict | None = None,
        echo: bool = False) -> list[Ran]:
    """Run the blocks of ``page`` in ``folder`` (files written, scripts run); raises
    :class:`BlockFailed` naming the block and its output when one exits non-zero. The ``wearbench``
    on PATH is the one of this Python (``sys.executable``'s folder comes first)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ if env is None else env)
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    done = []
    for block in blocks(page):
        if block.kind == "file":
            (folder / block.name).write_text(block.text, encoding="utf-8")
            done.append(Ran(block, 0.0, "", ""))
            continue
        if echo:
            print(f"--- {Path(page).name}:{block.line}\n{block.text}", end="", flush=True)
        start = time.monotonic()
        command = ["bash", "-euo", "pipefail", "-c"] if block.kind == "sh" else [sys.executable, "-c"]
        p = subprocess.run([*command, block.text], cwd=folder, env=env, capture_output=True, text=True,
                           timeout=timeout, check=False)
        ran = Ran(block, time.monotonic() - start, p.stdout, p.stderr)
        if echo:
            print(f"    ({ran.seconds:.0f} s, exit {p.returncode})", flush=True)
        if p.returncode != 0:
            raise BlockFailed(f"{Path(page).name}, block at line {block.line} exited {p.returncode}:\n{block.text}\n"
                              f"--- stdout (end)\n{p.stdout[-3000:]}\n--- stderr (end)\n{p.stderr[-3000:]}")
        done.append(ran)
    return done


if __name__ == "__main__":  # python docs/tools/tutorial.py PAGE FOLDER: run a page by hand
    run(sys.argv[1], sys.argv[2], echo=True)
