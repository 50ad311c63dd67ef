#include "engine/trajectory.hpp"

#include <istream>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <string_view>
#include <system_error>
#include <utility>

namespace incise::engine {
namespace {

constexpr std::array<char, 8> kFileMagic{'I', 'N', 'C', 'T', 'R', 'A', 'J', '\0'};
constexpr std::array<char, 4> kChunkMagic{'C', 'H', 'N', 'K'};
constexpr std::array<char, 4> kCgStopMagic{'C', 'G', 'S', 'T'};  // version 2
// Device quaternions often come from float arithmetic, whose normalisation is good to ~1e-7;
// anything further from unit length is not a rotation someone meant to record.
constexpr double kQuaternionNormTolerance = 1e-4;

// ---- little-endian serialisation, field by field, independent of the host's layout ----

void put_u32(std::byte* out, std::uint32_t value) {
  for (int i = 0; i < 4; ++i) out[i] = static_cast<std::byte>((value >> (8 * i)) & 0xFFu);
}
void put_u64(std::byte* out, std::uint64_t value) {
  for (int i = 0; i < 8; ++i) out[i] = static_cast<std::byte>((value >> (8 * i)) & 0xFFu);
}
void put_f64(std::byte* out, double value) { put_u64(out, std::bit_cast<std::uint64_t>(value)); }
void put_f32(std::byte* out, float value) { put_u32(out, std::bit_cast<std::uint32_t>(value)); }

std::uint32_t get_u32(const std::byte* in) {
  std::uint32_t value = 0;
  for (int i = 0; i < 4; ++i) value |= std::to_integer<std::uint32_t>(in[i]) << (8 * i);
  return value;
}
std::uint64_t get_u64(const std::byte* in) {
  std::uint64_t value = 0;
  for (int i = 0; i < 8; ++i) value |= std::to_integer<std::uint64_t>(in[i]) << (8 * i);
  return value;
}
double get_f64(const std::byte* in) { return std::bit_cast<double>(get_u64(in)); }
float get_f32(const std::byte* in) { return std::bit_cast<float>(get_u32(in)); }

void encode_sample(const ToolSample& sample, std::byte* out) {
  put_f64(out, sample.time);
  for (int i = 0; i < 3; ++i) put_f64(out + 8 + 8 * i, sample.position[i]);
  for (int i = 0; i < 4; ++i) put_f64(out + 32 + 8 * i, sample.orientation[i]);
  put_u32(out + 64, sample.buttons);
  for (int i = 0; i < 3; ++i) put_f32(out + 68 + 4 * i, sample.force[i]);
}

ToolSample decode_sample(const std::byte* in) {
  ToolSample sample;
  sample.time = get_f64(in);
  for (int i = 0; i < 3; ++i) sample.position[i] = get_f64(in + 8 + 8 * i);
  for (int i = 0; i < 4; ++i) sample.orientation[i] = get_f64(in + 32 + 8 * i);
  sample.buttons = get_u32(in + 64);
  for (int i = 0; i < 3; ++i) sample.force[i] = get_f32(in + 68 + 4 * i);
  return sample;
}

// ---- text ----

std::string shortest(double value) {
  char text[32];
  const auto result = std::to_chars(text, text + sizeof text, value);
  return std::string(text, result.ptr);
}

std::string hex32(std::uint32_t value) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%08x", value);
  return text;
}

std::string hex_bytes(const std::byte* bytes, std::size_t count) {
  std::string text;
  for (std::size_t i = 0; i < count; ++i) {
    char pair[4];
    std::snprintf(pair, sizeof pair, "%02x", std::to_integer<unsigned>(bytes[i]));
    text += pair;
  }
  return text;
}

std::string system_error_text(int error_number) {
  return std::generic_category().message(error_number);
}

// The one definition of a valid sample, shared by writer and reader so that whatever the
// writer accepts the reader accepts too. `previous_time` is absent for the first sample.
std::optional<std::string> find_sample_problem(const ToolSample& sample,
                                               std::optional<double> previous_time) {
  if (!std::isfinite(sample.time)) return "time is " + shortest(sample.time);
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(sample.position[i])) {
      return "position[" + std::to_string(i) + "] is " + shortest(sample.position[i]);
    }
  }
  for (int i = 0; i < 4; ++i) {
    if (!std::isfinite(sample.orientation[i])) {
      return "orientation[" + std::to_string(i) + "] is " + shortest(sample.orientation[i]);
    }
  }
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(sample.force[i])) {
      return "force[" + std::to_string(i) + "] is " + shortest(sample.force[i]);
    }
  }
  const auto& q = sample.orientation;
  const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (!(std::abs(norm - 1.0) <= kQuaternionNormTolerance)) {
    return "orientation has norm " + shortest(norm) + ", not 1";
  }
  if (previous_time && sample.time < *previous_time) {
    return "time " + shortest(sample.time) + " is earlier than the previous sample's time " +
           shortest(*previous_time);
  }
  return std::nullopt;
}

