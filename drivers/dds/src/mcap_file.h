// An MCAP file writer (https://mcap.dev/spec, major version 0): messages in uncompressed
// chunks, each followed by its message indexes; attachments and metadata in the data section;
// a summary (schemas, channels, chunk, attachment and metadata indexes, statistics) with its
// summary offsets; every CRC filled in. Debian packages no MCAP library (the reference one is
// header-only and not packaged), so this follows the specification by hand; the tests read its
// files with Foxglove's @mcap/core. Internal to drivers/dds.
#pragma once

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/graph/result.h"

namespace mixray::dds::detail {

// Thread-bound. Errors are kIoError naming the file; after one, every call fails.
class McapFile {
public:
    // Creates (replaces) `path` and writes the magic and the Header record.
    static Result<std::unique_ptr<McapFile>> create(const std::filesystem::path& path,
                                                    std::string_view profile,
                                                    std::string_view library,
                                                    size_t chunk_bytes = 4 << 20);
    ~McapFile();
    McapFile(const McapFile&) = delete;
    McapFile& operator=(const McapFile&) = delete;

    // A schema and a channel, ids from 1; written into the data section before the first
    // message that uses them, and into the summary.
    uint16_t addSchema(std::string_view name, std::string_view encoding, std::string_view data);
    uint16_t addChannel(uint16_t schema, std::string_view topic, std::string_view message_encoding,
                        const std::map<std::string, std::string>& metadata);
    Status addAttachment(std::string_view name, std::string_view media_type,
                         std::span<const uint8_t> data, uint64_t log_time);
    Status addMetadata(std::string_view name, const std::map<std::string, std::string>& metadata);
    // One message; a chunk is written once it holds chunk_bytes.
    Status write(uint16_t channel, uint32_t sequence, uint64_t log_time, uint64_t publish_time,
                 std::span<const uint8_t> data);
    // Writes the last chunk, the data end, the summary and the footer, and closes the file.
    Status close();
    uint64_t bytesWritten() const { return position_; }

private:
    struct Channel {
        uint16_t schema;
        std::vector<uint8_t> record;  // the whole Channel record
        bool written = false;         // into the data section
        uint64_t messages = 0;
    };
    struct Index {  // a Chunk Index, Attachment Index or Metadata Index record's content
        std::vector<uint8_t> content;
    };

    McapFile(std::FILE* file, std::filesystem::path path, size_t chunk_bytes)
        : file_(file), path_(std::move(path)), chunk_bytes_(chunk_bytes) {}
    // Appends to the file, counting the data section's CRC until data_end_.
    Status emit(std::span<const uint8_t> bytes);
    Status flushChunk();

    std::FILE* file_;
    std::filesystem::path path_;
    size_t chunk_bytes_;
    Status failed_ = Status::ok();
    uint64_t position_ = 0;
    uint32_t data_crc_ = 0;
    bool data_end_ = false;

    std::vector<std::vector<uint8_t>> schemas_;  // whole Schema records, id = index + 1
    std::vector<bool> schema_written_;
    std::vector<Channel> channels_;  // id = index + 1

    std::vector<uint8_t> chunk_;  // records of the open chunk
    uint64_t chunk_start_time_ = 0;
    uint64_t chunk_end_time_ = 0;
    std::map<uint16_t, std::vector<uint8_t>> chunk_message_index_;  // channel: (time, offset)s

    std::vector<Index> chunk_indexes_;
    std::vector<Index> attachment_indexes_;
    std::vector<Index> metadata_indexes_;
    uint64_t message_count_ = 0;
    uint64_t message_start_time_ = 0;
    uint64_t message_end_time_ = 0;
};

}  // namespace mixray::dds::detail
