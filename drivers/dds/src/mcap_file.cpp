#include "mcap_file.h"

#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace mixray::dds::detail {
namespace {

constexpr uint8_t kMagic[] = {0x89, 'M', 'C', 'A', 'P', 0x30, '\r', '\n'};

enum Opcode : uint8_t {
    kHeader = 0x01,
    kFooter = 0x02,
    kSchema = 0x03,
    kChannel = 0x04,
    kMessage = 0x05,
    kChunk = 0x06,
    kMessageIndex = 0x07,
    kChunkIndex = 0x08,
    kAttachment = 0x09,
    kAttachmentIndex = 0x0A,
    kStatistics = 0x0B,
    kMetadata = 0x0C,
    kMetadataIndex = 0x0D,
    kSummaryOffset = 0x0E,
    kDataEnd = 0x0F,
};

// MCAP's serialization: little-endian integers, strings and byte runs with a uint32 (or, where
// the spec says, uint64) length before them.
class Bytes {
public:
    Bytes& u8(uint8_t v) {
        data.push_back(v);
        return *this;
    }
    Bytes& u16(uint16_t v) { return little(v, 2); }
    Bytes& u32(uint32_t v) { return little(v, 4); }
    Bytes& u64(uint64_t v) { return little(v, 8); }
    Bytes& raw(std::span<const uint8_t> bytes) {
        data.insert(data.end(), bytes.begin(), bytes.end());
        return *this;
    }
    Bytes& str(std::string_view s) {
        u32(static_cast<uint32_t>(s.size()));
        return raw({reinterpret_cast<const uint8_t*>(s.data()), s.size()});
    }
    Bytes& map(const std::map<std::string, std::string>& entries) {
        Bytes body;
        for (const auto& [key, value] : entries)
            body.str(key).str(value);
        return u32(static_cast<uint32_t>(body.data.size())).raw(body.data);
    }
    // The whole record: opcode, content length, content.
    std::vector<uint8_t> record(uint8_t opcode) const {
        Bytes out;
        out.u8(opcode).u64(data.size()).raw(data);
        return std::move(out.data);
    }

    std::vector<uint8_t> data;

private:
    Bytes& little(uint64_t v, int bytes) {
        for (int i = 0; i < bytes; ++i)
            data.push_back(static_cast<uint8_t>(v >> (8 * i)));
        return *this;
    }
};

uint32_t crc32Of(uint32_t crc, std::span<const uint8_t> bytes) {
    return static_cast<uint32_t>(crc32_z(crc, bytes.data(), bytes.size()));
}

}  // namespace

Result<std::unique_ptr<McapFile>> McapFile::create(const std::filesystem::path& path,
                                                   std::string_view profile,
                                                   std::string_view library, size_t chunk_bytes) {
    std::FILE* file = std::fopen(path.c_str(), "wb");
    if (!file) {
        return Status(ErrorCode::kIoError,
                      "cannot create " + path.string() + ": " + std::strerror(errno));
    }
    std::unique_ptr<McapFile> out(new McapFile(file, path, std::max<size_t>(chunk_bytes, 1)));
    MIXRAY_RETURN_IF_ERROR(out->emit(kMagic));
    MIXRAY_RETURN_IF_ERROR(out->emit(Bytes().str(profile).str(library).record(kHeader)));
    return out;
}

McapFile::~McapFile() {
    if (file_)
        std::fclose(file_);
}

Status McapFile::emit(std::span<const uint8_t> bytes) {
    MIXRAY_RETURN_IF_ERROR(failed_);
    if (std::fwrite(bytes.data(), 1, bytes.size(), file_) != bytes.size()) {
        failed_ = {ErrorCode::kIoError,
                   "cannot write " + path_.string() + ": " + std::strerror(errno)};
        return failed_;
    }
    // The data section's CRC covers every byte from the leading magic up to the Data End
    // record, as @mcap/core and the reference writer compute it; the summary's is kept by
    // close() from the summary's start.
    if (!data_end_)
        data_crc_ = crc32Of(data_crc_, bytes);
    position_ += bytes.size();
    return Status::ok();
}

uint16_t McapFile::addSchema(std::string_view name, std::string_view encoding,
                             std::string_view data) {
    const auto id = static_cast<uint16_t>(schemas_.size() + 1);
    schemas_.push_back(Bytes().u16(id).str(name).str(encoding).str(data).record(kSchema));
    schema_written_.push_back(false);
    return id;
}