// The one definition of a valid CG stop, shared by writer and reader like the samples'.
std::optional<std::string> find_stop_problem(const CgStop& stop, const std::optional<CgStop>& previous) {
  if (stop.step == 0) return "step 0 (steps count from 1)";
  if (stop.iterations == 0) return "zero iterations";
  if (previous && (stop.step < previous->step || (stop.step == previous->step && stop.solve <= previous->solve)))
    return "step " + std::to_string(stop.step) + " solve " + std::to_string(stop.solve) + " does not come after step " +
           std::to_string(previous->step) + " solve " + std::to_string(previous->solve);
  return std::nullopt;
}

struct FileCloser {
  void operator()(std::FILE* stream) const { std::fclose(stream); }
};
using FileHandle = std::unique_ptr<std::FILE, FileCloser>;

}  // namespace

// ---- errors ----

namespace {
std::string error_message(const std::filesystem::path& file,
                          std::optional<std::uint64_t> byte_offset, const std::string& detail) {
  std::string message = "trajectory file '" + file.string() + "'";
  if (byte_offset) message += " at byte " + std::to_string(*byte_offset);
  return message + ": " + detail;
}
}  // namespace

TrajectoryError::TrajectoryError(const std::filesystem::path& file,
                                 std::optional<std::uint64_t> byte_offset,
                                 const std::string& detail)
    : std::runtime_error(error_message(file, byte_offset, detail)),
      file_(file),
      byte_offset_(byte_offset) {}

// ---- checksum ----

namespace {
constexpr std::array<std::uint32_t, 256> make_checksum_table() {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t byte = 0; byte < 256; ++byte) {
    std::uint32_t remainder = byte;
    for (int bit = 0; bit < 8; ++bit) {
      // 0xEDB88320 is 0x04C11DB7 bit-reversed: the reflected form processes bits LSB first.
      remainder = (remainder & 1u) ? (remainder >> 1) ^ 0xEDB88320u : remainder >> 1;
    }
    table[byte] = remainder;
  }
  return table;
}
constexpr auto kChecksumTable = make_checksum_table();
}  // namespace

std::uint32_t trajectory_checksum(std::span<const std::byte> bytes) {
  std::uint32_t crc = 0xFFFFFFFFu;
  for (const std::byte byte : bytes) {
    crc = kChecksumTable[(crc ^ std::to_integer<std::uint32_t>(byte)) & 0xFFu] ^ (crc >> 8);
  }
  return crc ^ 0xFFFFFFFFu;
}

// ---- writer ----

TrajectoryWriter::TrajectoryWriter(const std::filesystem::path& file, std::size_t samples_per_chunk)
    : file_(file), samples_per_chunk_(samples_per_chunk) {
  if (samples_per_chunk == 0 || samples_per_chunk > kMaximumSamplesPerChunk) {
    throw std::invalid_argument("TrajectoryWriter: samples_per_chunk must be in 1.." +
                                std::to_string(kMaximumSamplesPerChunk) + ", not " +
                                std::to_string(samples_per_chunk));
  }
  stream_ = std::fopen(file.c_str(), "wb");
  if (!stream_) {
    throw TrajectoryError(file, std::nullopt,
                          "cannot open for writing: " + system_error_text(errno));
  }
  std::array<std::byte, kTrajectoryHeaderBytes> header{};
  std::memcpy(header.data(), kFileMagic.data(), kFileMagic.size());
  put_u32(header.data() + 8, kTrajectoryVersion);
  put_u32(header.data() + 12, static_cast<std::uint32_t>(kTrajectoryHeaderBytes));
  put_u32(header.data() + 16, 0);  // flags
  // The header goes out at once so that a recording that dies before its first chunk is
  // still a readable, empty trajectory rather than an unusable file.
  if (std::fwrite(header.data(), 1, header.size(), stream_) != header.size() ||
      std::fflush(stream_) != 0) {
    const int error_number = errno;
    std::fclose(stream_);
    stream_ = nullptr;
    throw TrajectoryError(file, 0, "cannot write the header: " + system_error_text(error_number));
  }
  bytes_written_ = header.size();
  chunk_.reserve(kChunkHeaderBytes + samples_per_chunk_ * kSampleBytes);
  chunk_.resize(kChunkHeaderBytes);
}

