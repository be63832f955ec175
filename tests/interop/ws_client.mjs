// A live-view viewer built on @foxglove/ws-protocol's FoxgloveClient (the client library of
// Foxglove Studio before the SDK and of Lichtblick), over the `ws` package's WebSocket.
// Usage: node ws_client.mjs URL SUBPROTOCOL TOPIC COUNT
// Prints one JSON object: {subprotocol, server, topics, messages: [base64 payload, ...]} or {error}.
import wsProtocol from "@foxglove/ws-protocol";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;

const [url, subprotocol, topic, count] = process.argv.slice(2);
const out = { subprotocol: null, server: null, topics: [], messages: [] };
const ws = new WebSocket(url, [subprotocol]);
const client = new FoxgloveClient({ ws });
const timer = setTimeout(() => finish("timed out"), 15000);

function finish(error) {
  clearTimeout(timer);
  if (error) out.error = String(error);
  console.log(JSON.stringify(out));
  client.close();
  process.exit(0);
}

ws.on("open", () => { out.subprotocol = ws.protocol; });
ws.on("unexpected-response", (_req, res) => finish(`HTTP ${res.statusCode}`));
client.on("error", (error) => finish(error?.message ?? error));
client.on("serverInfo", (info) => { out.server = info.name; });
client.on("advertise", (channels) => {
  for (const channel of channels) {
    out.topics.push(channel.topic);
    if (channel.topic === topic) client.subscribe(channel.id);
  }
});
client.on("message", ({ data }) => {
  out.messages.push(Buffer.from(data.buffer, data.byteOffset, data.byteLength).toString("base64"));
  if (out.messages.length >= Number(count)) finish();
});
