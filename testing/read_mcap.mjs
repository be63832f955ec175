// Reads MCAP files the way Foxglove does: @mcap/core's McapIndexedReader over a file readable
// (summary, chunk indexes and message indexes), zstd/lz4 through @mcap/support, and every protobuf
// message decoded with protobufjs from the FileDescriptorSet in the file's schema.
// Usage: node read_mcap.mjs FILE...   Prints one JSON array: per file {path, ok, error?, chunks,
// messageCount, topics: {topic: {messages, schema, encoding, fields: {field: {kind, count, sum}}}}}.
// kind: "number" (a numeric field), "array" (a numeric array: count elements, sum them), "string",
// "bytes", "object", "other". Run by tests/interop/mcap_readers.py from the node cache folder.
import { open } from "node:fs/promises";
import { McapIndexedReader } from "@mcap/core";
import { FileHandleReadable } from "@mcap/nodejs";
import { loadDecompressHandlers } from "@mcap/support";
import protobuf from "protobufjs";
import descriptor from "protobufjs/ext/descriptor/index.js";

const decompressHandlers = await loadDecompressHandlers();

function kindOf(value) {
  if (typeof value === "number" || typeof value === "boolean") return "number";
  if (Array.isArray(value)) return value.every((v) => typeof v === "number") ? "array" : "other";
  if (typeof value === "string") return "string";
  if (value instanceof Uint8Array) return "bytes";
  if (value && typeof value === "object") return "object";
  return "other";
}

function tally(fields, obj) {
  for (const [name, value] of Object.entries(obj)) {
    const kind = kindOf(value);
    const f = (fields[name] ??= { kind, count: 0, sum: 0 });
    if (f.kind !== kind && !(kind === "array" && value.length === 0)) f.kind = "mixed";
    if (kind === "number") {
      f.count += 1;
      f.sum += Number(value);
    } else if (kind === "array") {
      f.count += value.length;
      for (const v of value) f.sum += v;
    } else {
      f.count += 1;
    }
  }
}

async function read(path) {
  const out = { path, ok: false };
  const handle = await open(path, "r");
  try {
    const reader = await McapIndexedReader.Initialize({
      readable: new FileHandleReadable(handle),
      decompressHandlers,
    });
    const types = new Map();
    for (const [id, channel] of reader.channelsById) {
      const schema = reader.schemasById.get(channel.schemaId);
      if (channel.messageEncoding === "protobuf" && schema?.encoding === "protobuf") {
        const root = protobuf.Root.fromDescriptor(descriptor.FileDescriptorSet.decode(schema.data));
        types.set(id, root.lookupType(schema.name));
      }
    }
    const topics = {};
    for await (const message of reader.readMessages()) {
      const channel = reader.channelsById.get(message.channelId);
      const topic = (topics[channel.topic] ??= {
        messages: 0,
        schema: reader.schemasById.get(channel.schemaId)?.name ?? "",
        encoding: channel.messageEncoding,
        fields: {},
      });
      topic.messages += 1;
      const type = types.get(message.channelId);
      if (type) {
        const decoded = type.toObject(type.decode(message.data), {
          longs: Number, enums: Number, bytes: Uint8Array, defaults: true, arrays: true,
        });
        tally(topic.fields, decoded);
      }
    }
    out.chunks = reader.chunkIndexes.length;
    out.messageCount = Number(reader.statistics?.messageCount ?? -1);
    out.topics = topics;
    out.ok = true;
  } catch (error) {
    out.error = String(error?.message ?? error);
  } finally {
    await handle.close();
  }
  return out;
}

const results = [];
for (const path of process.argv.slice(2)) {
  results.push(await read(path));
}
// Run with --single-threaded (mcap_readers.py): node's exit can deadlock on a background compile job
// (nodejs/node#54918), which CI saw as a reader that printed its result and never exited.
process.stdout.write(JSON.stringify(results) + "\n", () => process.exit(0));