TrajectoryWriter::~TrajectoryWriter() {
  try {
    close();
  } catch (...) {
    // A destructor has nowhere to report to; close() has already released the stream.
  }
}

void TrajectoryWriter::append(const ToolSample& sample) {
  if (!stream_) {
    throw std::logic_error("TrajectoryWriter: append to '" + file_.string() +
                           "' after it was closed or failed");
  }
  if (const auto problem = find_sample_problem(sample, last_time_)) {
    throw std::invalid_argument("TrajectoryWriter: sample " + std::to_string(samples_written_) +
                                " for '" + file_.string() + "': " + *problem);
  }
  const std::size_t offset = chunk_.size();
  chunk_.resize(offset + kSampleBytes);
  encode_sample(sample, chunk_.data() + offset);
  ++pending_samples_;
  ++samples_written_;
  last_time_ = sample.time;
  if (pending_samples_ == samples_per_chunk_) write_pending_chunk();
}

namespace {

// Seals a chunk whose payload follows its kChunkHeaderBytes (magic, record count, payload
// size, CRC of the payload) and hands it to the OS with one fwrite, then fflush: once the
// chunk is with the OS a crash of this process can no longer lose it. On failure the stream
// is closed and set to null: a partly written chunk would make every later chunk unreachable
// for the reader, so the writer stops there instead of carrying on behind it.
void write_chunk(std::FILE*& stream, const std::filesystem::path& file, std::uint64_t offset,
                 std::vector<std::byte>& chunk, const std::array<char, 4>& magic, std::size_t records,
                 const char* what) {
  const std::size_t payload_bytes = chunk.size() - kChunkHeaderBytes;
  std::byte* header = chunk.data();
  std::memcpy(header, magic.data(), magic.size());
  put_u32(header + 4, static_cast<std::uint32_t>(records));
  put_u32(header + 8, static_cast<std::uint32_t>(payload_bytes));
  put_u32(header + 12, trajectory_checksum({header + kChunkHeaderBytes, payload_bytes}));
  if (std::fwrite(chunk.data(), 1, chunk.size(), stream) != chunk.size() || std::fflush(stream) != 0) {
    const int error_number = errno;
    std::fclose(stream);
    stream = nullptr;
    throw TrajectoryError(file, offset,
                          "cannot write a chunk of " + std::to_string(records) + " " + what + ": " +
                              system_error_text(error_number));
  }
}

}  // namespace

void TrajectoryWriter::append_cg_stops(std::span<const CgStop> stops) {
  if (!stream_) {
    throw std::logic_error("TrajectoryWriter: CG stops to '" + file_.string() + "' after it was closed or failed");
  }
  if (stops.empty()) return;
  std::optional<CgStop> previous = last_stop_;
  for (const CgStop& stop : stops) {
    if (const auto problem = find_stop_problem(stop, previous))
      throw std::invalid_argument("TrajectoryWriter: CG stop for '" + file_.string() + "': " + *problem);
    previous = stop;
  }
  std::vector<std::byte> chunk(kChunkHeaderBytes + stops.size() * kCgStopBytes);
  for (std::size_t i = 0; i < stops.size(); ++i) {
    std::byte* out = chunk.data() + kChunkHeaderBytes + i * kCgStopBytes;
    put_u64(out, stops[i].step);
    put_u32(out + 8, stops[i].solve);
    put_u32(out + 12, stops[i].iterations);
  }
  write_chunk(stream_, file_, bytes_written_, chunk, kCgStopMagic, stops.size(), "CG stops");
  bytes_written_ += chunk.size();
  last_stop_ = previous;
}

