// The scene reader: one JSON object read key by key, every problem recorded with the field's
// path (`bodies[0].material.nu: ...`). engine/scene.cpp reads the scene with it; it is a header
// of its own so that a part of a scene read elsewhere (a deformable model's settings block)
// reports its errors like every other field.
#pragma once

#include "engine/scene.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace incise::engine {

using Json = nlohmann::json;

// A scene nests a handful of levels (bodies[0].generator.min); deeper text is refused before
// it is parsed.
inline constexpr int kSceneMaxDepth = 32;

// Parses scene text (engine/scene_json.cpp). On failure returns null and adds one error naming
// the line and column, and the field being read where there is one (`solver.dt: number 1e400
// is out of range (line 5, column 18)`).
Json parse_scene_json(const std::string& text, std::vector<std::string>& errors);

inline std::string number_text(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

// What a value is, for messages about the wrong type: "a string", "an array of 2", "null".
inline std::string kind_of(const Json& v) {
  if (v.is_array()) return "an array of " + std::to_string(v.size());
  if (v.is_object()) return "an object";
  if (v.is_string()) return "a string";
  if (v.is_boolean()) return v.get<bool>() ? "true" : "false";
  if (v.is_null()) return "null";
  if (v.is_number_integer()) return v.dump();
  if (v.is_number()) return number_text(v.get<double>());
  return v.type_name();
}

// Reads one JSON object, remembering which keys were consumed so the rest can be
// reported as unknown. Every accessor records an error and returns a neutral value
// rather than throwing, so one pass lists all the problems of a file.
class Reader {
 public:
  Reader(const Json& node, std::string path, std::vector<std::string>& errors)
      : node_(node), path_(std::move(path)), errors_(errors) {
    if (!node_.is_object()) error(path_, "must be an object, not " + kind_of(node_));
  }

  ~Reader() {
    if (!node_.is_object()) return;
    for (const auto& [key, value] : node_.items()) {
      if (!used_.count(key)) error(child(key), "unknown key");
    }
  }

  bool has(const std::string& key) const { return node_.is_object() && node_.contains(key); }
  std::string child(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  const std::string& path() const { return path_; }
  // The shared error list, for a Reader of a nested block (its errors go with this one's).
  std::vector<std::string>& errors() { return errors_; }

  const Json* get(const std::string& key, bool required) {
    used_.insert(key);
    if (!node_.is_object()) return nullptr;
    auto it = node_.find(key);
    if (it == node_.end()) {
      if (required) error(child(key), "is required");
      return nullptr;
    }
    return &*it;
  }

  // A finite number in [lo, hi] (hi_open: [lo, hi)); lo_open likewise.
  double number(const std::string& key, bool required, double fallback, double lo, double hi,
                bool lo_open = false, bool hi_open = false) {
    const Json* v = get(key, required);
    if (!v) return fallback;
    if (!v->is_number()) {
      error(child(key), "must be a number, not " + kind_of(*v));
      return fallback;
    }
    double x = v->get<double>();
    bool below = lo_open ? !(x > lo) : !(x >= lo);
    bool above = hi_open ? !(x < hi) : !(x <= hi);
    if (!std::isfinite(x) || below || above) {
      error(child(key), number_text(x) + " must be in " + (lo_open ? "(" : "[") + number_text(lo) +
                            ", " + number_text(hi) + (hi_open ? ")" : "]"));
      return fallback;
    }
    return x;
  }

  int integer(const std::string& key, bool required, int fallback, int lo, int hi) {
    const Json* v = get(key, required);
    if (!v) return fallback;
    if (!v->is_number_integer()) {
      error(child(key), "must be an integer, not " + kind_of(*v));
      return fallback;
    }
    // An unsigned value beyond long long's range would wrap to a negative one.
    const bool too_large = v->is_number_unsigned() && (hi < 0 || v->get<unsigned long long>() > static_cast<unsigned long long>(hi));
    const auto x = too_large ? 0LL : v->get<long long>();
    if (too_large || x < lo || x > hi) {
      error(child(key), v->dump() + " must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
      return fallback;
    }
    return static_cast<int>(x);
  }

  bool boolean(const std::string& key, bool fallback) {
    const Json* v = get(key, false);
    if (!v) return fallback;
    if (!v->is_boolean()) {
      error(child(key), "must be true or false, not " + kind_of(*v));
      return fallback;
    }
    return v->get<bool>();
  }

  std::string text(const std::string& key, bool required, const std::string& fallback,
                   const std::vector<std::string>& allowed = {}) {
    const Json* v = get(key, required);
    if (!v) return fallback;
    if (!v->is_string()) {
      error(child(key), "must be a string, not " + kind_of(*v));
      return fallback;
    }
    auto s = v->get<std::string>();
    if (!allowed.empty() && std::find(allowed.begin(), allowed.end(), s) == allowed.end()) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      error(child(key), "'" + s + "' is not one of: " + list);
      return fallback;
    }
    return s;
  }

  Point point(const std::string& key, bool required, Point fallback, double lo = -1e6,
              double hi = 1e6) {
    const Json* v = get(key, required);
    if (!v) return fallback;
    if (!v->is_array() || v->size() != 3) {
      error(child(key), "must be an array of 3 numbers, not " + kind_of(*v));
      return fallback;
    }
    Point p{};
    for (int i = 0; i < 3; ++i) {
      const Json& e = (*v)[i];
      if (!e.is_number() || !std::isfinite(e.get<double>()) || e.get<double>() < lo ||
          e.get<double>() > hi) {
        error(child(key) + "[" + std::to_string(i) + "]",
              kind_of(e) + " must be a finite number in [" + number_text(lo) + ", " + number_text(hi) + "]");
        return fallback;
      }
      p[i] = e.get<double>();
    }
    return p;
  }

  void error(const std::string& where, const std::string& what) {
    errors_.push_back((where.empty() ? std::string("(top level)") : where) + ": " + what);
  }

 private:
  const Json& node_;
  std::string path_;
  std::vector<std::string>& errors_;
  std::set<std::string> used_;
};

}  // namespace incise::engine
