// mixray info: what a recording holds — streams, formats, frame counts, timing, attachments.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <thread>

#include "cli.h"
#include "console.h"
#include "mixray/graph/mkv.h"
#include "mixray/replay/open_recording.h"
#include "mixray/tracking/light_record.h"
#include "recording_frames.h"

namespace mixray::cli {
namespace {

// Timing of one stream, gathered by reading every frame.
struct StreamSummary {
    uint64_t frames = 0;
    uint64_t bad_frames = 0;  // status other than ok
    uint64_t payload_bytes = 0;
    int64_t first_ns = 0;
    int64_t last_ns = 0;
    std::vector<int64_t> intervals_ns;
    uint64_t sequence_gaps = 0;  // frames the device numbered but never delivered
    uint64_t last_sequence = 0;
    // Pose, light and environment-map streams: their records decoded.
    tracking::RecordStreamKind records = tracking::RecordStreamKind::kNone;
    uint64_t stale = 0, lost = 0;
    std::string first_reason;
    struct Damaged {
        uint64_t frame = 0;  // index in the stream
        int64_t stamp_ns = 0;
        std::string what;
    };
    std::vector<Damaged> damaged;
};

// Decodes one frame of a record stream into its summary.
void addRecord(StreamSummary& s, const FrameRef& frame) {
    auto digest = tracking::digestRecord(s.records, frame.image());
    if (!digest) {
        s.damaged.push_back({s.frames - 1, frame.meta().host_stamp_ns, digest.status().message()});
        return;
    }
    s.stale += digest->stale;
    s.lost += digest->lost;
    if (s.first_reason.empty())
        s.first_reason = digest->reason;
}

// "record 3 (0.1 s after start): light record: CRC mismatch (the record is damaged)".
std::string describeDamagedRecord(const StreamSummary::Damaged& d, int64_t first_stamp_ns) {
    return "record " + std::to_string(d.frame) + " (" +
           formatDuration(d.stamp_ns - first_stamp_ns) + " after start): " + d.what;
}

// A gap is an interval longer than 1.5 nominal (or median) frame periods.
struct GapReport {
    uint64_t count = 0;
    int64_t longest_ns = 0;
    int64_t longest_at_ns = 0;  // offset of the longest gap's start from the stream's start
    double measured_fps = 0;
};

GapReport gapsOf(const StreamSummary& s, double nominal_fps) {
    GapReport report;
    if (s.intervals_ns.empty())
        return report;
    std::vector<int64_t> sorted = s.intervals_ns;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const int64_t median = sorted[sorted.size() / 2];
    const double period =
        nominal_fps > 0 ? 1e9 / nominal_fps : static_cast<double>(std::max<int64_t>(median, 1));
    int64_t at = 0;
    for (int64_t interval : s.intervals_ns) {
        if (static_cast<double>(interval) > 1.5 * period) {
            ++report.count;
            if (interval > report.longest_ns) {
                report.longest_ns = interval;
                report.longest_at_ns = at;
            }
        }
        at += interval;
    }
    const int64_t span = s.last_ns - s.first_ns;
    if (span > 0)
        report.measured_fps = static_cast<double>(s.frames - 1) * 1e9 / span;
    return report;
}

std::string layoutOf(const StreamInfo& info) {
    char text[96];
    std::snprintf(text, sizeof text, "%s %dx%d", std::string(toString(info.format.format)).c_str(),
                  info.format.width, info.format.height);
    return text;
}

// "at byte 123 (0.5 s into the recording, after the frame at ...): <what>; read on from byte 456".
std::string describeDamage(const RecordingDamage& d, int64_t first_stamp_ns) {
    std::string text = d.byte_offset >= 0 ? "at byte " + std::to_string(d.byte_offset)
                                          : std::string("at an unknown byte");
    if (d.after_stamp_ns >= 0 && d.after_stamp_ns >= first_stamp_ns) {
        text += " (after the frame at " + formatDuration(d.after_stamp_ns - first_stamp_ns) +
                " into the recording)";
    }
    text += ": " + d.what;
    text += d.resumed_at >= 0 ? "; read on from byte " + std::to_string(d.resumed_at)
                              : std::string("; nothing readable after it");
    return text;
}

int runInfo(const std::string& path, bool as_json) {
    setFfmpegLogging(false);
    auto opened = replay::openRecording(path);
    if (!opened)
        return fail("info", opened.status());
    RecordingReader& reader = **opened;
    const auto& streams = reader.streams();
    std::vector<StreamSummary> summaries(streams.size());
    for (size_t i = 0; i < streams.size(); ++i)
        summaries[i].records = tracking::recordStreamKind(streams[i]);

    Status end_status;
    uint64_t total = 0;
    for (;;) {
        auto next = nextFrame(reader);
        if (!next) {
            end_status = next.status();
            break;
        }
        if (!*next)
            break;
        const FrameRef& frame = **next;
        const auto& meta = frame.meta();
        if (meta.stream >= summaries.size())
            continue;
        StreamSummary& s = summaries[meta.stream];
        if (s.frames == 0) {
            s.first_ns = meta.host_stamp_ns;
        } else {
            s.intervals_ns.push_back(meta.host_stamp_ns - s.last_ns);
            if (meta.sequence > s.last_sequence + 1)
                s.sequence_gaps += meta.sequence - s.last_sequence - 1;
        }
        s.last_ns = meta.host_stamp_ns;
        s.last_sequence = meta.sequence;
        ++s.frames;
        if (meta.status != FrameStatus::kOk)
            ++s.bad_frames;
        s.payload_bytes += frame.image().size_bytes;
        if (s.records != tracking::RecordStreamKind::kNone)
            addRecord(s, frame);
        ++total;
    }

    const std::vector<RecordingDamage> damage = reader.damage();

    int64_t first = INT64_MAX, last = INT64_MIN;
    for (const auto& s : summaries) {
        if (s.frames == 0)
            continue;
        first = std::min(first, s.first_ns);
        last = std::max(last, s.last_ns);
    }
    const int64_t duration = total > 0 ? last - first : 0;
    std::error_code ec;
    const auto file_bytes =
        std::filesystem::is_regular_file(path, ec) ? std::filesystem::file_size(path, ec) : 0;

    if (as_json) {
        nlohmann::json j;
        j["path"] = path;
        j["format"] = reader.format();
        j["file_bytes"] = file_bytes;
        j["frames"] = total;
        j["duration_ns"] = duration;
        j["first_stamp_ns"] = total ? first : 0;
        j["complete"] = end_status.isOk() && damage.empty();
        j["damage"] = nlohmann::json::array();
        for (const RecordingDamage& d : damage) {
            j["damage"].push_back({{"byte_offset", d.byte_offset},
                                   {"resumed_at", d.resumed_at},
                                   {"after_stamp_ns", d.after_stamp_ns},
                                   {"what", d.what}});
        }
        if (!end_status.isOk())
            j["error"] = end_status.toString();
        j["tags"] = reader.tags();
        for (size_t i = 0; i < streams.size(); ++i) {
            const auto& info = streams[i];
            const auto& s = summaries[i];
            const GapReport gaps = gapsOf(s, info.nominal_fps);
            nlohmann::json stream = {{"name", info.name},
                                     {"kind", std::string(toString(info.kind))},
                                     {"format", std::string(toString(info.format.format))},
                                     {"width", info.format.width},
                                     {"height", info.format.height},
                                     {"nominal_fps", info.nominal_fps},
                                     {"measured_fps", gaps.measured_fps},
                                     {"frames", s.frames},
                                     {"bad_frames", s.bad_frames},
                                     {"first_stamp_ns", s.first_ns},
                                     {"last_stamp_ns", s.last_ns},
                                     {"gaps", gaps.count},
                                     {"longest_gap_ns", gaps.longest_ns},
                                     {"sequence_gaps", s.sequence_gaps},
                                     {"clock_domain", info.clock_domain},
                                     {"tags", info.tags}};
            if (s.records != tracking::RecordStreamKind::kNone) {
                nlohmann::json damaged = nlohmann::json::array();
                for (const auto& d : s.damaged)
                    damaged.push_back(
                        {{"record", d.frame}, {"stamp_ns", d.stamp_ns}, {"what", d.what}});
                stream["records"] = {{"decoded", s.frames - s.damaged.size()},
                                     {"stale", s.stale},
                                     {"lost", s.lost},
                                     {"first_reason", s.first_reason},
                                     {"damaged", damaged}};
            }
            j["streams"].push_back(std::move(stream));
        }
        j["attachments"] = nlohmann::json::array();
        for (const auto& a : reader.attachments()) {
            j["attachments"].push_back(
                {{"name", a.name}, {"mime_type", a.mime_type}, {"bytes", a.data.size()}});
        }
        std::printf("%s\n", j.dump(2).c_str());
    } else {
        std::printf("%s: %s", path.c_str(), reader.format().c_str());
        if (file_bytes)
            std::printf(", %s", formatBytes(file_bytes).c_str());
        std::printf("\n  %llu frames over %s\n", static_cast<unsigned long long>(total),
                    formatDuration(duration).c_str());
        for (const auto& [key, value] : reader.tags()) {
            std::printf("  tag %s = %s\n", key.c_str(), value.c_str());
        }
        std::printf("streams:\n");
        for (size_t i = 0; i < streams.size(); ++i) {
            const auto& info = streams[i];
            const auto& s = summaries[i];
            const GapReport gaps = gapsOf(s, info.nominal_fps);
            std::printf("  #%zu %-22s %-9s %-18s %6llu frames  %6.2f fps", i, info.name.c_str(),
                        std::string(toString(info.kind)).c_str(), layoutOf(info).c_str(),
                        static_cast<unsigned long long>(s.frames), gaps.measured_fps);
            if (info.nominal_fps > 0)
                std::printf(" (nominal %.2f)", info.nominal_fps);
            std::printf("  %s\n", formatBytes(s.payload_bytes).c_str());
            if (s.frames > 0) {
                std::printf("     stamps %s .. %s after start",
                            formatDuration(s.first_ns - first).c_str(),
                            formatDuration(s.last_ns - first).c_str());
                if (gaps.count) {
                    std::printf(", %llu gaps (longest %s at %s)",
                                static_cast<unsigned long long>(gaps.count),
                                formatDuration(gaps.longest_ns).c_str(),
                                formatDuration(gaps.longest_at_ns).c_str());
                } else {
                    std::printf(", no gaps");
                }
                if (s.sequence_gaps) {
                    std::printf(", %llu frames missing by sequence",
                                static_cast<unsigned long long>(s.sequence_gaps));
                }
                if (s.bad_frames) {
                    std::printf(", %llu incomplete/corrupt",
                                static_cast<unsigned long long>(s.bad_frames));
                }
                std::printf("\n");
            }
            if (s.records != tracking::RecordStreamKind::kNone && s.frames > 0) {
                std::printf("     records: %llu decoded, %llu stale, %llu lost, %zu damaged",
                            static_cast<unsigned long long>(s.frames - s.damaged.size()),
                            static_cast<unsigned long long>(s.stale),
                            static_cast<unsigned long long>(s.lost), s.damaged.size());
                if (!s.first_reason.empty())
                    std::printf(" (first reason: %s)", s.first_reason.c_str());
                std::printf("\n");
                for (const auto& d : s.damaged)
                    std::printf("     damaged %s\n", describeDamagedRecord(d, first).c_str());
            }
        }
        if (!reader.attachments().empty())
            std::printf("attachments:\n");
        for (const auto& a : reader.attachments()) {
            std::printf("  %-24s %-26s %s\n", a.name.c_str(), a.mime_type.c_str(),
                        formatBytes(a.data.size()).c_str());
        }
    }
    if (!as_json) {
        for (const RecordingDamage& d : damage)
            std::printf("damage: %s\n", describeDamage(d, total ? first : 0).c_str());
    }
    // A file that ends in damage says so with how far it reads (below); damage read past is
    // the story otherwise.
    if (!damage.empty() && end_status.isOk()) {
        const RecordingDamage& d = damage.front();
        return fail("info", {ErrorCode::kCorruptData,
                             path + ": damaged: " + std::to_string(damage.size()) +
                                 " stretch(es) could not be read and were skipped (frames in "
                                 "them are lost), the first " +
                                 describeDamage(d, total ? first : 0)});
    }
    for (size_t i = 0; i < streams.size() && end_status.isOk(); ++i) {
        const StreamSummary& s = summaries[i];
        if (s.damaged.empty())
            continue;
        return fail("info",
                    {ErrorCode::kCorruptData, path + ": stream '" + streams[i].name + "' holds " +
                                                  std::to_string(s.damaged.size()) +
                                                  " damaged record(s), the first " +
                                                  describeDamagedRecord(s.damaged.front(), first)});
    }
    if (!end_status.isOk()) {
        return fail("info", end_status.withContext(path + ": readable up to frame " +
                                                   std::to_string(total)));
    }
    return kExitOk;
}

}  // namespace

void registerInfoCommand(CLI::App& app, Commands& commands) {
    auto* sub = app.add_subcommand(
        "info",
        "Describe a recording: streams, formats, frame counts, duration, timestamp gaps, "
        "attachments. Reads every frame, so damage anywhere in the file is reported; the records "
        "of pose, light and environment-map streams are decoded and their stale, lost and "
        "damaged records counted.");
    struct Options {
        std::string path;
        bool json = false;
    };
    auto options = std::make_shared<Options>();
    sub->add_option("FILE", options->path,
                    "Recording: mixray or Azure Kinect .mkv, TUM RGB-D folder, PCL TIFF folder, "
                    "NYU Depth V2 raw scene folder, SUN RGB-D frame folder, OpenNI .oni file")
        ->required();
    sub->add_flag("--json", options->json, "Print the description as JSON");
    commands.push_back({sub, [options] { return runInfo(options->path, options->json); }});
}

}  // namespace mixray::cli
