#include "engine/surface_file.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <limits>

namespace incise::engine::surface_text {

std::string read_whole_file(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw MeshError(file.string() + ": cannot open the file");
  std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw MeshError(file.string() + ": cannot read the file");
  return data;
}

void split_words(std::string_view line, std::vector<std::string_view>& words) {
  words.clear();
  for (std::size_t at = 0; at < line.size();) {
    const std::size_t begin = line.find_first_not_of(" \t", at);
    if (begin == std::string_view::npos) break;
    at = std::min(line.find_first_of(" \t", begin), line.size());
    words.push_back(line.substr(begin, at - begin));
  }
}

std::optional<std::string> control_character(std::string_view line) {
  for (std::size_t column = 0; column < line.size(); ++column) {
    const auto c = static_cast<unsigned char>(line[column]);
    if ((c < 0x20 && c != '\t') || c == 0x7f) {
      char code[8];
      std::snprintf(code, sizeof code, "0x%02x", c);
      return std::string("control character ") + code + " at column " + std::to_string(column + 1);
    }
  }
  return std::nullopt;
}

namespace {

// from_chars takes no '+'; a second sign after it is no number.
std::string_view without_plus(std::string_view word) {
  if (word.size() > 1 && word[0] == '+' && word[1] != '-' && word[1] != '+') word.remove_prefix(1);
  return word;
}

}  // namespace

std::optional<double> real(std::string_view word) {
  word = without_plus(word);
  double value = 0;
  const auto [end, error] = std::from_chars(word.data(), word.data() + word.size(), value);
  if (error != std::errc() || end != word.data() + word.size()) return std::nullopt;
  return value;
}

std::optional<std::int64_t> integer(std::string_view word) {
  word = without_plus(word);
  std::int64_t value = 0;
  const auto [end, error] = std::from_chars(word.data(), word.data() + word.size(), value);
  if (error != std::errc() || end != word.data() + word.size()) return std::nullopt;
  return value;
}

std::optional<double> single_precision(double value) {
  const auto single = static_cast<double>(static_cast<float>(value));
  if (!std::isfinite(single)) return std::nullopt;
  return single;
}

namespace {

// assimp's fast_atoreal_move<float> (assimp/fast_atof.h) on a word of digits, at most one '.',
// and an exponent; nullopt where it would have overflowed its integer (then the nearest float).
std::optional<float> assimp_float(std::string_view word) {
  std::size_t at = 0;
  const bool negative = at < word.size() && word[at] == '-';
  if (at < word.size() && (word[at] == '-' || word[at] == '+')) ++at;
  const auto digits = [&](std::size_t most, unsigned& taken) -> std::optional<std::uint64_t> {
    std::uint64_t value = 0;
    taken = 0;
    for (; at < word.size() && word[at] >= '0' && word[at] <= '9'; ++at)
      if (taken < most) {
        if (value > (std::numeric_limits<std::uint64_t>::max() - 9) / 10) return std::nullopt;
        value = value * 10 + static_cast<unsigned>(word[at] - '0');
        ++taken;
      }
    return value;
  };
  unsigned taken = 0;
  float f = 0;
  if (at < word.size() && word[at] != '.') {
    const auto whole = digits(~0u, taken);
    if (!whole) return std::nullopt;
    f = static_cast<float>(*whole);
  }
  if (at + 1 < word.size() && word[at] == '.' && word[at + 1] >= '0' && word[at + 1] <= '9') {
    ++at;
    static constexpr double tenths[16] = {0.0,   0.1,   0.01,   0.001,   1e-4,   1e-5,   1e-6,   1e-7,
                                          1e-8,  1e-9,  1e-10,  1e-11,   1e-12,  1e-13,  1e-14,  1e-15};
    const auto fraction = digits(15, taken);  // assimp's 15 relevant decimals
    f += static_cast<float>(static_cast<double>(*fraction) * tenths[taken]);
  } else if (at < word.size() && word[at] == '.') {
    ++at;
  }
  if (at < word.size() && (word[at] == 'e' || word[at] == 'E')) {
    ++at;
    const bool negative_exponent = at < word.size() && word[at] == '-';
    if (at < word.size() && (word[at] == '-' || word[at] == '+')) ++at;
    const auto exponent = digits(~0u, taken);
    if (!exponent) return std::nullopt;
    float e = static_cast<float>(*exponent);
    if (negative_exponent) e = -e;
    f *= std::pow(10.0f, e);
  }
  return negative ? -f : f;
}

}  // namespace

std::optional<double> single_as_assimp_read(std::string_view word) {
  const auto exact = real(word);
  if (!exact || !std::isfinite(*exact)) return std::nullopt;
  const auto f = assimp_float(word);
  if (!f || !std::isfinite(*f)) return single_precision(*exact);
  return static_cast<double>(*f);
}

std::string quote(std::string_view word) { return "'" + std::string(word.substr(0, 40)) + "'"; }

}  // namespace incise::engine::surface_text
