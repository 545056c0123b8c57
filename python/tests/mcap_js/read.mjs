// Reads an MCAP file with the reference reader (@mcap/core, as Foxglove and Lichtblick do, with
// @mcap/support's decompressors) and prints what python/tests/test_log_mcap_js.py compares:
// the header, the statistics, and per topic its schema, encodings, count and first/last times.
// Usage: node read.mjs FILE.mcap   (prints one JSON object; times are strings of ns)
import { open } from "node:fs/promises";
import { McapIndexedReader } from "@mcap/core";
import { FileHandleReadable } from "@mcap/nodejs";
import { loadDecompressHandlers } from "@mcap/support";

const path = process.argv[2];
const handle = await open(path, "r");
try {
  const reader = await McapIndexedReader.Initialize({
    readable: new FileHandleReadable(handle),
    decompressHandlers: await loadDecompressHandlers(),
  });
  const topics = {};
  for (const channel of reader.channelsById.values()) {
    const schema = reader.schemasById.get(channel.schemaId);
    topics[channel.topic] = {
      schema: schema?.name ?? "",
      schemaEncoding: schema?.encoding ?? "",
      messageEncoding: channel.messageEncoding,
      count: 0,
      first: null,
      last: null,
      firstMessage: null,
    };
  }
  const decoder = new TextDecoder();
  for await (const msg of reader.readMessages({ validateCrcs: true })) {
    const t = topics[reader.channelsById.get(msg.channelId).topic];
    t.count += 1;
    if (t.first === null) {
      t.first = msg.logTime.toString();
      t.firstMessage = JSON.parse(decoder.decode(msg.data));
    }
    t.last = msg.logTime.toString();
  }
  const metadata = {};
  for await (const m of reader.readMetadata()) {
    metadata[m.name] = Object.fromEntries(m.metadata);
  }
  const stats = reader.statistics;
  console.log(
    JSON.stringify({
      profile: reader.header.profile,
      library: reader.header.library,
      messageCount: stats ? stats.messageCount.toString() : null,
      channelCount: stats ? stats.channelCount : null,
      messageStartTime: stats ? stats.messageStartTime.toString() : null,
      messageEndTime: stats ? stats.messageEndTime.toString() : null,
      topics,
      metadata,
    }),
  );
} finally {
  await handle.close();
}
