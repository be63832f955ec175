"""Session file format: message encoding x chunk compression x chunk size, at 20 kHz.

Takes one minute of blocks from the emulator (20 kHz acceleration with noise, 1 kHz encoder, the
sim backend on a stepped clock), then writes them to MCAP (in memory, message indexes on, a chunk
closed every 0.5 s of data as the recorder's flush interval does) once per candidate and measures
the bytes and the CPU time of encoding + writing. Figures are per hour of recording.

Candidates: ``protobuf`` (the session layout, ``acquisition.layout``), ``json`` (the same fields as
JSON numeric arrays, what a JSON-schema layout a viewer can plot would hold), ``json-base64``
(layout 1: base64 float32 inside JSON, which no viewer plots). Prints a table; with ``--json PATH``
also writes it as a result for the documentation (``result_json``, ``docs/results/data/``).

    python -m benchmarks.acquisition.session_format [--seconds 60] [--rate 20kHz] [--json PATH]
"""

from __future__ import annotations

import argparse
import base64
import io
import json
import math
import sys
import time

import numpy as np
from mcap.writer import CompressionType, IndexType, Writer
from wearbench.acquisition.backends import open_rig
from wearbench.acquisition.backends.sim import blocks_from_device
from wearbench.acquisition.drivers import ACCELERATION, Block
from wearbench.acquisition.layout import SCHEMAS, CrankAngle, encode_block
from wearbench.bench.load import parse_bench, shipped_bench
from wearbench.bench.units import parse_quantity

from benchmarks.result_json import Run, column, table, write_result


def capture(rate: float, seconds: float) -> list[Block]:
    path = shipped_bench("ninebar-testbed")
    text = path.read_text().replace('sample_rate = "10 kHz"', f'sample_rate = "{rate:g} Hz"')
    bench = parse_bench(text, path)
    rig = open_rig(bench, "sim", {"speedup": math.inf, "config": {
        "signal": "harmonic", "cache": False, "accelerometer": {"noise": "0.05 m/s^2"}}})
    src, device, out = rig.sources[0], rig.drive.device, []
    try:
        acc = bench.sensor("accelerometer")
        src.configure(acc.range, acc.sample_rate)
        rig.drive.enable()
        rig.drive.set_speed(2 * math.pi, 100.0)
        src.start()
        rig.clock.forget(src)  # this thread steps the clock and reads the device itself
        while rig.clock.now() < seconds + 0.5:
            rig.clock.sleep(0.02)
            out += [b for b in blocks_from_device(device.read(), time.time()) if b.device_time >= 0.5]
    finally:
        rig.close()
    return out


def _json(block: Block, b64: bool) -> bytes:
    head = {"sequence": block.sequence, "device_time": block.device_time, "host_time": block.host_time,
            "sample_rate": block.sample_rate}
    if block.stream == ACCELERATION:
        samples = np.asarray(block.samples, dtype=np.float32)
        body = {"acceleration": base64.b64encode(samples.tobytes()).decode() if b64 else samples.tolist()}
    else:
        counts = np.asarray(block.samples, dtype=np.int32)
        body = {"counts": base64.b64encode(counts.tobytes()).decode() if b64 else counts.tolist(),
                "index_at": np.flatnonzero(block.index).tolist()}
    return json.dumps({**head, **body}, separators=(",", ":")).encode()


ENCODERS = {
    "protobuf": lambda b, crank: encode_block(b, crank),
    "json": lambda b, crank: _json(b, False),
    "json-base64": lambda b, crank: _json(b, True),
}


