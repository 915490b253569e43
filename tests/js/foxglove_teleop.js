// Foxglove's Teleop panel, scripted with a real Foxglove WebSocket client (@foxglove/ws-protocol):
// advertises a JSON geometry_msgs/Twist channel and, while a "button" is held, publishes at a
// fixed rate (once at the press, then every 1/rate s, nothing on release), as the panel does.
// Usage: node foxglove_teleop.js URL TOPIC RATE_HZ SCHEDULE
//   SCHEDULE: JSON list of phases, {"hold": s, "v": m/s, "w": rad/s} or {"idle": s}.
// Prints JSON: the server's info and, per hold, the Unix times (ms) of its first and last
// message and their count; then exits.
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const WebSocket = require("ws");

const [url, topic, rateArg, scheduleArg] = process.argv.slice(2);
const rate = Number(rateArg);
const schedule = JSON.parse(scheduleArg);
const nowMs = () => performance.timeOrigin + performance.now();
const out = { serverInfo: null, holds: [] };
let finished = false;
const done = (extra) => {
  if (finished) return;
  finished = true;
  console.log(JSON.stringify({ ...out, ...extra }));
  ws.close(); // a clean close: the server sees the client go, not a reset
  setTimeout(() => process.exit(0), 100);
};
setTimeout(() => done({ error: "timeout" }), 60000);

// foxglove-sdk 0.30 servers accept only the foxglove.sdk.v1 subprotocol.
const ws = new WebSocket(url, ["foxglove.sdk.v1", FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
const client = new FoxgloveClient({ ws });
client.on("error", (e) => done({ error: String((e && e.message) || e) }));
client.on("close", () => {
  if (finished) process.exit(0);
  done({ error: "closed by the server" });
});

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

async function hold(channel, seconds, v, w) {
  const data = new TextEncoder().encode(JSON.stringify({
    linear: { x: v, y: 0, z: 0 }, angular: { x: 0, y: 0, z: w } }));
  const rec = { first: null, last: null, n: 0 };
  const send = () => {
    client.sendMessage(channel, data);
    rec.last = nowMs();
    if (rec.first === null) rec.first = rec.last;
    rec.n += 1;
  };
  const end = nowMs() + seconds * 1000;
  send(); // the panel publishes at the press ...
  await new Promise((resolve) => {
    const timer = setInterval(() => { // ... then at its rate while the button is held
      if (nowMs() + 1000 / rate > end) {
        clearInterval(timer);
        resolve();
        return;
      }
      send();
    }, 1000 / rate);
  });
  out.holds.push(rec);
}

client.on("serverInfo", async (info) => {
  out.serverInfo = info;
  if (!info.capabilities.includes("clientPublish")) {
    done({ error: "the server does not accept client publishing" });
    return;
  }
  const channel = client.advertise({ topic, encoding: "json", schemaName: "geometry_msgs/Twist" });
  for (const phase of schedule) {
    if ("hold" in phase) await hold(channel, phase.hold, phase.v || 0, phase.w || 0);
    else await sleep(phase.idle * 1000);
  }
  done({});
});
