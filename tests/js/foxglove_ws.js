// A real Foxglove WebSocket client (@foxglove/ws-protocol over `ws`): subscribes to every
// advertised channel and prints, as JSON, the channels and the first message per topic.
// Usage: node foxglove_ws.js ws://127.0.0.1:PORT TOPIC... (exits when all TOPICs arrived).
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const WebSocket = require("ws");

const [url, ...want] = process.argv.slice(2);
// foxglove-sdk 0.30 servers accept only the foxglove.sdk.v1 subprotocol.
const ws = new WebSocket(url, ["foxglove.sdk.v1", FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
const client = new FoxgloveClient({ ws });
const channels = {};
const bySub = {};
const first = {};
const done = (out) => { console.log(JSON.stringify(out)); process.exit(0); };
setTimeout(() => done({ error: "timeout", channels, first }), 15000);
client.on("error", (e) => done({ error: String(e && e.message || e), channels, first }));
client.on("advertise", (chs) => {
  for (const ch of chs) {
    channels[ch.topic] = { encoding: ch.encoding, schemaName: ch.schemaName };
    bySub[client.subscribe(ch.id)] = ch.topic;
  }
});
client.on("message", ({ subscriptionId, data }) => {
  const topic = bySub[subscriptionId];
  if (!(topic in first)) {
    first[topic] = JSON.parse(new TextDecoder().decode(data));
  }
  if (want.every((t) => t in first)) done({ channels, first });
});
