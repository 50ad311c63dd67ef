#include "batch/overrides.hpp"

#include <charconv>

namespace incise::batch {

namespace {

std::vector<std::string> split_dotted(const std::string& key) {
  std::vector<std::string> parts;
  std::size_t start = 0;
  while (true) {
    const std::size_t dot = key.find('.', start);
    parts.push_back(key.substr(start, dot == std::string::npos ? std::string::npos : dot - start));
    if (dot == std::string::npos) return parts;
    start = dot + 1;
  }
}

// The array index a part names, or -1 when it is not a plain decimal index.
long index_of(const std::string& part) {
  long index = -1;
  const auto [end, error] = std::from_chars(part.data(), part.data() + part.size(), index);
  if (error != std::errc() || end != part.data() + part.size() || part.empty()) return -1;
  return index;
}

}  // namespace

std::string apply_override(Json& scene, const std::string& key, const Json& value) {
  const std::vector<std::string> parts = split_dotted(key);
  Json* node = &scene;
  std::string reached;  // the part of the key resolved so far, for messages
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const std::string& part = parts[i];
    const bool last = i + 1 == parts.size();
    if (part.empty()) return "an empty part in the key";
    const std::string where = reached.empty() ? "the scene" : "'" + reached + "'";
    if (node->is_array()) {
      const long index = index_of(part);
      if (index < 0) return where + " is an array: '" + part + "' is not an index";
      if (static_cast<std::size_t>(index) >= node->size())
        return where + " has " + std::to_string(node->size()) + " element(s): no index " + part;
      node = &(*node)[static_cast<std::size_t>(index)];
    } else if (node->is_object()) {
      if (!last && !node->contains(part)) return where + " has no key '" + part + "'";
      node = &(*node)[part];
    } else {
      return where + " is " + std::string(node->type_name()) + ", not an object or array";
    }
    reached += (reached.empty() ? "" : ".") + part;
  }
  *node = value;
  return "";
}

}  // namespace incise::batch
