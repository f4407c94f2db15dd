// Foxglove's own client against `twin serve` (docs/live-view.md, "Foxglove"): connects to ws://HOST:PORT/ as
// Foxglove does (@foxglove/ws-protocol's FoxgloveClient over the ws package), subscribes to the channels the server
// advertises, and checks what a Foxglove user would see:
//   - the scene channel's schema is Foxglove's own foxglove.SceneUpdate (@foxglove/schemas), and every scene message
//     validates against it (ajv);
//   - the first scene message clears the panel and draws the whole cell: bodies with their primitives;
//   - the robots move: a later message puts a body of a robot named in the frames elsewhere than the first did;
//   - the frame channel carries the live view's frames, their firings counting up (the run goes on);
//   - the server never answers with an error status.
// Usage: node client.mjs PORT [seconds]; prints what it saw; exit 0 when all holds, 1 (saying what failed) otherwise.
import wsProtocol from "@foxglove/ws-protocol"; // CommonJS packages: their exports are the default
import foxgloveSchemas from "@foxglove/schemas/jsonschema.js";
import Ajv from "ajv";
import WebSocket from "ws";
import { isDeepStrictEqual } from "node:util";

const { FoxgloveClient } = wsProtocol;
const { SceneUpdate } = foxgloveSchemas;
const port = Number(process.argv[2]);
const seconds = Number(process.argv[3] ?? 20);
if (!Number.isInteger(port) || port <= 0) {
  console.error("usage: node client.mjs PORT [seconds]");
  process.exit(2);
}

const failures = [];
const fail = (what) => failures.push(what);
const decoder = new TextDecoder();
const ajv = new Ajv({ strict: false, allErrors: true });

const client = new FoxgloveClient({
  ws: new WebSocket(`ws://127.0.0.1:${port}/`, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]),
});
let serverInfo = null;
const channels = new Map(); // subscription id -> channel
let validate = null;
const scenes = [];
const frames = [];
const robots = new Set();

client.on("error", (e) => fail(`client error: ${e?.message ?? e}`));
client.on("serverInfo", (info) => (serverInfo = info));
client.on("status", (s) => {
  if (s.level >= 2) fail(`the server answered with an error status: ${s.message}`);
});
client.on("advertise", (list) => {
  for (const ch of list) {
    if (ch.topic === "/cellwright/scene") {
      if (ch.encoding !== "json" || ch.schemaName !== "foxglove.SceneUpdate" || ch.schemaEncoding !== "jsonschema") {
        fail(`the scene channel is ${ch.encoding} ${ch.schemaName} (${ch.schemaEncoding})`);
      }
      const schema = JSON.parse(ch.schema);
      if (!isDeepStrictEqual(schema, SceneUpdate)) fail("the scene channel's schema is not @foxglove/schemas' SceneUpdate");
      validate = ajv.compile(schema);
    }
    if (ch.topic === "/cellwright/scene" || ch.topic === "/cellwright/frame") {
      channels.set(client.subscribe(ch.id), ch);
    }
  }
});
client.on("message", ({ subscriptionId, timestamp, data }) => {
  const ch = channels.get(subscriptionId);
  if (!ch) return fail(`a message for subscription ${subscriptionId}, which this client never made`);
  let msg;
  try {
    msg = JSON.parse(decoder.decode(data));
  } catch (e) {
    return fail(`${ch.topic}: a message that is not JSON (${e.message})`);
  }
  if (ch.topic === "/cellwright/scene") {
    if (validate && !validate(msg)) {
      fail(`a scene message does not validate against foxglove.SceneUpdate: ${ajv.errorsText(validate.errors)}`);
    }
    scenes.push({ timestamp, msg });
  } else {
    frames.push(msg);
    for (const r of msg.robots ?? []) robots.add(r.name);
  }
});

// The position of each entity's first primitive, by entity id.
function positions(scene) {
  const out = new Map();
  for (const e of scene.entities) {
    const prim = [...e.cubes, ...e.cylinders, ...e.spheres][0];
    if (prim) out.set(e.id, prim.pose.position);
  }
  return out;
}

function robotMoved() {
  if (scenes.length < 2 || robots.size === 0) return null;
  const first = positions(scenes[0].msg);
  for (const s of scenes.slice(1)) {
    for (const [id, p] of positions(s.msg)) {
      const q = first.get(id);
      const robot = [...robots].find((r) => id.startsWith(`body/${r}`));
      if (robot && q && Math.hypot(p.x - q.x, p.y - q.y, p.z - q.z) > 0.01) return { id, robot };
    }
  }
  return null;
}

const deadline = Date.now() + seconds * 1000;
const firingsRose = () => frames.length >= 2 && frames[frames.length - 1].firings > frames[0].firings;
while (Date.now() < deadline && !(robotMoved() && firingsRose() && failures.length === 0)) {
  if (failures.length) break;
  await new Promise((r) => setTimeout(r, 50));
}
client.close();

if (!serverInfo) fail("no serverInfo");
if (scenes.length === 0) {
  fail("no message on /cellwright/scene");
} else {
  const base = scenes[0].msg;
  if (!base.deletions.some((d) => d.type === 1)) fail("the first scene message does not clear the scene (deletion ALL)");
  const bodies = base.entities.filter((e) => e.id.startsWith("body/"));
  const prims = bodies.reduce((n, e) => n + e.cubes.length + e.cylinders.length + e.spheres.length, 0);
  if (bodies.length < 5 || prims < 10) fail(`the first scene has ${bodies.length} bodies, ${prims} primitives`);
  if (!base.entities.every((e) => e.frame_id === "world")) fail("an entity not in the frame 'world'");
  console.log(`scene: ${scenes.length} messages, the first with ${bodies.length} bodies and ${prims} primitives`);
}
const moved = robotMoved();
if (!moved) fail(`no body of a robot (${[...robots].join(", ") || "none named in the frames"}) moved`);
else console.log(`robot ${moved.robot} moved: ${moved.id}`);
if (frames.length < 2) fail(`${frames.length} frames on /cellwright/frame`);
else {
  if (!frames.every((f) => f.type === "frame")) fail("a message on /cellwright/frame that is not a frame");
  const firings = frames.map((f) => f.firings);
  if (firings.some((n, i) => i > 0 && n < firings[i - 1])) fail(`firings went down: ${firings.join(" ")}`);
  if (!firingsRose()) fail(`the frames' firings never rose (${firings[0]} .. ${firings[firings.length - 1]})`);
  console.log(`frames: ${frames.length}, firings ${firings[0]} .. ${firings[firings.length - 1]}`);
}
if (failures.length) {
  for (const f of failures) console.error(`FAIL: ${f}`);
  process.exit(1);
}
console.log(`OK: ${serverInfo.name} speaks to Foxglove's client`);
process.exit(0);
