// Recorded tool trajectories: the haptic thread records every 1 kHz sample of the tool so a
// session can be replayed headless, bit for bit. The on-disk format is specified in
// docs/trajectory.md; this header is its only reader and writer.
//
// The file is a header followed by checksummed chunks, each flushed to the OS as soon as it
// is complete, so a crash of the process loses at most the samples of the chunk being filled.
// A damaged tail is therefore an expected outcome, not an error: read_trajectory returns every
// chunk before the first damaged one and says in its report what was discarded and why.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <ostream>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace incise::engine {

struct ToolSample {
  double time = 0;                                // seconds since the start of the recording
  std::array<double, 3> position{};               // metres, world frame (tool tip)
  std::array<double, 4> orientation{1, 0, 0, 0};  // unit quaternion w,x,y,z (tool frame -> world)
  std::uint32_t buttons = 0;                      // bit 0: blade/probe engaged
  // N, force rendered to the device at that tick (0 when not recorded)
  std::array<float, 3> force{};

  friend bool operator==(const ToolSample&, const ToolSample&) = default;
};

inline constexpr std::uint32_t kToolButtonEngaged = 1u << 0;

// A CG that a live session's real-time budget stopped (physics/core/cg.hpp, CgBudget): the
// `solve`-th CG of step `step` (counted from 0 in the step's order: bodies, then retried
// sub-steps) did `iterations` iterations. A replay stops that CG there, so it takes the steps
// the session took.
struct CgStop {
  std::uint64_t step = 0;  // 1 for the first step
  std::uint32_t solve = 0;
  std::uint32_t iterations = 0;  // >= 1

  friend bool operator==(const CgStop&, const CgStop&) = default;
};

struct TrajectoryReadReport {
  std::size_t chunks_read = 0;  // good chunks, all of whose samples were returned
  std::size_t samples_read = 0;
  std::size_t cg_stops_read = 0;
  bool complete = true;             // false when a damaged or truncated tail was discarded
  std::size_t bytes_discarded = 0;  // from the start of the first bad chunk to the end of the file
  std::uint64_t discarded_from = 0;  // byte where the first bad chunk starts (the kept part ends)
  // The bad chunk is the last one and the file ends inside it: a write that a crash (kill -9,
  // power loss) interrupted, as opposed to bytes that are there but wrong.
  bool torn_tail = false;
  std::string problem;  // empty when complete; otherwise names the chunk, byte offset and cause
};

struct Trajectory {
  std::vector<ToolSample> samples;
  std::vector<CgStop> cg_stops;  // in (step, solve) order; empty unless recorded in real time
  TrajectoryReadReport report;
};

// A file that cannot be used at all (missing, empty, not a trajectory, unsupported version) or
// that cannot be written. The message names the file and, where one applies, the byte offset.
class TrajectoryError : public std::runtime_error {
 public:
  TrajectoryError(const std::filesystem::path& file, std::optional<std::uint64_t> byte_offset,
                  const std::string& detail);
  const std::filesystem::path& file() const { return file_; }
  std::optional<std::uint64_t> byte_offset() const { return byte_offset_; }

 private:
  std::filesystem::path file_;
  std::optional<std::uint64_t> byte_offset_;
};

// Format constants, public so tests and tools can reason about offsets.
inline constexpr std::uint32_t kTrajectoryVersion = 2;  // what this writer emits; 1 is read too
inline constexpr std::size_t kTrajectoryHeaderBytes = 32;         // what this writer emits
inline constexpr std::size_t kTrajectoryMinimumHeaderBytes = 20;  // magic, version, size, flags
inline constexpr std::size_t kTrajectoryMaximumHeaderBytes = 4096;
inline constexpr std::size_t kChunkHeaderBytes = 16;
inline constexpr std::size_t kSampleBytes = 80;
inline constexpr std::size_t kMaximumSamplesPerChunk = 1'000'000;
inline constexpr std::size_t kCgStopBytes = 16;  // version 2: step u64, solve u32, iterations u32

// CRC-32 as in IEEE 802.3 / zlib (reflected 0x04C11DB7, init and final xor 0xFFFFFFFF), the
// checksum stored in every chunk header. Exposed so tools and tests can build valid chunks.
std::uint32_t trajectory_checksum(std::span<const std::byte> bytes);

