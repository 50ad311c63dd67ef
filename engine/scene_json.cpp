// Scene text -> JSON, with every failure placed: line and column, and the field being read
// where there is one. nlohmann's own exceptions name neither the line (a number out of range)
// nor the key, so the text is parsed through its SAX interface, which reports the byte of any
// failure, with a handler that keeps the path of keys and indices to the value being read.
#include "engine/scene_reader.hpp"

#include <string>
#include <vector>

namespace incise::engine {

namespace {

// Line and column (both from 1) of the byte at `offset`.
std::string line_and_column(const std::string& text, std::size_t offset) {
  offset = std::min(offset, text.size());
  std::size_t line = 1, line_start = 0;
  for (std::size_t i = 0; i < offset; ++i)
    if (text[i] == '\n') {
      ++line;
      line_start = i + 1;
    }
  return "line " + std::to_string(line) + ", column " + std::to_string(offset - line_start + 1);
}

// The first object or array opened deeper than kSceneMaxDepth, found before parsing so that
// no tree that deep is built: its byte offset, or npos.
std::size_t too_deep_at(const std::string& text) {
  int depth = 0;
  bool in_string = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\') ++i;
      else if (c == '"') in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '{' || c == '[') {
      if (++depth > kSceneMaxDepth) return i;
    } else if (c == '}' || c == ']') {
      --depth;
    }
  }
  return std::string::npos;
}

// Builds the tree (nlohmann's DOM builder) and keeps the path of the value being parsed.
class PlacingParser {
 public:
  using Dom = nlohmann::detail::json_sax_dom_parser<Json>;

  explicit PlacingParser(Json& root) : dom_(root, false) {}

  bool null() { return next() && dom_.null(); }
  bool boolean(bool v) { return next() && dom_.boolean(v); }
  bool number_integer(Json::number_integer_t v) { return next() && dom_.number_integer(v); }
  bool number_unsigned(Json::number_unsigned_t v) { return next() && dom_.number_unsigned(v); }
  bool number_float(Json::number_float_t v, const Json::string_t& s) { return next() && dom_.number_float(v, s); }
  bool string(Json::string_t& v) { return next() && dom_.string(v); }
  bool binary(Json::binary_t& v) { return next() && dom_.binary(v); }
  bool start_object(std::size_t n) {
    next();
    frames_.push_back({false, "", -1});
    return dom_.start_object(n);
  }
  bool key(Json::string_t& k) {
    frames_.back().key = k;
    return dom_.key(k);
  }
  bool end_object() {
    frames_.pop_back();
    return dom_.end_object();
  }
  bool start_array(std::size_t n) {
    next();
    frames_.push_back({true, "", -1});
    return dom_.start_array(n);
  }
  bool end_array() {
    frames_.pop_back();
    return dom_.end_array();
  }
  template <class Exception>
  bool parse_error(std::size_t byte, const std::string& token, const Exception& e) {
    byte_ = byte;
    token_ = token;
    id_ = e.id;
    message_ = e.what();
    // The message after nlohmann's "[json.exception.parse_error.101] parse error at line 1,
    // column 2: " prefix: the place is given in our own words.
    if (const auto colon = message_.find(": "); id_ == 101 && colon != std::string::npos) message_.erase(0, colon + 2);
    else if (const auto bracket = message_.find("] "); bracket != std::string::npos) message_.erase(0, bracket + 2);
    // The element of an array being read when it failed is the one after the last complete.
    if (!frames_.empty() && frames_.back().array) ++frames_.back().index;
    path_ = path();
    return dom_.parse_error(byte, token, e);
  }

  std::string error(const std::string& text) const {
    // nlohmann counts the bytes read: a number is placed at its first digit, anything else at
    // the byte that failed.
    const std::size_t at = id_ == 406 ? byte_ - std::min(byte_, token_.size()) : byte_ > 0 ? byte_ - 1 : 0;
    const std::string place = line_and_column(text, at);
    const std::string field = path_.empty() ? "(top level)" : path_;
    if (id_ == 406)  // out_of_range.406: a number beyond a double's range
      return field + ": number " + token_ + " is out of range (" + place + ")";
    return place + ": not valid JSON: " + message_ + (path_.empty() ? "" : " (near " + path_ + ")");
  }

 private:
  struct Frame {
    bool array;
    std::string key;
    long index;
  };

  bool next() {
    if (!frames_.empty() && frames_.back().array) ++frames_.back().index;
    return true;
  }

  std::string path() const {
    std::string p;
    for (const Frame& f : frames_) {
      if (f.array) p += "[" + std::to_string(std::max(0L, f.index)) + "]";
      else if (!f.key.empty()) p += (p.empty() ? "" : ".") + f.key;
    }
    return p;
  }

  Dom dom_;
  std::vector<Frame> frames_;
  std::size_t byte_ = 0;
  std::string token_, message_, path_;
  int id_ = 0;
};

}  // namespace

Json parse_scene_json(const std::string& text, std::vector<std::string>& errors) {
  if (const std::size_t at = too_deep_at(text); at != std::string::npos) {
    errors.push_back(line_and_column(text, at) + ": nested deeper than " + std::to_string(kSceneMaxDepth) +
                     " levels (a scene needs a handful)");
    return {};
  }
  Json root;
  PlacingParser parser(root);
  if (!Json::sax_parse(text, &parser)) {
    errors.push_back(parser.error(text));
    return {};
  }
  return root;
}

}  // namespace incise::engine
