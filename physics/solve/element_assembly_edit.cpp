// The plan edited for rows that changed in a few elements (element_assembly.hpp): a cut's
// re-selection changes a few hundred rows of 20k, and rebuilding the plan from every row
// (grouping them, laying the pattern from every group) cost the cutting steps about 5 ms of
// their critical path at 20k elements. The edited plan is the one build() would make for the
// same rows over the same pattern: the same groups in the same order (regroup_elements), each
// group's pairs at the same blocks, so the refill's sums and their order are the same.
#include "physics/solve/element_assembly.hpp"

#include <algorithm>
#include <stdexcept>

namespace incise::physics {

namespace {

// Rows edited in more than this share of the elements are grouped afresh.
constexpr int edited_share = 4;  // 1 / 4

}  // namespace

bool ElementAssembly::edit(int nodes, int stride, const std::vector<int>& lengths, const std::vector<int>& neighbours,
                           const std::vector<int>* listed) {
  if (matrix_.nodes() != nodes || stride_ != stride || lengths_.size() != lengths.size() ||
      neighbours.size() != neighbours_.size() || groups_.node_start.empty())
    return false;
  const int elements = static_cast<int>(lengths.size());
  std::vector<int> changed;
  if (listed) {
    // The caller's list (a superset of the changed rows: regrouping an unchanged row finds its
    // own node set again).
    if (static_cast<int>(listed->size()) * edited_share > elements) return false;
    for (size_t i = 0; i < listed->size(); ++i)
      if ((*listed)[i] < 0 || (*listed)[i] >= elements || (i > 0 && (*listed)[i] <= (*listed)[i - 1]))
        throw std::invalid_argument("ElementAssembly: the changed elements must increase within [0, elements)");
    changed = *listed;
  } else {
    for (int e = 0; e < elements; ++e) {
      const size_t base = static_cast<size_t>(e) * static_cast<size_t>(stride);
      const int length = lengths[static_cast<size_t>(e)];
      if (length != lengths_[static_cast<size_t>(e)] ||
          !std::equal(neighbours.begin() + static_cast<std::ptrdiff_t>(base), neighbours.begin() + static_cast<std::ptrdiff_t>(base) + std::max(0, std::min(length, stride)),
                      neighbours_.begin() + static_cast<std::ptrdiff_t>(base)))
        changed.push_back(e);
      if (static_cast<int>(changed.size()) * edited_share > elements) return false;
    }
  }
  std::vector<int> previous_group;
  ElementGroups groups = regroup_elements(groups_, stride, lengths, neighbours, changed, &previous_group);
  for (size_t g = 0; g < previous_group.size(); ++g)
    if (previous_group[g] < 0)
      for (int i = groups.node_start[g]; i < groups.node_start[g + 1]; ++i)
        if (groups.nodes[static_cast<size_t>(i)] < 0 || groups.nodes[static_cast<size_t>(i)] >= nodes)
          throw std::invalid_argument("ElementAssembly: a row names a node outside [0, nodes)");
  const std::vector<int> old_pair_start = std::move(pair_start_);
  const std::vector<int> old_pair_index = std::move(pair_index_);
  groups_ = std::move(groups);
  lengths_ = lengths;
  neighbours_ = neighbours;
  size_groups();
  // A group of a node set the last plan had takes its pairs' blocks; a new set looks its up.
  pair_index_.assign(static_cast<size_t>(pair_start_.back()), -1);
  std::vector<std::pair<int, int>> missing;
  for (int g = 0; g < groups_.count(); ++g) {
    const int previous = previous_group[static_cast<size_t>(g)];
    const int next = pair_start_[static_cast<size_t>(g)];
    if (previous >= 0) {
      std::copy(old_pair_index.begin() + old_pair_start[static_cast<size_t>(previous)],
                old_pair_index.begin() + old_pair_start[static_cast<size_t>(previous) + 1], pair_index_.begin() + next);
      continue;
    }
    const int* group_nodes = groups_.nodes.data() + groups_.node_start[static_cast<size_t>(g)];
    const int length = groups_.length(g);
    int pair = next;
    for (int a = 0; a < length; ++a)
      for (int b = a; b < length; ++b, ++pair) {
        pair_index_[static_cast<size_t>(pair)] = matrix_.find(group_nodes[a], group_nodes[b]);
        if (pair_index_[static_cast<size_t>(pair)] < 0) {
          missing.emplace_back(group_nodes[a], group_nodes[b]);
          missing.emplace_back(group_nodes[b], group_nodes[a]);
        }
      }
  }
  pattern_rebuilt_ = !missing.empty();
  if (pattern_rebuilt_) {
    const std::vector<int> moved = grow_pattern(std::move(missing));
    for (int& index : pair_index_) index = index >= 0 ? moved[static_cast<size_t>(index)] : -1;
    for (int g = 0; g < groups_.count(); ++g) {
      if (previous_group[static_cast<size_t>(g)] >= 0) continue;
      const int* group_nodes = groups_.nodes.data() + groups_.node_start[static_cast<size_t>(g)];
      const int length = groups_.length(g);
      int pair = pair_start_[static_cast<size_t>(g)];
      for (int a = 0; a < length; ++a)
        for (int b = a; b < length; ++b, ++pair)
          if (pair_index_[static_cast<size_t>(pair)] < 0)
            pair_index_[static_cast<size_t>(pair)] = matrix_.find(group_nodes[a], group_nodes[b]);
    }
    index_mirrors();
  }
  list_incidences();
  return true;
}

std::vector<int> ElementAssembly::grow_pattern(std::vector<std::pair<int, int>> missing) {
  std::sort(missing.begin(), missing.end());
  missing.erase(std::unique(missing.begin(), missing.end()), missing.end());
  const std::vector<int>& start = matrix_.row_start();
  const std::vector<int>& columns = matrix_.columns();
  const int nodes = matrix_.nodes();
  std::vector<int> row_start(static_cast<size_t>(nodes) + 1, 0), grown;
  grown.reserve(columns.size() + missing.size());
  std::vector<int> moved(columns.size(), -1);
  size_t m = 0;
  for (int row = 0; row < nodes; ++row) {
    int k = start[static_cast<size_t>(row)];
    const int end = start[static_cast<size_t>(row) + 1];
    while (k < end || (m < missing.size() && missing[m].first == row)) {
      if (m < missing.size() && missing[m].first == row && (k == end || missing[m].second < columns[static_cast<size_t>(k)])) {
        grown.push_back(missing[m++].second);
      } else {
        moved[static_cast<size_t>(k)] = static_cast<int>(grown.size());
        grown.push_back(columns[static_cast<size_t>(k++)]);
      }
    }
    row_start[static_cast<size_t>(row) + 1] = static_cast<int>(grown.size());
  }
  if (m != missing.size()) throw std::logic_error("ElementAssembly: a missing pair's row is outside the pattern");
  // The grown pattern's blocks in the old ones' storage, not a new zeroed one (20 MB at 76k
  // elements, for a few dozen new pairs): the refill rewrites every block, the lower ones as
  // their mirrors' transposes. Room for an eighth more, so the next cuts' pairs fit.
  std::vector<Mat3> storage = matrix_.release_blocks();
  const size_t blocks = grown.size();
  if (storage.capacity() < blocks) {
    storage.clear();
    storage.reserve(blocks + blocks / 8);
  }
  storage.resize(blocks);
  matrix_ = BlockMatrix(nodes, std::move(row_start), std::move(grown), std::move(storage));
  return moved;
}

}  // namespace incise::physics
