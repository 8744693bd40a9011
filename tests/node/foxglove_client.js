// A test peer: Foxglove's own ws-protocol client (`FoxgloveClient`, the subprotocol it names,
// foxglove.websocket.v1) over the `ws` package's WebSocket. It subscribes to the topics named on
// its command line as they are advertised and prints what it receives as JSON lines on stdout,
// payloads in base64, for the Python test to decode. It publishes as its stdin's JSON lines say
// (client publishing, with the client's own `advertise` and `sendMessage`):
//   {"op": "advertise", "name": ..., "topic": ..., "encoding": "json" | "cdr", "schemaName": ...}
//     advertises a client channel known by `name` (the topic unless given), printed back as
//     {"event": "advertised", "name", "id"};
//   {"op": "publish", "name": ..., "data": <base64>}  sends one message on that channel.
// It ends when its stdin closes. With --no-resubscribe it never subscribes again by itself after
// the server refused a subscription (see "status" below): what the bridge must then do for it.
//
//   node foxglove_client.js [--no-resubscribe] ws://127.0.0.1:8765 /drake/scene /drake/transforms
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const readline = require("readline");
const { WebSocket } = require("ws");

const resubscribes = !process.argv.includes("--no-resubscribe");
const [url, ...topics] = process.argv.slice(2).filter((arg) => arg !== "--no-resubscribe");
const print = (event) => process.stdout.write(JSON.stringify(event) + "\n");

const ws = new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
const client = new FoxgloveClient({ ws });
const topicOfSubscription = new Map();
const wanted = new Map(); // channel id -> topic, for the topics asked for
const retries = new Map(); // channel id -> subscriptions sent again

function subscribeTo(channelId) {
  topicOfSubscription.set(client.subscribe(channelId), wanted.get(channelId));
}

client.on("open", () => print({ event: "open", subprotocol: ws.protocol }));
client.on("error", (error) => print({ event: "error", message: String(error) }));
client.on("close", (event) => print({ event: "close", code: event.code }));
client.on("serverInfo", (info) =>
  print({
    event: "serverInfo", name: info.name, capabilities: info.capabilities,
    supportedEncodings: info.supportedEncodings ?? null,
  }),
);
client.on("unadvertise", (ids) => print({ event: "unadvertise", channelIds: ids }));
client.on("advertise", (channels) => {
  for (const channel of channels) {
    print({
      event: "advertise", id: channel.id, topic: channel.topic, encoding: channel.encoding,
      schemaName: channel.schemaName, schemaEncoding: channel.schemaEncoding, schema: channel.schema,
    });
    if (topics.includes(channel.topic)) {
      wanted.set(channel.id, channel.topic);
      subscribeTo(channel.id);
    }
  }
});
client.on("status", (status) => {
  print({ event: "status", level: status.level, message: status.message });
  // The SDK's server sends an advertisement before it records the channel as advertised to this
  // client, so a subscription sent at once can be refused as an unknown channel: send it again.
  const refused = /Unknown channel ID: (\d+)/.exec(status.message);
  const channelId = refused ? Number(refused[1]) : undefined;
  if (resubscribes && wanted.has(channelId) && (retries.get(channelId) ?? 0) < 10) {
    retries.set(channelId, (retries.get(channelId) ?? 0) + 1);
    subscribeTo(channelId);
  }
});
client.on("message", ({ subscriptionId, timestamp, data }) => {
  const bytes = Buffer.from(data.buffer, data.byteOffset, data.byteLength);
  print({
    event: "message",
    topic: topicOfSubscription.get(subscriptionId),
    timestamp: timestamp.toString(),
    data: bytes.toString("base64"),
  });
});

const published = new Map(); // name -> client channel id
const commands = readline.createInterface({ input: process.stdin });
commands.on("line", (line) => {
  const command = JSON.parse(line);
  if (command.op === "advertise") {
    const { topic, encoding, schemaName } = command;
    const name = command.name ?? topic;
    published.set(name, client.advertise({ topic, encoding, schemaName }));
    print({ event: "advertised", name, id: published.get(name) });
  } else if (command.op === "publish") {
    client.sendMessage(published.get(command.name), new Uint8Array(Buffer.from(command.data, "base64")));
  }
});
commands.on("close", () => {
  client.close();
  process.exit(0);
});
