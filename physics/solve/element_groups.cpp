#include "physics/solve/element_groups.hpp"

#include <algorithm>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

namespace incise::physics {

namespace {

std::uint64_t hash_nodes(const std::vector<std::pair<int, int>>& sorted) {
  std::uint64_t hash = 1469598103934665603ull;  // FNV-1a over the node indices
  for (const auto& [node, k] : sorted) {
    hash ^= static_cast<std::uint32_t>(node);
    hash *= 1099511628211ull;
  }
  return hash;
}

bool same_nodes(const std::vector<std::pair<int, int>>& sorted, const int* nodes, int length) {
  if (static_cast<int>(sorted.size()) != length) return false;
  for (int a = 0; a < length; ++a)
    if (sorted[static_cast<size_t>(a)].first != nodes[a]) return false;
  return true;
}

// A row's nodes sorted, with their places in the row: (node, k), by node then k. `who` names
// the caller in the error on a length outside [0, stride].
void sort_row(const std::vector<int>& neighbours, size_t base, int length, int stride, const char* who,
              std::vector<std::pair<int, int>>& sorted) {
  if (length < 0 || length > stride) throw std::invalid_argument(std::string(who) + ": a row length is outside [0, stride]");
  sorted.clear();
  for (int k = 0; k < length; ++k) sorted.emplace_back(neighbours[base + static_cast<size_t>(k)], k);
  std::sort(sorted.begin(), sorted.end());
}

// Node sets numbered 0, 1, ... (their nodes in start/nodes arrays the caller keeps), found by
// hash: per hash the newest set with it, the others chained behind it. The chains decide only
// which sets are compared, not the order of anything.
class NodeSetIndex {
 public:
  explicit NodeSetIndex(size_t expected) { first_with_hash_.reserve(expected); }
  // The set with `sorted`'s nodes, -1 if none.
  int find(std::uint64_t hash, const std::vector<std::pair<int, int>>& sorted, const std::vector<int>& start,
           const std::vector<int>& nodes) const {
    const auto found = first_with_hash_.find(hash);
    int key = found == first_with_hash_.end() ? -1 : found->second;
    while (key >= 0 && !same_nodes(sorted, nodes.data() + start[static_cast<size_t>(key)],
                                   start[static_cast<size_t>(key) + 1] - start[static_cast<size_t>(key)]))
      key = next_with_hash_[static_cast<size_t>(key)];
    return key;
  }
  // Adds set `key` (the next number) of hash `hash`.
  void add(std::uint64_t hash, int key) {
    next_with_hash_.push_back(-1);
    const auto [found, inserted] = first_with_hash_.try_emplace(hash, key);
    if (!inserted) {
      next_with_hash_[static_cast<size_t>(key)] = found->second;
      found->second = key;
    }
  }

