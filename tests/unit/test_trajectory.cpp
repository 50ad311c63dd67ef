#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <numbers>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "engine/trajectory.hpp"
#include "engine/trajectory_synth.hpp"

namespace incise::engine {
namespace {

namespace fs = std::filesystem;

constexpr std::size_t kChunkBytesFor100 = kChunkHeaderBytes + 100 * kSampleBytes;

// Deterministic but irregular samples: every field varies, quaternions are unit, times rise
// with occasional repeats (allowed: non-decreasing) so the round trip covers them too.
std::vector<ToolSample> make_samples(std::size_t count) {
  std::vector<ToolSample> samples(count);
  double time = 0;
  for (std::size_t i = 0; i < count; ++i) {
    ToolSample& s = samples[i];
    if (i % 97 != 0) time += 0.001;
    s.time = time;
    const double k = static_cast<double>(i);
    s.position = {0.1 * std::sin(k * 0.01), -0.05 + 1e-7 * k, std::cos(k * 0.013) / 3};
    const double angle = 0.002 * k;
    const double axis[3] = {0.6, 0.0, 0.8};
    s.orientation = {std::cos(angle / 2), axis[0] * std::sin(angle / 2),
                     axis[1] * std::sin(angle / 2), axis[2] * std::sin(angle / 2)};
    s.buttons = static_cast<std::uint32_t>(i * 2654435761u) & 0x7u;
    s.force = {static_cast<float>(k * 0.1f), -1.0f / 3.0f, static_cast<float>(std::sqrt(k))};
  }
  return samples;
}

bool bitwise_equal(const ToolSample& a, const ToolSample& b) {
  auto same = [](auto x, auto y) {
    using Bits = std::conditional_t<sizeof(x) == 8, std::uint64_t, std::uint32_t>;
    return std::bit_cast<Bits>(x) == std::bit_cast<Bits>(y);
  };
  bool equal = same(a.time, b.time) && a.buttons == b.buttons;
  for (int i = 0; i < 3; ++i) equal = equal && same(a.position[i], b.position[i]);
  for (int i = 0; i < 4; ++i) equal = equal && same(a.orientation[i], b.orientation[i]);
  for (int i = 0; i < 3; ++i) equal = equal && same(a.force[i], b.force[i]);
  return equal;
}

std::vector<std::byte> read_bytes(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::vector<char> chars((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<std::byte> bytes(chars.size());
  std::memcpy(bytes.data(), chars.data(), chars.size());
  return bytes;
}

void write_bytes(const fs::path& file, std::span<const std::byte> bytes) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
}

void put_u32(std::vector<std::byte>& bytes, std::size_t offset, std::uint32_t value) {
  for (int i = 0; i < 4; ++i) bytes[offset + i] = static_cast<std::byte>(value >> (8 * i));
}
void put_f64(std::vector<std::byte>& bytes, std::size_t offset, double value) {
  const auto bits = std::bit_cast<std::uint64_t>(value);
  for (int i = 0; i < 8; ++i) bytes[offset + i] = static_cast<std::byte>(bits >> (8 * i));
}
double get_f64(const std::vector<std::byte>& bytes, std::size_t offset) {
  std::uint64_t bits = 0;
  for (int i = 0; i < 8; ++i) bits |= std::to_integer<std::uint64_t>(bytes[offset + i]) << (8 * i);
  return std::bit_cast<double>(bits);
}

std::size_t chunk_offset(std::size_t chunk) {
  return kTrajectoryHeaderBytes + chunk * kChunkBytesFor100;
}

// Re-seals a chunk (of 100 samples) after a test edited its payload, so that only the
// sample validation can object to it.
void reseal_chunk(std::vector<std::byte>& bytes, std::size_t chunk) {
  const std::size_t start = chunk_offset(chunk);
  const std::uint32_t checksum = trajectory_checksum(
      std::span<const std::byte>(bytes).subspan(start + kChunkHeaderBytes, 100 * kSampleBytes));
  put_u32(bytes, start + 12, checksum);
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

class TrajectoryFile : public ::testing::Test {
 protected:
  void SetUp() override {
    // One directory per test and process: ctest runs the discovered tests in parallel.
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    directory_ = fs::temp_directory_path() / ("incise_trajectory_" + std::string(info->name()) +
                                              "_" + std::to_string(::getpid()));
    fs::remove_all(directory_);
    fs::create_directories(directory_);
  }
  void TearDown() override {
    std::error_code ignored;
    fs::remove_all(directory_, ignored);
  }
  fs::path path(const std::string& name) const { return directory_ / name; }

  // 1234 samples, 100 per chunk: 12 full chunks and one of 34.
  fs::path write_standard(const std::string& name = "standard.traj") {
    const fs::path file = path(name);
    write_trajectory(file, make_samples(1234), 100);
    return file;
  }

  fs::path directory_;
};

std::string error_of(const fs::path& file) {
  try {
    read_trajectory(file);
  } catch (const TrajectoryError& error) {
    return error.what();
  }
  return "(no TrajectoryError thrown)";
}

TEST(TrajectoryChecksum, MatchesTheStandardCheckValue) {
  const std::string text = "123456789";
  EXPECT_EQ(trajectory_checksum(std::as_bytes(std::span(text.data(), text.size()))), 0xCBF43926u);
  EXPECT_EQ(trajectory_checksum({}), 0u);
}

TEST_F(TrajectoryFile, RoundTripIsBitwiseExact) {
  const auto samples = make_samples(1234);
  const fs::path file = path("round.traj");
  write_trajectory(file, samples, 100);

  EXPECT_EQ(fs::file_size(file),
            kTrajectoryHeaderBytes + 13 * kChunkHeaderBytes + 1234 * kSampleBytes);
  const Trajectory read = read_trajectory(file);
  EXPECT_TRUE(read.report.complete) << read.report.problem;
  EXPECT_TRUE(read.report.problem.empty());
  EXPECT_EQ(read.report.chunks_read, 13u);
  EXPECT_EQ(read.report.samples_read, 1234u);
  EXPECT_EQ(read.report.bytes_discarded, 0u);
  ASSERT_EQ(read.samples.size(), samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i) {
    ASSERT_TRUE(bitwise_equal(read.samples[i], samples[i])) << "sample " << i;
  }
}

TEST_F(TrajectoryFile, FormatIsLittleEndianFieldByField) {
  ToolSample sample;
  sample.time = 1.5;  // 0x3FF8000000000000
  sample.buttons = 0x01020304;
  sample.force = {2.0f, 0, 0};  // 0x40000000
  const fs::path file = path("one.traj");
  write_trajectory(file, {sample});
  const auto bytes = read_bytes(file);
  ASSERT_EQ(bytes.size(), kTrajectoryHeaderBytes + kChunkHeaderBytes + kSampleBytes);
  EXPECT_EQ(std::memcmp(bytes.data(), "INCTRAJ\0", 8), 0);
  EXPECT_EQ(bytes[8], std::byte{2});    // version 2, low byte first
  EXPECT_EQ(bytes[12], std::byte{32});  // header size
  EXPECT_EQ(std::memcmp(bytes.data() + 32, "CHNK", 4), 0);
  EXPECT_EQ(bytes[36], std::byte{1});   // one sample
  EXPECT_EQ(bytes[40], std::byte{80});  // payload bytes
  const std::size_t payload = 32 + 16;
  EXPECT_EQ(bytes[payload + 7], std::byte{0x3F});
  EXPECT_EQ(bytes[payload + 6], std::byte{0xF8});
  EXPECT_EQ(bytes[payload + 32 + 6], std::byte{0xF0});  // orientation w = 1.0 = 0x3FF0...
  EXPECT_EQ(bytes[payload + 64], std::byte{0x04});
  EXPECT_EQ(bytes[payload + 67], std::byte{0x01});
  EXPECT_EQ(bytes[payload + 71], std::byte{0x40});
}

TEST_F(TrajectoryFile, EmptyRecordingIsAValidEmptyTrajectory) {
  const fs::path file = path("nothing.traj");
  write_trajectory(file, {});
  EXPECT_EQ(fs::file_size(file), kTrajectoryHeaderBytes);
  const Trajectory read = read_trajectory(file);
  EXPECT_TRUE(read.report.complete);
  EXPECT_TRUE(read.samples.empty());
}

TEST_F(TrajectoryFile, HeaderCutThrows) {
  const auto bytes = read_bytes(write_standard());
  for (std::size_t cut : {1u, 4u, 7u, 8u, 12u, 19u, 20u, 31u}) {
    const fs::path file = path("cut.traj");
    write_bytes(file, std::span(bytes).first(cut));
    const std::string message = error_of(file);
    EXPECT_TRUE(contains(message, "truncated header")) << "cut at " << cut << ": " << message;
    EXPECT_TRUE(contains(message, file.string())) << message;
  }
}

TEST_F(TrajectoryFile, ChunkCutKeepsTheGoodChunks) {
  const auto bytes = read_bytes(write_standard());
  const std::size_t last_chunk = chunk_offset(12);
  ASSERT_LT(last_chunk, bytes.size());
  for (std::size_t cut : {last_chunk + 1, last_chunk + 15, last_chunk + 16,
                          last_chunk + 16 + 80 * 5 + 3, bytes.size() - 1}) {
    const fs::path file = path("cut.traj");
    write_bytes(file, std::span(bytes).first(cut));
    const Trajectory read = read_trajectory(file);
    EXPECT_FALSE(read.report.complete) << "cut at " << cut;
    EXPECT_EQ(read.report.chunks_read, 12u);
    EXPECT_EQ(read.report.samples_read, 1200u);
    EXPECT_EQ(read.samples.size(), 1200u);
    EXPECT_EQ(read.report.bytes_discarded, cut - last_chunk);
    EXPECT_EQ(read.report.discarded_from, last_chunk);
    EXPECT_TRUE(read.report.torn_tail) << "cut at " << cut;  // what a crash mid-write leaves
    EXPECT_TRUE(contains(read.report.problem, "truncated")) << read.report.problem;
    EXPECT_TRUE(contains(read.report.problem, "chunk 12 at byte " + std::to_string(last_chunk)))
        << read.report.problem;
  }
  // Cut inside an earlier chunk too: everything from that chunk on is gone.
  const fs::path file = path("cut.traj");
  write_bytes(file, std::span(bytes).first(chunk_offset(5) + 100));
  const Trajectory read = read_trajectory(file);
  EXPECT_EQ(read.report.samples_read, 500u);
  EXPECT_TRUE(contains(read.report.problem, "chunk 5 at byte " + std::to_string(chunk_offset(5))));
}

TEST_F(TrajectoryFile, CutAtAChunkBoundaryReadsAsComplete) {
  // Documented limitation: a file cut exactly between chunks is indistinguishable from a
  // recording that ended there.
  const auto bytes = read_bytes(write_standard());
  const fs::path file = path("cut.traj");
  write_bytes(file, std::span(bytes).first(chunk_offset(7)));
  const Trajectory read = read_trajectory(file);
  EXPECT_TRUE(read.report.complete);
  EXPECT_EQ(read.samples.size(), 700u);
}

TEST_F(TrajectoryFile, FlippedBitStopsAtTheDamagedChunk) {
  auto bytes = read_bytes(write_standard());
  const std::size_t chunk3 = chunk_offset(3);
  bytes[chunk3 + kChunkHeaderBytes + 1234] ^= std::byte{0x10};
  const fs::path file = path("flipped.traj");
  write_bytes(file, bytes);

  const Trajectory read = read_trajectory(file);
  EXPECT_FALSE(read.report.complete);
  EXPECT_EQ(read.report.chunks_read, 3u);
  ASSERT_EQ(read.samples.size(), 300u);
  const auto original = make_samples(300);
  for (std::size_t i = 0; i < 300; ++i) EXPECT_TRUE(bitwise_equal(read.samples[i], original[i]));
  EXPECT_TRUE(contains(read.report.problem, "checksum mismatch")) << read.report.problem;
  EXPECT_FALSE(read.report.torn_tail);  // every byte is there: damage, not an interrupted write
  EXPECT_EQ(read.report.discarded_from, chunk3);
  EXPECT_TRUE(contains(read.report.problem, "chunk 3 at byte " + std::to_string(chunk3)));
  EXPECT_EQ(read.report.bytes_discarded, bytes.size() - chunk3);
  EXPECT_TRUE(contains(read.report.problem, std::to_string(bytes.size() - chunk3) + " bytes"));
}

TEST_F(TrajectoryFile, ImplausibleChunkSizesAreCorruptionNotAllocations) {
  const auto original = read_bytes(write_standard());
  struct Case {
    std::uint32_t count;
    std::uint32_t payload;
    const char* expected;
  };
  for (const Case& c :
       {Case{0xFFFFFFFFu, 0xFFFFFFFFu, "implausible sample count"},
        Case{1'000'001u, 80'000'080u, "implausible sample count"},
        Case{100u, 0xFFFFFFF0u, "does not match"}, Case{50'000u, 4'000'000u, "truncated"}}) {
    auto bytes = original;
    put_u32(bytes, chunk_offset(2) + 4, c.count);
    put_u32(bytes, chunk_offset(2) + 8, c.payload);
    const fs::path file = path("sizes.traj");
    write_bytes(file, bytes);
    const Trajectory read = read_trajectory(file);
    EXPECT_FALSE(read.report.complete);
    EXPECT_EQ(read.samples.size(), 200u);
    EXPECT_TRUE(contains(read.report.problem, c.expected)) << read.report.problem;
  }
}

TEST_F(TrajectoryFile, BadChunkMagicIsCorruption) {
  auto bytes = read_bytes(write_standard());
  bytes[chunk_offset(4)] = std::byte{'X'};
  const fs::path file = path("magic.traj");
  write_bytes(file, bytes);
  const Trajectory read = read_trajectory(file);
  EXPECT_EQ(read.samples.size(), 400u);
  EXPECT_TRUE(contains(read.report.problem, "bad chunk magic")) << read.report.problem;
}

TEST_F(TrajectoryFile, EmptyFileThrows) {
  const fs::path file = path("empty.traj");
  write_bytes(file, {});
  const std::string message = error_of(file);
  EXPECT_TRUE(contains(message, "empty")) << message;
  EXPECT_TRUE(contains(message, file.string())) << message;
}

TEST_F(TrajectoryFile, MissingFileThrowsNamingThePath) {
  const fs::path file = path("does_not_exist.traj");
  const std::string message = error_of(file);
  EXPECT_TRUE(contains(message, file.string())) << message;
  EXPECT_TRUE(contains(message, "cannot open")) << message;
}

TEST_F(TrajectoryFile, BadMagicThrows) {
  const fs::path file = path("foreign.traj");
  const std::string text = "time,x,y,z\n0,1,2,3\n";
  write_bytes(file, std::as_bytes(std::span(text.data(), text.size())));
  const std::string message = error_of(file);
  EXPECT_TRUE(contains(message, "bad magic")) << message;
  EXPECT_TRUE(contains(message, "at byte 0")) << message;
}

TEST_F(TrajectoryFile, UnsupportedVersionThrows) {
  auto bytes = read_bytes(write_standard());
  put_u32(bytes, 8, 3);
  const fs::path file = path("future.traj");
  write_bytes(file, bytes);
  const std::string message = error_of(file);
  EXPECT_TRUE(contains(message, "unsupported version 3")) << message;
  EXPECT_TRUE(contains(message, "at byte 8")) << message;
}

TEST_F(TrajectoryFile, UnknownFlagsAndOddHeaderSizes) {
  const auto original = read_bytes(write_standard());
  auto flagged = original;
  put_u32(flagged, 16, 1);
  write_bytes(path("flags.traj"), flagged);
  EXPECT_TRUE(contains(error_of(path("flags.traj")), "unsupported flags"));

  auto tiny_header = original;
  put_u32(tiny_header, 12, 4);
  write_bytes(path("tiny.traj"), tiny_header);
  EXPECT_TRUE(contains(error_of(path("tiny.traj")), "invalid header size"));

  // A longer header from a later writer of version 1 is skipped over.
  auto longer = original;
  put_u32(longer, 12, 40);
  longer.insert(longer.begin() + 32, 8, std::byte{0xAB});
  write_bytes(path("longer.traj"), longer);
  const Trajectory read = read_trajectory(path("longer.traj"));
  EXPECT_TRUE(read.report.complete) << read.report.problem;
  EXPECT_EQ(read.samples.size(), 1234u);
}

TEST_F(TrajectoryFile, InvalidSamplesInAValidChunkAreCorruption) {
  const auto original = read_bytes(write_standard());
  const std::size_t sample5 = chunk_offset(2) + kChunkHeaderBytes + 5 * kSampleBytes;
  struct Case {
    const char* name;
    std::size_t offset;  // within sample 5 of chunk 2
    double value;
    const char* expected;
  };
  const double earlier = get_f64(original, sample5 - kSampleBytes) - 1.0;
  for (const Case& c :
       {Case{"time goes back", 0, earlier, "earlier than the previous sample"},
        Case{"nan position", 8 + 8, std::nan(""), "position[1]"},
        Case{"infinite time", 0, std::numeric_limits<double>::infinity(), "time is inf"},
        Case{"quaternion not unit", 32, 0.5, "orientation has norm"}}) {
    auto bytes = original;
    put_f64(bytes, sample5 + c.offset, c.value);
    reseal_chunk(bytes, 2);
    const fs::path file = path("invalid.traj");
    write_bytes(file, bytes);
    const Trajectory read = read_trajectory(file);
    EXPECT_FALSE(read.report.complete) << c.name;
    EXPECT_EQ(read.samples.size(), 200u) << c.name;
    const std::string& problem = read.report.problem;
    EXPECT_TRUE(contains(problem, "chunk 2")) << problem;
    EXPECT_TRUE(contains(problem, "sample 5 of the chunk (sample 205 of the file)")) << problem;
    EXPECT_TRUE(contains(problem, c.expected)) << problem;
  }
}

TEST_F(TrajectoryFile, TimeGoingBackAcrossAChunkBoundaryIsCorruption) {
  auto bytes = read_bytes(write_standard());
  // First sample of chunk 4 before the last of chunk 3, and the rest of chunk 4 with it.
  for (int i = 0; i < 100; ++i) {
    const std::size_t offset = chunk_offset(4) + kChunkHeaderBytes + i * kSampleBytes;
    put_f64(bytes, offset, get_f64(bytes, offset) - 10.0);
  }
  reseal_chunk(bytes, 4);
  const fs::path file = path("back.traj");
  write_bytes(file, bytes);
  const Trajectory read = read_trajectory(file);
  EXPECT_EQ(read.samples.size(), 400u);
  EXPECT_TRUE(contains(read.report.problem, "sample 0 of the chunk")) << read.report.problem;
}

TEST_F(TrajectoryFile, WriterFlushesEachChunkWhileStillOpen) {
  const fs::path file = path("live.traj");
  const auto samples = make_samples(250);
  TrajectoryWriter writer(file, 100);
  EXPECT_EQ(read_trajectory(file).samples.size(), 0u);  // header alone is already there
  for (const ToolSample& sample : samples) writer.append(sample);
  EXPECT_EQ(writer.samples_written(), 250u);

  Trajectory live = read_trajectory(file);
  EXPECT_TRUE(live.report.complete) << live.report.problem;
  EXPECT_EQ(live.report.chunks_read, 2u);
  ASSERT_EQ(live.samples.size(), 200u);
  EXPECT_TRUE(bitwise_equal(live.samples.back(), samples[199]));

  writer.flush();  // the partial chunk of 50
  live = read_trajectory(file);
  EXPECT_EQ(live.report.chunks_read, 3u);
  EXPECT_EQ(live.samples.size(), 250u);
  writer.flush();  // nothing pending: must not write an empty chunk
  EXPECT_EQ(read_trajectory(file).report.chunks_read, 3u);
  writer.close();
  writer.close();
  EXPECT_EQ(read_trajectory(file).samples.size(), 250u);
  EXPECT_THROW(writer.append(samples[0]), std::logic_error);
}

TEST_F(TrajectoryFile, DestructorClosesAndWritesThePartialChunk) {
  const fs::path file = path("scoped.traj");
  {
    TrajectoryWriter writer(file, 100);
    for (const ToolSample& sample : make_samples(130)) writer.append(sample);
  }
  EXPECT_EQ(read_trajectory(file).samples.size(), 130u);
}

TEST_F(TrajectoryFile, WriterRejectsSamplesItsReaderWouldReject) {
  TrajectoryWriter writer(path("strict.traj"), 10);
  ToolSample sample;
  sample.time = 1.0;
  writer.append(sample);
  ToolSample earlier = sample;
  earlier.time = 0.5;
  EXPECT_THROW(writer.append(earlier), std::invalid_argument);
  ToolSample not_unit = sample;
  not_unit.orientation = {1, 1, 0, 0};
  EXPECT_THROW(writer.append(not_unit), std::invalid_argument);
  ToolSample nan_force = sample;
  nan_force.force[2] = std::nanf("");
  EXPECT_THROW(writer.append(nan_force), std::invalid_argument);
  writer.append(sample);  // equal times are allowed
  EXPECT_EQ(writer.samples_written(), 2u);
  EXPECT_THROW(TrajectoryWriter(path("zero.traj"), 0), std::invalid_argument);
  EXPECT_THROW(TrajectoryWriter(directory_ / "no_such_dir" / "x.traj"), TrajectoryError);
}

TEST_F(TrajectoryFile, CsvExportRoundTripsEveryNumber) {
  Trajectory trajectory;
  ToolSample awkward;
  awkward.time = 0.1;
  awkward.position = {std::numbers::pi, -0.0, 1e-300};
  const double s = std::sqrt(0.5);
  awkward.orientation = {s, 0, -s, 0};
  awkward.buttons = 4294967295u;
  awkward.force = {0.1f, -3.4028235e38f, 1e-45f};
  trajectory.samples = {ToolSample{}, awkward};
  std::ostringstream out;
  export_csv(trajectory, out);

  std::istringstream in(out.str());
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "time,x,y,z,qw,qx,qy,qz,buttons,fx,fy,fz");
  std::getline(in, line);
  EXPECT_EQ(line, "0,0,0,0,1,0,0,0,0,0,0,0");
  std::getline(in, line);
  std::vector<std::string> fields;
  std::stringstream row(line);
  for (std::string field; std::getline(row, field, ',');) fields.push_back(field);
  ASSERT_EQ(fields.size(), 12u) << line;
  auto number = [&](int i) { return std::strtod(fields[i].c_str(), nullptr); };
  ToolSample parsed;
  parsed.time = number(0);
  for (int i = 0; i < 3; ++i) parsed.position[i] = number(1 + i);
  for (int i = 0; i < 4; ++i) parsed.orientation[i] = number(4 + i);
  parsed.buttons = static_cast<std::uint32_t>(std::strtoul(fields[8].c_str(), nullptr, 10));
  for (int i = 0; i < 3; ++i) parsed.force[i] = std::strtof(fields[9 + i].c_str(), nullptr);
  EXPECT_TRUE(bitwise_equal(parsed, awkward)) << line;
  EXPECT_FALSE(std::getline(in, line));
}

TEST(TrajectorySampleAt, InterpolatesAtTheMidpoint) {
  ToolSample a;
  a.time = 1.0;
  a.position = {0, 0, 0};
  a.force = {0, 2, 0};
  a.buttons = 1;
  ToolSample b;
  b.time = 2.0;
  b.position = {2, -4, 6};
  b.force = {1, 0, 0};
  b.buttons = 0;
  // a quarter turn about z between the two
  b.orientation = {std::cos(std::numbers::pi / 4), 0, 0, std::sin(std::numbers::pi / 4)};
  const std::vector<ToolSample> samples{a, b};

  const ToolSample middle = sample_at(samples, 1.5);
  EXPECT_DOUBLE_EQ(middle.time, 1.5);
  EXPECT_DOUBLE_EQ(middle.position[0], 1);
  EXPECT_DOUBLE_EQ(middle.position[1], -2);
  EXPECT_DOUBLE_EQ(middle.position[2], 3);
  EXPECT_FLOAT_EQ(middle.force[0], 0.5f);
  EXPECT_FLOAT_EQ(middle.force[1], 1.0f);
  EXPECT_EQ(middle.buttons, 1u);
  // Halfway through a quarter turn is an eighth turn, and of unit length.
  EXPECT_NEAR(middle.orientation[0], std::cos(std::numbers::pi / 8), 1e-12);
  EXPECT_NEAR(middle.orientation[3], std::sin(std::numbers::pi / 8), 1e-12);
  for (double t = 1.0; t <= 2.0; t += 0.0625) {
    const auto q = sample_at(samples, t).orientation;
    EXPECT_NEAR(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3], 1.0, 1e-12) << t;
  }
  EXPECT_EQ(sample_at(samples, 2.0).buttons, 0u);
}

TEST(TrajectorySampleAt, ClampsOutsideTheRange) {
  const auto samples = make_samples(10);
  EXPECT_TRUE(bitwise_equal(sample_at(samples, -5.0), samples.front()));
  EXPECT_TRUE(bitwise_equal(sample_at(samples, 1e9), samples.back()));
  EXPECT_TRUE(bitwise_equal(sample_at(samples, samples[4].time), samples[4]));
  EXPECT_THROW(sample_at({}, 0.0), std::invalid_argument);
  EXPECT_THROW(sample_at(samples, std::nan("")), std::invalid_argument);
}

TEST(TrajectorySampleAt, TakesTheShortArcBetweenOppositeSignQuaternions) {
  ToolSample a;
  a.time = 0;
  a.orientation = {std::cos(0.1), std::sin(0.1), 0, 0};
  ToolSample b = a;
  b.time = 1;
  // The same rotation with the opposite sign: a naive blend would pass through zero.
  for (double& component : b.orientation) component = -component;
  const ToolSample middle = sample_at({a, b}, 0.5);
  const double dot =
      middle.orientation[0] * a.orientation[0] + middle.orientation[1] * a.orientation[1];
  EXPECT_NEAR(std::abs(dot), 1.0, 1e-12);
}

TEST(TrajectorySampleAt, LastOfEqualTimesWins) {
  ToolSample a;
  a.time = 0;
  ToolSample b;
  b.time = 1;
  b.buttons = 1;
  ToolSample c = b;
  c.buttons = 2;
  c.position = {1, 0, 0};
  ToolSample d;
  d.time = 2;
  const std::vector<ToolSample> samples{a, b, c, d};
  EXPECT_EQ(sample_at(samples, 1.0).buttons, 2u);
  EXPECT_EQ(sample_at(samples, 1.5).buttons, 2u);
  EXPECT_DOUBLE_EQ(sample_at(samples, 1.5).position[0], 0.5);
}

TEST(TrajectorySamplesBetween, HalfOpenInterval) {
  std::vector<ToolSample> samples(5);
  for (int i = 0; i < 5; ++i) samples[i].time = i;  // 0 1 2 3 4
  auto times = [&](double t0, double t1) {
    std::vector<double> result;
    for (const ToolSample& s : samples_between(samples, t0, t1)) result.push_back(s.time);
    return result;
  };
  EXPECT_EQ(times(1, 3), (std::vector<double>{2, 3}));
  EXPECT_EQ(times(0.5, 1), (std::vector<double>{1}));
  EXPECT_EQ(times(-1, 0), (std::vector<double>{0}));
  EXPECT_EQ(times(4, 10), (std::vector<double>{}));
  EXPECT_EQ(times(3, 3), (std::vector<double>{}));
  EXPECT_EQ(times(3, 1), (std::vector<double>{}));
  EXPECT_EQ(times(2.25, 2.75), (std::vector<double>{}));
  const double infinity = std::numeric_limits<double>::infinity();
  EXPECT_EQ(times(-infinity, infinity), (std::vector<double>{0, 1, 2, 3, 4}));
  EXPECT_TRUE(samples_between(samples, std::nan(""), 3).empty());
  EXPECT_TRUE(samples_between({}, 0, 1).empty());
  // Consecutive steps partition the samples: none missed, none twice.
  std::size_t seen = 0;
  for (double t = -0.3; t < 5; t += 0.7) seen += samples_between(samples, t, t + 0.7).size();
  EXPECT_EQ(seen, 5u);
  EXPECT_EQ(samples_between(samples, 1, 3).data(), samples.data() + 2);
}

TEST(TrajectorySynth, PokeIsContinuousBoundedAndPressedOnlyInside) {
  PokeSpec spec;
  spec.approach_point = {0.01, 0.06, -0.02};
  spec.contact_point = {0.01, 0.01, -0.02};
  spec.depth = 0.004;
  spec.stroke = {0.03, 0.5, 0};  // the part along the approach axis (y) must be dropped
  const auto samples = synthesize_poke(spec);

  const double total = spec.approach_seconds + spec.press_seconds + spec.hold_seconds +
                       spec.stroke_seconds + spec.release_seconds;
  ASSERT_EQ(samples.size(), static_cast<std::size_t>(std::llround(total * spec.rate_hz)) + 1);
  EXPECT_EQ(samples.front().position, spec.approach_point);
  EXPECT_DOUBLE_EQ(samples.back().time, total);
  EXPECT_NEAR(samples.back().position[0], 0.04, 1e-12);
  EXPECT_NEAR(samples.back().position[1], 0.06, 1e-12);

  // Smoothstep peaks at 1.5 times the mean speed of a phase; the release is the fastest.
  const double fastest = 1.5 * (0.05 + 0.004) / spec.release_seconds;
  const double largest_acceleration = 6 * 0.054 / (spec.release_seconds * spec.release_seconds);
  const double dt = 1 / spec.rate_hz;
  double deepest = 0;
  std::size_t pressed = 0;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const ToolSample& s = samples[i];
    EXPECT_EQ(s.orientation, (std::array<double, 4>{1, 0, 0, 0}));
    const double depth = spec.contact_point[1] - s.position[1];
    deepest = std::max(deepest, depth);
    const bool inside = depth > 1e-9;
    if (std::abs(depth) > 1e-9) {
      EXPECT_EQ((s.buttons & kToolButtonEngaged) != 0, inside) << "sample " << i;
    }
    if (s.buttons & kToolButtonEngaged) {
      EXPECT_GT(depth, 0) << "sample " << i;
    }
    pressed += (s.buttons & kToolButtonEngaged) ? 1 : 0;
    EXPECT_EQ(s.position[2], -0.02) << "the stroke has no z part, so z never moves";
    if (i == 0) continue;
    const ToolSample& p = samples[i - 1];
    EXPECT_NEAR(s.time - p.time, dt, 1e-12);
    double step = 0;
    for (int k = 0; k < 3; ++k)
      step += (s.position[k] - p.position[k]) * (s.position[k] - p.position[k]);
    EXPECT_LE(std::sqrt(step) / dt, fastest * 1.0001) << "sample " << i;
    if (i < 2) continue;
    const ToolSample& pp = samples[i - 2];
    for (int k = 0; k < 3; ++k) {
      // A velocity jump (a C1 break) would show up as a second difference of order v * dt.
      const double second = s.position[k] - 2 * p.position[k] + pp.position[k];
      EXPECT_LE(std::abs(second) / (dt * dt), largest_acceleration * 1.01) << "sample " << i;
    }
  }
  EXPECT_NEAR(deepest, spec.depth, 1e-12);
  // Pressed through the press, hold and stroke phases at least.
  EXPECT_GT(pressed,
            static_cast<std::size_t>(
                (spec.press_seconds + spec.hold_seconds + spec.stroke_seconds) * spec.rate_hz));
  EXPECT_EQ(samples.front().buttons, 0u);
  EXPECT_EQ(samples.back().buttons, 0u);

  // Deterministic, and acceptable to the writer.
  const auto again = synthesize_poke(spec);
  ASSERT_EQ(again.size(), samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i) ASSERT_TRUE(bitwise_equal(again[i], samples[i]));
}

TEST_F(TrajectoryFile, SynthesizedPokeWritesAndReadsBack) {
  const auto samples = synthesize_poke(PokeSpec{});
  write_trajectory(path("poke.traj"), samples);
  const Trajectory read = read_trajectory(path("poke.traj"));
  EXPECT_TRUE(read.report.complete) << read.report.problem;
  EXPECT_EQ(read.samples, samples);
}

TEST(TrajectorySynth, RejectsUnusableSpecs) {
  PokeSpec same_points;
  same_points.contact_point = same_points.approach_point;
  EXPECT_THROW(synthesize_poke(same_points), std::invalid_argument);
  PokeSpec instant_press;
  instant_press.press_seconds = 0;
  EXPECT_THROW(synthesize_poke(instant_press), std::invalid_argument);
  PokeSpec no_hold;
  no_hold.hold_seconds = 0;  // a phase that does not move may take no time
  EXPECT_NO_THROW(synthesize_poke(no_hold));
  PokeSpec negative;
  negative.depth = -1;
  EXPECT_THROW(synthesize_poke(negative), std::invalid_argument);
  PokeSpec huge;
  huge.stroke_seconds = 1e9;
  EXPECT_THROW(synthesize_poke(huge), std::invalid_argument);
  PokeSpec bad_rate;
  bad_rate.rate_hz = 0;
  EXPECT_THROW(synthesize_poke(bad_rate), std::invalid_argument);
}

// Version 2 (issue 29): the CG stops of a real-time session, in chunks of their own between the
// samples', read back in order; a version-1 file (written before them) still reads, and
// holds no CGST chunk; stops out of order are refused by the writer and end the read.
TEST_F(TrajectoryFile, CgStopsRoundTripBesideTheSamplesAndVersionOneStillReads) {
  const fs::path file = path("stops.traj");
  std::vector<ToolSample> samples(7);
  for (std::size_t i = 0; i < samples.size(); ++i) samples[i].time = 0.001 * static_cast<double>(i);
  const std::vector<CgStop> first{{1, 0, 3}, {1, 2, 5}}, second{{4, 0, 7}};
  {
    TrajectoryWriter writer(file, 3);
    for (std::size_t i = 0; i < 4; ++i) writer.append(samples[i]);
    writer.append_cg_stops(first);
    for (std::size_t i = 4; i < samples.size(); ++i) writer.append(samples[i]);
    writer.append_cg_stops(second);
    EXPECT_THROW(writer.append_cg_stops(std::vector<CgStop>{{4, 0, 2}}), std::invalid_argument);  // not after {4, 0}
    EXPECT_THROW(writer.append_cg_stops(std::vector<CgStop>{{5, 0, 0}}), std::invalid_argument);  // no iteration
    writer.close();
  }
  const Trajectory read = read_trajectory(file);
  EXPECT_TRUE(read.report.complete) << read.report.problem;
  EXPECT_EQ(read.samples, samples);
  const std::vector<CgStop> all{{1, 0, 3}, {1, 2, 5}, {4, 0, 7}};
  EXPECT_EQ(read.cg_stops, all);
  EXPECT_EQ(read.report.cg_stops_read, 3u);

  // The same bytes as version 1: a CGST chunk is not a chunk of version 1.
  auto bytes = read_bytes(file);
  put_u32(bytes, 8, 1);
  write_bytes(path("v1.traj"), bytes);
  const Trajectory v1 = read_trajectory(path("v1.traj"));
  EXPECT_FALSE(v1.report.complete);
  EXPECT_TRUE(contains(v1.report.problem, "bad chunk magic")) << v1.report.problem;
  EXPECT_TRUE(v1.cg_stops.empty());

  // A stop going back in time, re-sealed so only the validation can object: the read ends there.
  bytes = read_bytes(file);
  const std::size_t second_stops = kTrajectoryHeaderBytes + (kChunkHeaderBytes + 3 * kSampleBytes) +
                                   (kChunkHeaderBytes + 2 * kCgStopBytes) + (kChunkHeaderBytes + 3 * kSampleBytes);
  ASSERT_EQ(std::memcmp(bytes.data() + second_stops, "CGST", 4), 0);
  bytes[second_stops + kChunkHeaderBytes] = std::byte{1};  // step 4 -> 1
  put_u32(bytes, second_stops + 12,
          trajectory_checksum(std::span<const std::byte>(bytes).subspan(second_stops + kChunkHeaderBytes, kCgStopBytes)));
  write_bytes(path("back.traj"), bytes);
  const Trajectory back = read_trajectory(path("back.traj"));
  EXPECT_FALSE(back.report.complete);
  EXPECT_TRUE(contains(back.report.problem, "invalid CG stop")) << back.report.problem;
  EXPECT_EQ(back.cg_stops, first);
  EXPECT_EQ(back.samples.size(), 6u);
}

}  // namespace
// fuzz_trajectory_csv found both: a quaternion whose sum of squares overflows was imported as
// zero, and a force beyond a float's range as infinity; the writer refuses either sample.
TEST(TrajectoryImportCsv, LargeQuaternionIsNormalisedAndLargeForceRefused) {
  std::istringstream large("time,x,y,z,qw,qx,qy,qz,buttons\n0,0,0,0,1e200,1e200,0,0,1\n");
  const auto samples = import_csv(large, "large.csv");
  ASSERT_EQ(samples.size(), 1u);
  EXPECT_NEAR(samples[0].orientation[0], std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(samples[0].orientation[1], std::sqrt(0.5), 1e-15);
  EXPECT_EQ(samples[0].buttons, 1u);

  std::istringstream force("time,x,y,z,qw,qx,qy,qz,buttons,fx,fy,fz\n0,0,0,0,1,0,0,0,0,0,0,0\n1,0,0,0,1,0,0,0,0,0,-1e300,0\n");
  try {
    import_csv(force, "force.csv");
    FAIL() << "accepted a force of -1e300 N";
  } catch (const TrajectoryError& e) {
    EXPECT_EQ(std::string(e.what()), "trajectory file 'force.csv': line 3, column 11 (fy): -1e+300 N is beyond a float's range");
  }
  std::istringstream zero("time,x,y,z,qw,qx,qy,qz,buttons\n0,0,0,0,0,0,0,0,0\n");
  EXPECT_THROW(import_csv(zero, "zero.csv"), TrajectoryError);
}

}  // namespace incise::engine