void TrajectoryWriter::write_pending_chunk() {
  if (pending_samples_ == 0) return;
  write_chunk(stream_, file_, bytes_written_, chunk_, kChunkMagic, pending_samples_, "samples");
  bytes_written_ += chunk_.size();
  chunk_.resize(kChunkHeaderBytes);
  pending_samples_ = 0;
}

void TrajectoryWriter::flush() {
  if (!stream_) return;
  write_pending_chunk();
}

void TrajectoryWriter::close() {
  if (!stream_) return;
  write_pending_chunk();
  std::FILE* stream = std::exchange(stream_, nullptr);
  if (std::fclose(stream) != 0) {
    throw TrajectoryError(file_, bytes_written_, "cannot close: " + system_error_text(errno));
  }
}

void write_trajectory(const std::filesystem::path& file, const std::vector<ToolSample>& samples,
                      std::size_t samples_per_chunk) {
  TrajectoryWriter writer(file, samples_per_chunk);
  for (const ToolSample& sample : samples) writer.append(sample);
  writer.close();
}

// ---- reader ----

namespace {

// Reads and checks the file header (the stream at its start, the file `file_bytes` long);
// returns its size, where the first chunk starts. Throws on anything but a valid header.
std::uint32_t read_header(std::FILE* stream, const std::filesystem::path& file, std::uint64_t file_bytes,
                          std::uint32_t& version) {
  std::array<std::byte, kTrajectoryMaximumHeaderBytes> header{};
  const std::size_t header_prefix =
      static_cast<std::size_t>(std::min<std::uint64_t>(file_bytes, kTrajectoryMinimumHeaderBytes));
  const std::size_t got = std::fread(header.data(), 1, header_prefix, stream);
  const std::size_t magic_bytes = std::min(got, kFileMagic.size());
  // Comparing only what is there lets a trajectory cut inside its magic be called truncated
  // rather than foreign.
  if (std::memcmp(header.data(), kFileMagic.data(), magic_bytes) != 0) {
    throw TrajectoryError(file, 0,
                          "not a trajectory file (bad magic: expected 494e435452414a00 "
                          "\"INCTRAJ\\0\", found " +
                              hex_bytes(header.data(), magic_bytes) + ")");
  }
  if (got < kTrajectoryMinimumHeaderBytes) {
    throw TrajectoryError(file, got,
                          "truncated header: the file has " + std::to_string(got) +
                              " bytes, a header needs at least " +
                              std::to_string(kTrajectoryMinimumHeaderBytes));
  }
  version = get_u32(header.data() + 8);
  if (version != 1 && version != kTrajectoryVersion) {
    throw TrajectoryError(file, 8,
                          "unsupported version " + std::to_string(version) +
                              " (this reader supports versions 1 and " +
                              std::to_string(kTrajectoryVersion) + ")");
  }
  const std::uint32_t header_bytes = get_u32(header.data() + 12);
  if (header_bytes < kTrajectoryMinimumHeaderBytes ||
      header_bytes > kTrajectoryMaximumHeaderBytes) {
    throw TrajectoryError(file, 12,
                          "invalid header size " + std::to_string(header_bytes) + " (must be " +
                              std::to_string(kTrajectoryMinimumHeaderBytes) + ".." +
                              std::to_string(kTrajectoryMaximumHeaderBytes) + ")");
  }
  const std::uint32_t flags = get_u32(header.data() + 16);
  if (flags != 0) {
    throw TrajectoryError(file, 16,
                          "unsupported flags " + hex32(flags) + " (versions 1 and 2 define none)");
  }
  if (file_bytes < header_bytes) {
    throw TrajectoryError(file, file_bytes,
                          "truncated header: it is " + std::to_string(header_bytes) +
                              " bytes but the file has only " + std::to_string(file_bytes));
  }
  // Reserved header bytes are skipped unread so a later writer may use them.
  const std::size_t reserved = header_bytes - got;
  if (std::fread(header.data() + got, 1, reserved, stream) != reserved) {
    throw TrajectoryError(file, got, "read error in the header: " + system_error_text(errno));
  }
  return header_bytes;
}

struct ChunkHeader {
  bool cg_stops = false;          // a CGST chunk (version 2), else CHNK
  std::uint32_t sample_count = 0;  // records: samples or CG stops
  std::uint32_t payload_bytes = 0;
  std::uint32_t stored_checksum = 0;
  bool cut_short = false;  // the file ends inside this chunk: a write a crash interrupted
};

// Reads the header of the chunk that starts `remaining` bytes before the end of the file and
// checks that its payload fits there; returns the problem, if any.
std::optional<std::string> read_chunk_header(std::FILE* stream, std::uint64_t remaining, std::uint32_t version,
                                             ChunkHeader& header) {
  std::array<std::byte, kChunkHeaderBytes> chunk_header{};
  if (remaining < kChunkHeaderBytes) {
    header.cut_short = true;
    return "truncated chunk header (" + std::to_string(remaining) + " of " +
           std::to_string(kChunkHeaderBytes) + " bytes present)";
  }
  if (std::fread(chunk_header.data(), 1, kChunkHeaderBytes, stream) != kChunkHeaderBytes) {
    return "truncated chunk header (read failed: " + system_error_text(errno) + ")";
  }
  header.cg_stops = version >= 2 && std::memcmp(chunk_header.data(), kCgStopMagic.data(), kCgStopMagic.size()) == 0;
  if (!header.cg_stops && std::memcmp(chunk_header.data(), kChunkMagic.data(), kChunkMagic.size()) != 0) {
    return std::string("bad chunk magic (expected 43484e4b \"CHNK\"") +
           (version >= 2 ? " or 43475354 \"CGST\"" : "") + ", found " +
           hex_bytes(chunk_header.data(), kChunkMagic.size()) + ")";
  }
  header.sample_count = get_u32(chunk_header.data() + 4);
  header.payload_bytes = get_u32(chunk_header.data() + 8);
  header.stored_checksum = get_u32(chunk_header.data() + 12);
  const char* records = header.cg_stops ? "CG stops" : "samples";
  const std::size_t record_bytes = header.cg_stops ? kCgStopBytes : kSampleBytes;
  if (header.sample_count > kMaximumSamplesPerChunk) {
    return std::string("implausible ") + (header.cg_stops ? "CG stop" : "sample") + " count " +
           std::to_string(header.sample_count) + " (at most " + std::to_string(kMaximumSamplesPerChunk) + ")";
  }
  if (std::uint64_t{header.payload_bytes} != std::uint64_t{header.sample_count} * record_bytes) {
    return "payload size " + std::to_string(header.payload_bytes) + " does not match " +
           std::to_string(header.sample_count) + " " + records + " of " + std::to_string(record_bytes) + " bytes";
  }
  if (remaining - kChunkHeaderBytes < header.payload_bytes) {
    header.cut_short = true;
    return "truncated chunk: its payload needs " + std::to_string(header.payload_bytes) + " bytes, only " +
           std::to_string(remaining - kChunkHeaderBytes) + " present";
  }
  return std::nullopt;
}

// Reads the chunks after the file header in order. Whatever stands between them and the end
// of the file as sized (a truncated, corrupt or invalid chunk) is discarded with everything
// after it and reported, rather than thrown: a recording cut short keeps what came before.
class ChunkReader {
 public:
  ChunkReader(std::FILE* stream, std::uint32_t version, Trajectory& trajectory)
      : stream_(stream), version_(version), trajectory_(trajectory) {}

