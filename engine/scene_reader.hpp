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

inline std::string number_text(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

// Reads one JSON object, remembering which keys were consumed so the rest can be
// reported as unknown. Every accessor records an error and returns a neutral value
// rather than throwing, so one pass lists all the problems of a file.
class Reader {
 public:
  Reader(const Json& node, std::string path, std::vector<std::string>& errors)
      : node_(node), path_(std::move(path)), errors_(errors) {
    if (!node_.is_object()) error(path_, "must be an object");
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
      error(child(key), "must be a number, not " + std::string(v->type_name()));
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
      error(child(key), "must be an integer");
      return fallback;
    }
    auto x = v->get<long long>();
    if (x < lo || x > hi) {
      error(child(key), std::to_string(x) + " must be in [" + std::to_string(lo) + ", " +
                            std::to_string(hi) + "]");
      return fallback;
    }
    return static_cast<int>(x);
  }

  bool boolean(const std::string& key, bool fallback) {
    const Json* v = get(key, false);
    if (!v) return fallback;
    if (!v->is_boolean()) {
      error(child(key), "must be true or false");
      return fallback;
    }
    return v->get<bool>();
  }

  std::string text(const std::string& key, bool required, const std::string& fallback,
                   const std::vector<std::string>& allowed = {}) {
    const Json* v = get(key, required);
    if (!v) return fallback;
    if (!v->is_string()) {
      error(child(key), "must be a string");
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
      error(child(key), "must be an array of 3 numbers");
      return fallback;
    }
    Point p{};
    for (int i = 0; i < 3; ++i) {
      const Json& e = (*v)[i];
      if (!e.is_number() || !std::isfinite(e.get<double>()) || e.get<double>() < lo ||
          e.get<double>() > hi) {
        error(child(key) + "[" + std::to_string(i) + "]",
              "must be a finite number in [" + number_text(lo) + ", " + number_text(hi) + "]");
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
