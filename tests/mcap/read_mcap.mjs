// Reads an MCAP file with Foxglove's own libraries, independent of mixray: @mcap/core's indexed
// reader (summary, chunk indexes, message indexes and every CRC it checks) and its stream
// reader (a linear pass through every record), and decodes each message's CDR with the schema
// the file carries (@foxglove/rosmsg parses the .msg text, @foxglove/rosmsg2-serialization reads
// the CDR). Prints one JSON object with what it found, for tests/dds/mcap_export_test.cpp.
//   node read_mcap.mjs FILE.mcap
import { createHash } from "node:crypto";
import { readFileSync } from "node:fs";

import { crc32 } from "@foxglove/crc";
import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import { McapIndexedReader, McapStreamReader } from "@mcap/core";

const bytes = new Uint8Array(readFileSync(process.argv[2]));
const sha256 = (data) => createHash("sha256").update(data).digest("hex");
const readable = {
  size: async () => BigInt(bytes.length),
  read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length)),
};
const reader = await McapIndexedReader.Initialize({ readable });

const decoders = new Map();
for (const [id, schema] of reader.schemasById) {
  const definition = new TextDecoder().decode(schema.data);
  decoders.set(id, new MessageReader(parse(definition, { ros2: true })));
}
const out = {
  profile: reader.header.profile,
  library: reader.header.library,
  schemas: [...reader.schemasById.values()].map((s) => ({ id: s.id, name: s.name, encoding: s.encoding })),
  channels: [...reader.channelsById.values()].map((c) => ({
    id: c.id,
    topic: c.topic,
    messageEncoding: c.messageEncoding,
    schemaId: c.schemaId,
    offeredQos: c.metadata.get("offered_qos_profiles") ?? null,
  })),
  statistics: {
    messageCount: Number(reader.statistics.messageCount),
    chunkCount: reader.statistics.chunkCount,
    attachmentCount: reader.statistics.attachmentCount,
    metadataCount: reader.statistics.metadataCount,
    channelMessageCounts: Object.fromEntries(
      [...reader.statistics.channelMessageCounts].map(([id, n]) => [id, Number(n)])),
  },
  chunkIndexes: reader.chunkIndexes.length,
  messages: [],
  attachments: [],
  metadata: [],
};
for await (const message of reader.readMessages()) {
  const channel = reader.channelsById.get(message.channelId);
  const schema = reader.schemasById.get(channel.schemaId).name;
  const decoded = decoders.get(channel.schemaId).readMessage(message.data);
  const out_message = {
    topic: channel.topic,
    schema,
    sequence: message.sequence,
    logTime: message.logTime.toString(),
    publishTime: message.publishTime.toString(),
  };
  if (decoded.header) {
    out_message.sec = decoded.header.stamp.sec;
    out_message.nanosec = decoded.header.stamp.nanosec;
    out_message.frameId = decoded.header.frame_id;
  }
  if (schema === "sensor_msgs/msg/Image") {
    Object.assign(out_message, {
      width: decoded.width,
      height: decoded.height,
      encoding: decoded.encoding,
      isBigendian: decoded.is_bigendian,
      step: decoded.step,
      dataLength: decoded.data.length,
      sha256: sha256(decoded.data),
    });
  } else if (schema === "sensor_msgs/msg/CameraInfo") {
    Object.assign(out_message, {
      width: decoded.width,
      height: decoded.height,
      distortionModel: decoded.distortion_model,
      d: Array.from(decoded.d),
      k: Array.from(decoded.k),
      r: Array.from(decoded.r),
      p: Array.from(decoded.p),
    });
  } else if (schema === "tf2_msgs/msg/TFMessage") {
    out_message.transforms = decoded.transforms.map((t) => ({
      parent: t.header.frame_id,
      child: t.child_frame_id,
      translation: [t.transform.translation.x, t.transform.translation.y, t.transform.translation.z],
      rotation: [t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z, t.transform.rotation.w],
    }));
  }
  out.messages.push(out_message);
}
for await (const a of reader.readAttachments()) {
  out.attachments.push({ name: a.name, mediaType: a.mediaType, size: a.data.length, sha256: sha256(a.data) });
}
for await (const m of reader.readMetadata()) {
  out.metadata.push({ name: m.name, entries: Object.fromEntries(m.metadata) });
}

// A linear pass: every record in file order, chunk CRCs checked, and the data section's CRC
// (from the leading magic to the Data End record) computed here and compared.
const stream = new McapStreamReader({ validateCrcs: true });
stream.append(bytes);
let streamed = 0;
let dataEndCrc = null;
let footer = null;
for (let record; (record = stream.nextRecord()); ) {
  if (record.type === "Message") streamed++;
  if (record.type === "DataEnd") dataEndCrc = record.dataSectionCrc;
  if (record.type === "Footer") footer = record;
}
out.streamedMessages = streamed;
out.streamDone = stream.done();
const dataEndOffset = Number(footer.summaryStart) - (1 + 8 + 4);
out.dataSectionCrcMatches = dataEndCrc !== 0 && crc32(bytes.subarray(0, dataEndOffset)) === dataEndCrc;
console.log(JSON.stringify(out));