  void read(std::uint64_t offset, std::uint64_t file_bytes) {
    auto& report = trajectory_.report;
    for (std::size_t chunk = 0; offset < file_bytes; ++chunk) {
      const std::uint64_t remaining = file_bytes - offset;
      std::uint64_t chunk_bytes = 0;
      if (const auto cause = read_chunk(remaining, chunk_bytes)) {
        report.complete = false;
        report.bytes_discarded = static_cast<std::size_t>(remaining);
        report.discarded_from = offset;
        report.torn_tail = cut_short_;
        report.problem = "chunk " + std::to_string(chunk) + " at byte " + std::to_string(offset) + ": " + *cause +
                         "; " + std::to_string(remaining) + " bytes discarded (this chunk and everything after it)";
        break;
      }
      ++report.chunks_read;
      offset += chunk_bytes;
    }
  }

 private:
  // Appends the next chunk's samples and sets `chunk_bytes` to its size, or returns why the
  // chunk cannot be taken.
  std::optional<std::string> read_chunk(std::uint64_t remaining, std::uint64_t& chunk_bytes) {
    ChunkHeader header;
    auto problem = read_chunk_header(stream_, remaining, version_, header);
    cut_short_ = header.cut_short;
    if (problem) return problem;
    payload_.resize(header.payload_bytes);
    if (std::fread(payload_.data(), 1, header.payload_bytes, stream_) != header.payload_bytes) {
      return "truncated chunk (read failed: " + system_error_text(errno) + ")";
    }
    const std::uint32_t computed_checksum = trajectory_checksum(payload_);
    if (computed_checksum != header.stored_checksum) {
      return "checksum mismatch (stored " + hex32(header.stored_checksum) + ", computed " +
             hex32(computed_checksum) + ")";
    }
    if (header.cg_stops) {
      if (auto problem = decode_stops(header.sample_count)) return "invalid CG stop: " + *problem;
      trajectory_.cg_stops.insert(trajectory_.cg_stops.end(), stops_.begin(), stops_.end());
      chunk_bytes = kChunkHeaderBytes + header.payload_bytes;
      return std::nullopt;
    }
    if (auto problem = decode_payload(header.sample_count)) return "invalid sample: " + *problem;
    trajectory_.samples.insert(trajectory_.samples.end(), decoded_.begin(), decoded_.end());
    chunk_bytes = kChunkHeaderBytes + header.payload_bytes;
    return std::nullopt;
  }