// Appends samples to a new file (an existing one is replaced). Meant for a single thread, the
// haptic one: append() only copies into a buffer until a chunk is full, then writes that chunk
// with one fwrite and fflushes it. Samples are checked on append so the writer can never
// produce a file its reader would call corrupted.
class TrajectoryWriter {
 public:
  explicit TrajectoryWriter(const std::filesystem::path& file, std::size_t samples_per_chunk = 250);
  TrajectoryWriter(const TrajectoryWriter&) = delete;
  TrajectoryWriter& operator=(const TrajectoryWriter&) = delete;
  ~TrajectoryWriter();  // closes; never throws (errors at this point are lost: call close())

  // Throws std::invalid_argument for a non-finite value, a quaternion whose norm is not near 1
  // or a time earlier than the previous sample's; std::logic_error after close(); TrajectoryError
  // when the file cannot be written.
  void append(const ToolSample& sample);
  // Writes the stops as a chunk of their own at once (a step's stops are few, and a replay of
  // what a crash kept needs the stops of every step it kept). Throws std::invalid_argument for
  // a stop out of (step, solve) order or with zero iterations, as append() does for a sample.
  void append_cg_stops(std::span<const CgStop> stops);
  // Writes the pending samples as a (possibly short) chunk and hands everything to the OS.
  void flush();
  // Flushes and closes; further appends throw. Calling it twice is harmless.
  void close();

  std::size_t samples_written() const { return samples_written_; }  // appended, flushed or not
  const std::filesystem::path& file() const { return file_; }

 private:
  void write_pending_chunk();

  std::filesystem::path file_;
  std::size_t samples_per_chunk_;
  std::FILE* stream_ = nullptr;
  std::vector<std::byte> chunk_;  // chunk header + serialised pending samples
  std::size_t pending_samples_ = 0;
  std::size_t samples_written_ = 0;
  std::uint64_t bytes_written_ = 0;
  std::optional<double> last_time_;
  std::optional<CgStop> last_stop_;
};

// Throws TrajectoryError when the file is missing, empty, has a truncated header, is not a
// trajectory (bad magic) or has an unsupported version or flags. A truncated or corrupted chunk
// (bad magic, implausible sizes, checksum mismatch, or samples that fail validation: times
// decreasing, non-finite numbers, quaternion norm away from 1; CG stops out of order or of
// zero iterations) ends the read there: the samples and stops of the chunks before it are
// returned with report.complete = false.
Trajectory read_trajectory(const std::filesystem::path& file);

void write_trajectory(const std::filesystem::path& file, const std::vector<ToolSample>& samples,
                      std::size_t samples_per_chunk = 250);

// Header line time,x,y,z,qw,qx,qy,qz,buttons,fx,fy,fz then one row per sample, each number in
// its shortest form that parses back to the identical double (or float for the force).
void export_csv(const Trajectory& trajectory, std::ostream& out);
// The inverse, for trajectories authored as text (keyframes from a script, another
// simulator): the header "time,x,y,z,qw,qx,qy,qz,buttons" (optionally ",fx,fy,fz"), one sample
// per line, times strictly increasing, finite numbers, a non-zero quaternion (normalised
// here), buttons a non-negative integer. Throws TrajectoryError naming the line and column.
std::vector<ToolSample> import_csv(std::istream& in, const std::string& name);

// The tool at `time`: position and force interpolated linearly, orientation by slerp along the
// shorter arc, buttons of the sample at or before `time`. Outside the recorded range the time
// is clamped to it. Samples must be in non-decreasing time order (as read_trajectory returns
// them). Throws std::invalid_argument on an empty vector or a NaN time.
ToolSample sample_at(const std::vector<ToolSample>& samples, double time);

// The samples with t0 < time <= t1: the path swept since the previous step at t0, ending at
// this step at t1, with each sample belonging to exactly one step. Empty when t1 <= t0 or
// either bound is NaN. Samples must be in non-decreasing time order.
std::span<const ToolSample> samples_between(const std::vector<ToolSample>& samples, double t0,
                                            double t1);

}  // namespace incise::engine
