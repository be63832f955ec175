"""Writing a measured latency into a bench file: the accelerometer's ``[sensor.chain] latency`` key,
changed in the file's text so every comment and every other line stays as it was.

The edit is checked before it is kept: the new text, parsed, must equal the old one with only that
key changed. Where the file does not lay the table out as a ``[sensor.chain]`` header under the
accelerometer's ``[[sensor]]`` (an inline table, a dotted key), nothing is written. Imports tomllib and
the output-file policy (:mod:`~wearbench.bench.output_file`) only.
"""

from __future__ import annotations

import copy
import re
import tomllib
from pathlib import Path

from wearbench.bench.output_file import output_file

__all__ = ["ChainEditError", "set_chain_latency", "with_chain_latency"]

_HEADER = re.compile(r"^\s*\[(\[)?\s*([A-Za-z0-9_.\s\"-]+?)\s*\]?\]\s*(#.*)?$")
_LATENCY = re.compile(r"^(\s*latency\s*=\s*)(\"[^\"]*\"|'[^']*'|[-+0-9.eE]+)(.*)$")


class ChainEditError(ValueError):
    """The bench file's text could not be edited safely; the message says why."""


def _accelerometer_index(data: dict) -> int:
    sensors = data.get("sensor", [])
    for i, s in enumerate(sensors):
        if isinstance(s, dict) and s.get("kind") == "accelerometer":
            return i
    raise ChainEditError("no [[sensor]] of kind accelerometer")


def with_chain_latency(text: str, latency_ms: float) -> str:
    """``text`` (a bench file) with its accelerometer's ``[sensor.chain] latency`` set to
    ``latency_ms`` (written as ``"X ms"``, 3 decimals); the line's comment is kept, a missing key is
    added under the header. Raises :class:`ChainEditError` where that cannot be done safely."""
    old = tomllib.loads(text)
    target = _accelerometer_index(old)
    value = f'"{latency_ms:.3f} ms"'
    lines = text.splitlines(keepends=True)
    sensor, table, header_at, done = -1, None, None, False
    for i, line in enumerate(lines):
        m = _HEADER.match(line)
        if m:
            name = re.sub(r"\s+", "", m.group(2))
            if m.group(1) and name == "sensor":
                sensor += 1
            table = name
            if table == "sensor.chain" and sensor == target:
                header_at = i
            continue
        if table == "sensor.chain" and sensor == target and (lm := _LATENCY.match(line.rstrip("\r\n"))):
            end = line[len(line.rstrip("\r\n")):]
            rest = lm.group(3)  # keep a trailing comment where it was: take the longer value out of its padding
            pad = len(rest) - len(rest.lstrip(" "))
            if rest.strip() and pad > 1:
                rest = rest[min(pad - 1, max(0, len(value) - len(lm.group(2)))):]
            lines[i] = f"{lm.group(1)}{value}{rest}{end}"
            done = True
            break
    if not done:
        if header_at is None:
            raise ChainEditError("the accelerometer has no [sensor.chain] table header to write the latency under")
        newline = "\r\n" if lines[header_at].endswith("\r\n") else "\n"
        lines.insert(header_at + 1, f"latency = {value}{newline}")
    new_text = "".join(lines)
    expected = copy.deepcopy(old)
    expected["sensor"][target].setdefault("chain", {})["latency"] = value.strip('"')
    try:
        parsed = tomllib.loads(new_text)
    except tomllib.TOMLDecodeError as exc:
        raise ChainEditError(f"the edited text would not parse ({exc})") from None
    if parsed != expected:
        raise ChainEditError("the edit would change more than the accelerometer's [sensor.chain] latency")
    return new_text


def set_chain_latency(path: str | Path, latency_ms: float) -> None:
    """Set the latency in the bench file at ``path`` in place (:func:`~wearbench.bench.output_file.output_file`:
    a crash or a Ctrl-C leaves the old file or the new one, never half of one, nor a temporary file)."""
    path = Path(path)
    new_text = with_chain_latency(path.read_text(), latency_ms)
    with output_file(path, force=True, option="--write-latency") as tmp:
        tmp.write_text(new_text)