  // A chunk is taken whole or not at all, so its samples are decoded and checked before any
  // is kept; the time the next chunk must not go back from advances only when all pass.
  std::optional<std::string> decode_payload(std::uint32_t sample_count) {
    decoded_.clear();
    std::optional<double> chunk_previous_time = previous_time_;
    for (std::uint32_t i = 0; i < sample_count; ++i) {
      const ToolSample sample = decode_sample(payload_.data() + std::size_t{i} * kSampleBytes);
      if (const auto problem = find_sample_problem(sample, chunk_previous_time)) {
        return "sample " + std::to_string(i) + " of the chunk (sample " +
               std::to_string(trajectory_.samples.size() + i) + " of the file): " + *problem;
      }
      chunk_previous_time = sample.time;
      decoded_.push_back(sample);
    }
    previous_time_ = chunk_previous_time;
    return std::nullopt;
  }

  std::optional<std::string> decode_stops(std::uint32_t count) {
    stops_.clear();
    std::optional<CgStop> previous;
    if (!trajectory_.cg_stops.empty()) previous = trajectory_.cg_stops.back();
    for (std::uint32_t i = 0; i < count; ++i) {
      const std::byte* in = payload_.data() + std::size_t{i} * kCgStopBytes;
      const CgStop stop{get_u64(in), get_u32(in + 8), get_u32(in + 12)};
      if (const auto problem = find_stop_problem(stop, previous)) {
        return "stop " + std::to_string(i) + " of the chunk (stop " + std::to_string(trajectory_.cg_stops.size() + i) +
               " of the file): " + *problem;
      }
      previous = stop;
      stops_.push_back(stop);
    }
    return std::nullopt;
  }

  std::FILE* stream_;
  std::uint32_t version_;
  Trajectory& trajectory_;
  bool cut_short_ = false;  // the last chunk read_chunk looked at runs past the end of the file
  std::vector<CgStop> stops_;  // reused
  std::vector<std::byte> payload_;     // reused
  std::vector<ToolSample> decoded_;    // reused
  std::optional<double> previous_time_;  // of the last sample kept
};

}  // namespace

Trajectory read_trajectory(const std::filesystem::path& file) {
  FileHandle stream(std::fopen(file.c_str(), "rb"));
  if (!stream) {
    throw TrajectoryError(file, std::nullopt,
                          "cannot open for reading: " + system_error_text(errno));
  }
  // The size is taken once: a file still being recorded keeps growing, and whatever arrives
  // after this point is simply not part of this read.
  std::error_code size_error;
  const std::uint64_t file_bytes = std::filesystem::file_size(file, size_error);
  if (size_error) {
    throw TrajectoryError(file, std::nullopt, "cannot determine its size: " + size_error.message());
  }
  if (file_bytes == 0) {
    throw TrajectoryError(file, 0, "the file is empty (0 bytes), not a trajectory");
  }
  std::uint32_t version = 0;
  const std::uint32_t header_bytes = read_header(stream.get(), file, file_bytes, version);

  Trajectory trajectory;
  // Bounded by the file size, so a lying count cannot make this allocation large.
  trajectory.samples.reserve(static_cast<std::size_t>((file_bytes - header_bytes) / kSampleBytes));
  ChunkReader(stream.get(), version, trajectory).read(header_bytes, file_bytes);
  trajectory.report.samples_read = trajectory.samples.size();
  trajectory.report.cg_stops_read = trajectory.cg_stops.size();
  return trajectory;
}