def write(blocks: list[Block], encoding: str, compression: CompressionType, chunk: int) -> tuple[int, float]:
    """Bytes of the MCAP file and CPU seconds to encode and write ``blocks``."""
    cpu0 = time.process_time()
    buf = io.BytesIO()
    w = Writer(buf, chunk_size=chunk, compression=compression, index_types=IndexType.ALL,
               enable_data_crcs=True)
    w.start(profile="wearbench-session", library="benchmark")
    sid = w.register_schema(SCHEMAS[ACCELERATION][0], "protobuf", SCHEMAS[ACCELERATION][1])
    channels = {s: w.register_channel(f"/{s}", "protobuf", sid) for s in ("acceleration", "encoder")}
    crank, next_flush = CrankAngle(4096), blocks[0].device_time + 0.5
    for b in blocks:
        w.add_message(channels[b.stream], int(b.device_time * 1e9), ENCODERS[encoding](b, crank),
                      int(b.device_time * 1e9), b.sequence & 0xFFFFFFFF)
        if b.device_time >= next_flush:
            w.flush()
            next_flush += 0.5
    w.finish()
    return len(buf.getvalue()), time.process_time() - cpu0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--rate", default="20kHz", help="accelerometer sample rate")
    ap.add_argument("--json", metavar="PATH", help="also write the result as JSON (docs/results/data/ for the docs)")
    args = ap.parse_args()
    run = Run()
    rate = parse_quantity(args.rate, "frequency")
    blocks = capture(rate, args.seconds)
    span = blocks[-1].device_time - blocks[0].device_time
    per_hour = 3600.0 / span
    n_acc = sum(len(b.samples) for b in blocks if b.stream == ACCELERATION)
    print(f"session_format: {n_acc:,} acceleration samples ({rate / 1e3:g} kHz) + encoder at 1 kHz, "
          f"{span:.1f} s of data, {len(blocks):,} blocks; figures per hour of recording")
    print(f"  {'encoding':12s} {'compression':11s} {'chunk':>6s} {'MB/hour':>9s} {'write CPU':>16s}")
    rows = []
    for encoding in ENCODERS:
        for compression in (CompressionType.ZSTD, CompressionType.LZ4, CompressionType.NONE):
            for chunk in (256 << 10, 1 << 20):
                size, cpu = write(blocks, encoding, compression, chunk)
                rows.append((encoding, compression.name.lower(), chunk, size * per_hour / 1e6, cpu / span))
                print(f"  {encoding:12s} {compression.name.lower():11s} {chunk >> 10:5d}K "
                      f"{rows[-1][3]:9.0f} {100 * rows[-1][4]:7.2f} % of a core")
    best = {r[0]: r for r in rows if r[1] == "zstd" and r[2] == 1 << 20}
    pb, js = best["protobuf"], best["json"]
    print(f"protobuf vs JSON arrays (zstd, 1 MiB chunks): {js[3] / pb[3]:.1f}x smaller, "
          f"{js[4] / pb[4]:.1f}x less write CPU")
    if args.json:
        write_json(args.json, rows, rate=rate, span=span, n_acc=n_acc, run=run)
    return 0


def write_json(path: str, rows: list[tuple], *, rate: float, span: float, n_acc: int, run: Run) -> None:
    """The table as a result of the documentation (schema wearbench-result/1)."""
    best = {r[0]: r for r in rows if r[1] == "zstd" and r[2] == 1 << 20}
    pb, js, b64 = best["protobuf"], best["json"], best["json-base64"]
    plain = {r[0]: r for r in rows if r[1] == "none" and r[2] == 1 << 20}
    findings = [
        (f"protobuf with zstd chunks (the session layout) takes {pb[3]:.0f} MB per hour of recording at "
        f"{100 * pb[4]:.2f} % of a core to encode and write, against {js[3]:.0f} MB and {100 * js[4]:.2f} % for "
        f"the same fields as JSON numeric arrays ({js[3] / pb[3]:.2f}x the size, {js[4] / pb[4]:.1f}x the CPU)."),
        (f"Uncompressed, protobuf is {plain['protobuf'][3]:.0f} MB per hour and JSON arrays {plain['json'][3]:.0f} MB: "
        f"zstd shrinks protobuf {plain['protobuf'][3] / pb[3]:.1f}x."),
        f"Layout 1 (base64 float32 inside JSON, which no viewer plots) takes {b64[3]:.0f} MB per hour with zstd.",
    ]
    write_result(
        path, question="How large is a session file per hour, and what does writing it cost?",
        script=__file__, run=run, seeds={"emulator noise (the [emulator] seed, default)": 0},
        findings=findings,
        tables=[table(
            "Size and write cost per hour of recording, by encoding, compression and chunk size",
            [column("encoding"), column("compression"), column("chunk", "KiB", "d"),
             column("size", "MB/h", ".0f", "file size per hour of recording"),
             column("write CPU", "% of a core", ".2f", "encoding and writing, CPU time over the data's span")],
            [(e, c, chunk >> 10, mb, 100 * cpu) for e, c, chunk, mb, cpu in rows],
            description=f"{span:.1f} s of emulated data ({n_acc:,} acceleration samples at {rate / 1e3:g} kHz with "
            "noise, the encoder at 1 kHz; the sim backend on a stepped clock, harmonic test signal), written to an "
            "in-memory MCAP file once per candidate with message indexes and data CRCs on, a chunk closed every "
            "0.5 s of data as the recorder's flush does; figures scaled to one hour.")],
        notes=[("Sizes are exact for this signal; the CPU shares are one run's process time and move with the "
               "machine's load.")])


if __name__ == "__main__":
    sys.exit(main())