uint16_t McapFile::addChannel(uint16_t schema, std::string_view topic,
                              std::string_view message_encoding,
                              const std::map<std::string, std::string>& metadata) {
    const auto id = static_cast<uint16_t>(channels_.size() + 1);
    channels_.push_back({.schema = schema,
                         .record = Bytes()
                                       .u16(id)
                                       .u16(schema)
                                       .str(topic)
                                       .str(message_encoding)
                                       .map(metadata)
                                       .record(kChannel),
                         .written = false,
                         .messages = 0});
    return id;
}

Status McapFile::addAttachment(std::string_view name, std::string_view media_type,
                               std::span<const uint8_t> data, uint64_t log_time) {
    Bytes content;
    content.u64(log_time).u64(0).str(name).str(media_type).u64(data.size()).raw(data);
    content.u32(crc32Of(0, content.data));
    const uint64_t offset = position_;
    MIXRAY_RETURN_IF_ERROR(emit(content.record(kAttachment)));
    attachment_indexes_.push_back({Bytes()
                                       .u64(offset)
                                       .u64(position_ - offset)
                                       .u64(log_time)
                                       .u64(0)
                                       .u64(data.size())
                                       .str(name)
                                       .str(media_type)
                                       .data});
    return Status::ok();
}

Status McapFile::addMetadata(std::string_view name,
                             const std::map<std::string, std::string>& metadata) {
    const uint64_t offset = position_;
    MIXRAY_RETURN_IF_ERROR(emit(Bytes().str(name).map(metadata).record(kMetadata)));
    metadata_indexes_.push_back({Bytes().u64(offset).u64(position_ - offset).str(name).data});
    return Status::ok();
}

Status McapFile::write(uint16_t channel, uint32_t sequence, uint64_t log_time,
                       uint64_t publish_time, std::span<const uint8_t> data) {
    MIXRAY_RETURN_IF_ERROR(failed_);
    if (channel == 0 || channel > channels_.size())
        return {ErrorCode::kInvalidArgument, "mcap: no channel " + std::to_string(channel)};
    Channel& c = channels_[channel - 1];
    if (!c.written) {
        if (c.schema != 0 && !schema_written_[c.schema - 1]) {
            chunk_.insert(chunk_.end(), schemas_[c.schema - 1].begin(),
                          schemas_[c.schema - 1].end());
            schema_written_[c.schema - 1] = true;
        }
        chunk_.insert(chunk_.end(), c.record.begin(), c.record.end());
        c.written = true;
    }
    const uint64_t offset = chunk_.size();
    Bytes head;
    head.u8(kMessage).u64(2 + 4 + 8 + 8 + data.size());
    head.u16(channel).u32(sequence).u64(log_time).u64(publish_time);
    chunk_.insert(chunk_.end(), head.data.begin(), head.data.end());
    chunk_.insert(chunk_.end(), data.begin(), data.end());
    Bytes entry;
    entry.u64(log_time).u64(offset);
    std::vector<uint8_t>& index = chunk_message_index_[channel];
    index.insert(index.end(), entry.data.begin(), entry.data.end());

    const bool first_in_chunk = chunk_message_index_.size() == 1 && index.size() == 16;
    chunk_start_time_ = first_in_chunk ? log_time : std::min(chunk_start_time_, log_time);
    chunk_end_time_ = first_in_chunk ? log_time : std::max(chunk_end_time_, log_time);
    message_start_time_ = message_count_ == 0 ? log_time : std::min(message_start_time_, log_time);
    message_end_time_ = message_count_ == 0 ? log_time : std::max(message_end_time_, log_time);
    ++message_count_;
    ++c.messages;
    return chunk_.size() >= chunk_bytes_ ? flushChunk() : Status::ok();
}

Status McapFile::flushChunk() {
    if (chunk_.empty())
        return Status::ok();
    const uint64_t chunk_start = position_;
    Bytes head;
    head.u8(kChunk).u64(8 + 8 + 8 + 4 + 4 + 8 + chunk_.size());
    head.u64(chunk_start_time_).u64(chunk_end_time_).u64(chunk_.size());
    head.u32(crc32Of(0, chunk_)).str("").u64(chunk_.size());
    MIXRAY_RETURN_IF_ERROR(emit(head.data));
    MIXRAY_RETURN_IF_ERROR(emit(chunk_));
    const uint64_t chunk_length = position_ - chunk_start;

    const uint64_t indexes_start = position_;
    Bytes offsets;
    for (const auto& [channel, entries] : chunk_message_index_) {
        offsets.u16(channel).u64(position_);
        MIXRAY_RETURN_IF_ERROR(emit(Bytes()
                                        .u16(channel)
                                        .u32(static_cast<uint32_t>(entries.size()))
                                        .raw(entries)
                                        .record(kMessageIndex)));
    }
    Bytes index;
    index.u64(chunk_start_time_).u64(chunk_end_time_).u64(chunk_start).u64(chunk_length);
    index.u32(static_cast<uint32_t>(offsets.data.size())).raw(offsets.data);
    index.u64(position_ - indexes_start).str("").u64(chunk_.size()).u64(chunk_.size());
    chunk_indexes_.push_back({std::move(index.data)});

    chunk_.clear();
    chunk_message_index_.clear();
    return Status::ok();
}