// ---- CSV ----

void export_csv(const Trajectory& trajectory, std::ostream& out) {
  out << "time,x,y,z,qw,qx,qy,qz,buttons,fx,fy,fz\n";
  // to_chars rather than printf: shortest round-trip digits and no dependence on the locale's
  // decimal separator, which would otherwise turn a comma-separated file into garbage.
  std::string line;
  char number[32];
  auto add = [&](auto value) {
    const auto result = std::to_chars(number, number + sizeof number, value);
    line.append(number, result.ptr);
  };
  for (const ToolSample& sample : trajectory.samples) {
    line.clear();
    add(sample.time);
    for (double value : sample.position) {
      line += ',';
      add(value);
    }
    for (double value : sample.orientation) {
      line += ',';
      add(value);
    }
    line += ',';
    add(sample.buttons);
    for (float value : sample.force) {
      line += ',';
      add(value);
    }
    line += '\n';
    out << line;
  }
}

// ---- queries ----

namespace {
bool time_before(double time, const ToolSample& sample) { return time < sample.time; }

std::array<double, 4> slerp(const std::array<double, 4>& from, std::array<double, 4> to,
                            double fraction) {
  double cosine = 0;
  for (int i = 0; i < 4; ++i) cosine += from[i] * to[i];
  // q and -q are the same rotation; without this the blend would take the long way round.
  if (cosine < 0) {
    for (double& component : to) component = -component;
    cosine = -cosine;
  }
  double weight_from = 1 - fraction;
  double weight_to = fraction;
  // Close orientations (always the case between 1 kHz samples) make sin(angle) tiny and the
  // slerp weights ill-conditioned; there a normalised lerp is the same rotation to rounding.
  if (cosine < 0.9995) {
    const double angle = std::acos(std::min(cosine, 1.0));
    const double sine = std::sin(angle);
    weight_from = std::sin((1 - fraction) * angle) / sine;
    weight_to = std::sin(fraction * angle) / sine;
  }
  std::array<double, 4> result{};
  double norm_squared = 0;
  for (int i = 0; i < 4; ++i) {
    result[i] = weight_from * from[i] + weight_to * to[i];
    norm_squared += result[i] * result[i];
  }
  const double norm = std::sqrt(norm_squared);
  for (double& component : result) component /= norm;
  return result;
}
}  // namespace

ToolSample sample_at(const std::vector<ToolSample>& samples, double time) {
  if (samples.empty()) throw std::invalid_argument("sample_at: no samples");
  if (std::isnan(time)) throw std::invalid_argument("sample_at: time is NaN");
  if (time <= samples.front().time) return samples.front();
  if (time >= samples.back().time) return samples.back();
  // The first sample after `time`; the one before it is the latest at or before `time`, so
  // of several samples sharing a time the last recorded one wins.
  const auto after = std::upper_bound(samples.begin(), samples.end(), time, time_before);
  const ToolSample& before_sample = *(after - 1);
  const ToolSample& after_sample = *after;
  if (time == before_sample.time) return before_sample;
  const double fraction = (time - before_sample.time) / (after_sample.time - before_sample.time);

  ToolSample result;
  result.time = time;
  for (int i = 0; i < 3; ++i) {
    result.position[i] = std::lerp(before_sample.position[i], after_sample.position[i], fraction);
    result.force[i] = static_cast<float>(
        std::lerp(double{before_sample.force[i]}, double{after_sample.force[i]}, fraction));
  }
  result.orientation = slerp(before_sample.orientation, after_sample.orientation, fraction);
  result.buttons = before_sample.buttons;
  return result;
}

std::span<const ToolSample> samples_between(const std::vector<ToolSample>& samples, double t0,
                                            double t1) {
  if (std::isnan(t0) || std::isnan(t1) || !(t0 < t1)) return {};
  const auto first = std::upper_bound(samples.begin(), samples.end(), t0, time_before);
  const auto last = std::upper_bound(first, samples.end(), t1, time_before);
  return {first, last};
}

}  // namespace incise::engine