 private:
  std::unordered_map<std::uint64_t, int> first_with_hash_;
  std::vector<int> next_with_hash_;
};

// Lists each group's members in increasing element order (a counting sort by group).
void list_members(ElementGroups& groups) {
  const int count = groups.count();
  groups.member_start.assign(static_cast<size_t>(count) + 1, 0);
  for (int g : groups.group_of) ++groups.member_start[static_cast<size_t>(g) + 1];
  for (int g = 0; g < count; ++g) groups.member_start[static_cast<size_t>(g) + 1] += groups.member_start[static_cast<size_t>(g)];
  groups.members.assign(groups.group_of.size(), 0);
  groups.member_of.assign(groups.group_of.size(), 0);
  std::vector<int> next(groups.member_start.begin(), groups.member_start.end() - 1);
  for (int e = 0; e < static_cast<int>(groups.group_of.size()); ++e) {
    const int g = groups.group_of[static_cast<size_t>(e)];
    const int slot = next[static_cast<size_t>(g)]++;
    groups.members[static_cast<size_t>(slot)] = e;
    groups.member_of[static_cast<size_t>(e)] = slot - groups.member_start[static_cast<size_t>(g)];
  }
}

}  // namespace

ElementGroups group_elements(int stride, const std::vector<int>& lengths, const std::vector<int>& neighbours) {
  if (stride < 1 || neighbours.size() != lengths.size() * static_cast<size_t>(stride))
    throw std::invalid_argument("group_elements: the rows need lengths.size() x stride neighbours");
  const int elements = static_cast<int>(lengths.size());
  ElementGroups groups;
  groups.node_start.push_back(0);
  groups.group_of.assign(static_cast<size_t>(elements), 0);
  groups.local.assign(neighbours.size(), 0);
  NodeSetIndex sets(static_cast<size_t>(elements) / 4 + 1);
  std::vector<std::pair<int, int>> sorted;
  for (int e = 0; e < elements; ++e) {
    const size_t base = static_cast<size_t>(e) * stride;
    const int length = lengths[static_cast<size_t>(e)];
    sort_row(neighbours, base, length, stride, "group_elements", sorted);
    const std::uint64_t hash = hash_nodes(sorted);
    int group = sets.find(hash, sorted, groups.node_start, groups.nodes);
    if (group < 0) {
      group = groups.count();
      sets.add(hash, group);
      for (const auto& entry : sorted) groups.nodes.push_back(entry.first);
      groups.node_start.push_back(static_cast<int>(groups.nodes.size()));
    }
    groups.group_of[static_cast<size_t>(e)] = group;
    for (int a = 0; a < length; ++a) groups.local[base + static_cast<size_t>(sorted[static_cast<size_t>(a)].second)] = a;
  }
  list_members(groups);
  return groups;
}

ElementGroups regroup_elements(const ElementGroups& previous, int stride, const std::vector<int>& lengths,
                               const std::vector<int>& neighbours, const std::vector<int>& changed,
                               std::vector<int>* previous_group) {
  const int elements = static_cast<int>(lengths.size());
  if (stride < 1 || neighbours.size() != lengths.size() * static_cast<size_t>(stride) ||
      previous.group_of.size() != lengths.size() || previous.local.size() != neighbours.size())
    throw std::invalid_argument("regroup_elements: the rows need the previous grouping's elements x stride neighbours");
  // Keys: the previous groups' node sets (0 .. old - 1), then the changed rows' new sets.
  const int old = previous.count();
  std::vector<int> key_start(previous.node_start), key_nodes(previous.nodes);
  NodeSetIndex sets(static_cast<size_t>(old) + changed.size());
  std::vector<std::pair<int, int>> sorted;
  for (int g = 0; g < old; ++g) {
    sorted.clear();
    for (int i = key_start[static_cast<size_t>(g)]; i < key_start[static_cast<size_t>(g) + 1]; ++i)
      sorted.emplace_back(key_nodes[static_cast<size_t>(i)], 0);
    sets.add(hash_nodes(sorted), g);
  }
  std::vector<int> key_of(previous.group_of);
  std::vector<int> local(previous.local);
  int last = -1;
  for (const int e : changed) {
    if (e <= last || e >= elements) throw std::invalid_argument("regroup_elements: changed elements must increase within [0, elements)");
    last = e;
    const size_t base = static_cast<size_t>(e) * stride;
    const int length = lengths[static_cast<size_t>(e)];
    sort_row(neighbours, base, length, stride, "regroup_elements", sorted);
    const std::uint64_t hash = hash_nodes(sorted);
    int key = sets.find(hash, sorted, key_start, key_nodes);
    if (key < 0) {
      key = static_cast<int>(key_start.size()) - 1;
      for (const auto& entry : sorted) key_nodes.push_back(entry.first);
      key_start.push_back(static_cast<int>(key_nodes.size()));
      sets.add(hash, key);
    }
    key_of[static_cast<size_t>(e)] = key;
    for (int k = length; k < stride; ++k) local[base + static_cast<size_t>(k)] = 0;
    for (int a = 0; a < length; ++a) local[base + static_cast<size_t>(sorted[static_cast<size_t>(a)].second)] = a;
  }
  // group_elements numbers the groups in the order of their first elements.
  ElementGroups groups;
  std::vector<int> group_of_key(key_start.size() - 1, -1);
  groups.node_start.push_back(0);
  groups.group_of.assign(static_cast<size_t>(elements), 0);
  if (previous_group) previous_group->clear();
  for (int e = 0; e < elements; ++e) {
    const int key = key_of[static_cast<size_t>(e)];
    int& group = group_of_key[static_cast<size_t>(key)];
    if (group < 0) {
      group = groups.count();
      groups.nodes.insert(groups.nodes.end(), key_nodes.begin() + key_start[static_cast<size_t>(key)],
                          key_nodes.begin() + key_start[static_cast<size_t>(key) + 1]);
      groups.node_start.push_back(static_cast<int>(groups.nodes.size()));
      if (previous_group) previous_group->push_back(key < old ? key : -1);
    }
    groups.group_of[static_cast<size_t>(e)] = group;
  }
  groups.local = std::move(local);
  list_members(groups);
  return groups;
}

}  // namespace incise::physics