Status McapFile::close() {
    if (!file_)
        return failed_;
    MIXRAY_RETURN_IF_ERROR(flushChunk());
    const uint32_t data_crc = data_crc_;
    data_end_ = true;
    MIXRAY_RETURN_IF_ERROR(emit(Bytes().u32(data_crc).record(kDataEnd)));

    // The summary, grouped by opcode, each group located by a Summary Offset record.
    const uint64_t summary_start = position_;
    uint32_t summary_crc = 0;
    const auto summary = [&](std::span<const uint8_t> bytes) {
        summary_crc = crc32Of(summary_crc, bytes);
        return emit(bytes);
    };
    Bytes offsets;
    const auto group = [&](uint8_t opcode, const auto& records) -> Status {
        if (records.empty())
            return Status::ok();
        const uint64_t start = position_;
        for (const auto& r : records)
            MIXRAY_RETURN_IF_ERROR(summary(r));
        offsets.u8(kSummaryOffset).u64(1 + 8 + 8).u8(opcode).u64(start).u64(position_ - start);
        return Status::ok();
    };
    const auto records = [](const std::vector<Index>& indexes, uint8_t opcode) {
        std::vector<std::vector<uint8_t>> out;
        for (const Index& i : indexes)
            out.push_back(Bytes().raw(i.content).record(opcode));
        return out;
    };
    std::vector<std::vector<uint8_t>> channel_records;
    Bytes counts;
    for (size_t i = 0; i < channels_.size(); ++i) {
        channel_records.push_back(channels_[i].record);
        counts.u16(static_cast<uint16_t>(i + 1)).u64(channels_[i].messages);
    }
    MIXRAY_RETURN_IF_ERROR(group(kSchema, schemas_));
    MIXRAY_RETURN_IF_ERROR(group(kChannel, channel_records));
    MIXRAY_RETURN_IF_ERROR(group(kChunkIndex, records(chunk_indexes_, kChunkIndex)));
    MIXRAY_RETURN_IF_ERROR(group(kAttachmentIndex, records(attachment_indexes_, kAttachmentIndex)));
    MIXRAY_RETURN_IF_ERROR(group(kMetadataIndex, records(metadata_indexes_, kMetadataIndex)));
    Bytes statistics;
    statistics.u64(message_count_)
        .u16(static_cast<uint16_t>(schemas_.size()))
        .u32(static_cast<uint32_t>(channels_.size()))
        .u32(static_cast<uint32_t>(attachment_indexes_.size()))
        .u32(static_cast<uint32_t>(metadata_indexes_.size()))
        .u32(static_cast<uint32_t>(chunk_indexes_.size()))
        .u64(message_start_time_)
        .u64(message_end_time_)
        .u32(static_cast<uint32_t>(counts.data.size()))
        .raw(counts.data);
    MIXRAY_RETURN_IF_ERROR(
        group(kStatistics, std::vector<std::vector<uint8_t>>{statistics.record(kStatistics)}));

    const uint64_t summary_offset_start = position_;
    MIXRAY_RETURN_IF_ERROR(summary(offsets.data));
    // The footer's CRC covers the summary and summary offsets and the footer up to itself.
    MIXRAY_RETURN_IF_ERROR(summary(
        Bytes().u8(kFooter).u64(8 + 8 + 4).u64(summary_start).u64(summary_offset_start).data));
    MIXRAY_RETURN_IF_ERROR(emit(Bytes().u32(summary_crc).data));
    MIXRAY_RETURN_IF_ERROR(emit(kMagic));
    const bool closed = std::fclose(file_) == 0;
    file_ = nullptr;
    if (!closed) {
        failed_ = {ErrorCode::kIoError,
                   "cannot write " + path_.string() + ": " + std::strerror(errno)};
    }
    return failed_;
}

}  // namespace mixray::dds::detail