namespace incise::engine {

namespace {

// q / |q|, or nothing for a zero quaternion. The components are scaled by the largest first, so
// that values near a double's limits neither overflow nor vanish in the sum of squares (1e200
// once made the norm infinite and the orientation zero).
std::optional<std::array<double, 4>> unit_quaternion(const double* q) {
  double largest = 0;
  for (int c = 0; c < 4; ++c) largest = std::max(largest, std::abs(q[c]));
  if (!(largest > 0)) return std::nullopt;
  std::array<double, 4> scaled{};
  double norm = 0;
  for (int c = 0; c < 4; ++c) {
    scaled[c] = q[c] / largest;
    norm += scaled[c] * scaled[c];
  }
  norm = std::sqrt(norm);
  for (double& component : scaled) component /= norm;
  return scaled;
}

}  // namespace

std::vector<ToolSample> import_csv(std::istream& in, const std::string& name) {
  const auto fail = [&name](const std::string& what) { return TrajectoryError(name, std::nullopt, what); };
  std::string line;
  if (!std::getline(in, line)) throw fail("empty file (expected a header line)");
  if (!line.empty() && line.back() == '\r') line.pop_back();
  const std::string header = "time,x,y,z,qw,qx,qy,qz,buttons";
  const bool with_force = line == header + ",fx,fy,fz";
  if (line != header && !with_force)
    throw fail("line 1: header must be '" + header + "' (optionally ',fx,fy,fz'), got '" + line + "'");
  static const char* columns[] = {"time", "x", "y", "z", "qw", "qx", "qy", "qz", "buttons", "fx", "fy", "fz"};
  const size_t expected = with_force ? 12 : 9;
  std::vector<ToolSample> samples;
  for (long number = 2; std::getline(in, line); ++number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    std::vector<double> values;
    size_t start = 0;
    while (true) {
      const size_t comma = line.find(',', start);
      const std::string field = line.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
      const std::string where = "line " + std::to_string(number) + ", column " +
                                std::to_string(values.size() + 1) +
                                (values.size() < 12 ? std::string(" (") + columns[values.size()] + ")" : "");
      double value = 0;
      const auto result = std::from_chars(field.data(), field.data() + field.size(), value);
      if (result.ec != std::errc() || result.ptr != field.data() + field.size() || field.empty())
        throw fail(where + ": '" + field + "' is not a number");
      if (!std::isfinite(value)) throw fail(where + ": " + field + " is not finite");
      values.push_back(value);
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
    if (values.size() != expected)
      throw fail("line " + std::to_string(number) + ": " + std::to_string(values.size()) +
                            " columns, the header has " + std::to_string(expected));
    ToolSample sample;
    sample.time = values[0];
    for (int c = 0; c < 3; ++c) sample.position[c] = values[1 + c];
    const auto orientation = unit_quaternion(&values[4]);
    if (!orientation) throw fail("line " + std::to_string(number) + ": the quaternion (qw, qx, qy, qz) is zero");
    sample.orientation = *orientation;
    if (values[8] < 0 || values[8] != std::floor(values[8]) || values[8] > 4294967295.0)
      throw fail("line " + std::to_string(number) + ": column 9 (buttons): " + std::to_string(values[8]) +
                            " is not an unsigned integer");
    sample.buttons = static_cast<std::uint32_t>(values[8]);
    for (int c = 0; with_force && c < 3; ++c) {
      // Forces are stored as floats: a larger value would be stored as infinity.
      if (!(std::abs(values[9 + c]) <= std::numeric_limits<float>::max()))
        throw fail("line " + std::to_string(number) + ", column " + std::to_string(10 + c) + " (" + columns[9 + c] +
                   "): " + shortest(values[9 + c]) + " N is beyond a float's range");
      sample.force[c] = static_cast<float>(values[9 + c]);
    }
    if (!samples.empty() && !(sample.time > samples.back().time))
      throw fail("line " + std::to_string(number) + ": time " + std::to_string(sample.time) +
                            " does not increase (previous " + std::to_string(samples.back().time) + ")");
    samples.push_back(sample);
  }
  if (samples.empty()) throw fail("no sample after the header");
  return samples;
}

}  // namespace incise::engine
