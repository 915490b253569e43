// Reads an autochair MCAP with Foxglove's own reader (@mcap/core) and validates every
// foxglove.* message against Foxglove's published JSON Schemas (@foxglove/schemas) and every
// autochair message against the schema embedded in the file.
// Usage: node check_mcap.js FILE [--stream]   (--stream: McapStreamReader, for unindexed files)
// Prints one JSON object: {indexed, channels: {topic: {schema, count}}, errors: [...]}.
"use strict";
const fs = require("fs");
const { McapIndexedReader, McapStreamReader } = require("@mcap/core");
const foxgloveSchemas = require("@foxglove/schemas/jsonschema");
const Ajv = require("ajv");
const fzstd = require("fzstd");

const decompressHandlers = { zstd: (buf) => fzstd.decompress(buf) };
const ajv = new Ajv({ strict: false, allErrors: true });
const validators = new Map();
const out = { indexed: false, channels: {}, errors: [] };

// JSON has no NaN/inf: the recorder writes them as strings (see autochair.logger.schema).
function finiteOnly(v) {
  if (v === "NaN" || v === "Infinity" || v === "-Infinity") return 0;
  if (Array.isArray(v)) return v.map(finiteOnly);
  if (v && typeof v === "object") {
    const o = {};
    for (const [k, x] of Object.entries(v)) o[k] = finiteOnly(x);
    return o;
  }
  return v;
}

function validatorFor(schema) {
  let v = validators.get(schema.name);
  if (!v) {
    let js;
    if (schema.name.startsWith("foxglove.")) {
      js = foxgloveSchemas[schema.name.slice("foxglove.".length)];
      if (!js) throw new Error(`no published schema ${schema.name}`);
    } else {
      js = JSON.parse(new TextDecoder().decode(schema.data));
    }
    if (schema.encoding !== "jsonschema") out.errors.push(`${schema.name}: encoding ${schema.encoding}`);
    v = ajv.compile(js);
    validators.set(schema.name, v);
  }
  return v;
}

function check(channel, schema, data) {
  if (channel.messageEncoding !== "json") out.errors.push(`${channel.topic}: encoding ${channel.messageEncoding}`);
  const c = (out.channels[channel.topic] ??= { schema: schema ? schema.name : "", count: 0 });
  c.count += 1;
  if (!schema) { out.errors.push(`${channel.topic}: no schema`); return; }
  let msg;
  try {
    msg = JSON.parse(new TextDecoder().decode(data));
  } catch (e) {
    out.errors.push(`${channel.topic}: bad JSON: ${e}`);
    return;
  }
  const validate = validatorFor(schema);
  const value = schema.name.startsWith("foxglove.") ? msg : finiteOnly(msg);
  if (!validate(value) && out.errors.length < 50) {
    out.errors.push(`${channel.topic} (${schema.name}): ${ajv.errorsText(validate.errors)}`);
  }
}

async function readIndexed(path) {
  const fd = fs.openSync(path, "r");
  const readable = {
    size: async () => BigInt(fs.fstatSync(fd).size),
    read: async (offset, size) => {
      const buf = Buffer.alloc(Number(size));
      fs.readSync(fd, buf, 0, Number(size), Number(offset));
      return new Uint8Array(buf.buffer, buf.byteOffset, buf.length);
    },
  };
  const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
  out.indexed = true;
  for await (const m of reader.readMessages()) {
    const channel = reader.channelsById.get(m.channelId);
    check(channel, reader.schemasById.get(channel.schemaId), m.data);
  }
  out.statistics_count = reader.statistics ? Number(reader.statistics.messageCount) : null;
}

function readStream(path) {
  const reader = new McapStreamReader({ decompressHandlers });
  reader.append(new Uint8Array(fs.readFileSync(path)));
  const schemas = new Map();
  const channels = new Map();
  for (let r; (r = reader.nextRecord()); ) {
    if (r.type === "Schema") schemas.set(r.id, r);
    else if (r.type === "Channel") channels.set(r.id, r);
    else if (r.type === "Message") {
      const channel = channels.get(r.channelId);
      check(channel, schemas.get(channel.schemaId), r.data);
    }
  }
  out.complete = reader.done();
}

(async () => {
  const [path, mode] = process.argv.slice(2);
  if (mode === "--stream") readStream(path);
  else await readIndexed(path);
  process.stdout.write(JSON.stringify(out) + "\n");
})().catch((e) => {
  process.stdout.write(JSON.stringify({ ...out, fatal: String(e && e.stack || e) }) + "\n");
  process.exit(1);
});
