// Elements grouped by their node set, for assemblies that sum per group before they scatter
// (element_assembly.hpp). The EFG's integration points of one particle cell take the same 8
// cell corners as neighbours, each nearest first, so in its own order: grouped by the set,
// 8 points share one set of node pairs and their contributions are summed in registers before
// one scatter per pair instead of eight.
//
// The grouping is a function of the rows alone (not of the edits that led to them): groups in
// the order of their first element, members in increasing element order, a group's nodes in
// increasing index order. So an assembly that follows it sums in the same order for a model
// built with its cuts and for one cut step by step.
#pragma once

#include <cstddef>
#include <vector>

namespace incise::physics {

struct ElementGroups {
  // Group g's nodes, increasing (repeats kept): nodes[node_start[g] .. node_start[g + 1]).
  std::vector<int> node_start, nodes;
  // Group g's elements, increasing: members[member_start[g] .. member_start[g + 1]).
  std::vector<int> member_start, members;
  // Per element: its group, and its member index within it (0 for the group's first).
  std::vector<int> group_of, member_of;
  // Per row entry e * stride + k (k < lengths[e]): the position of that node in its group's
  // nodes.
  std::vector<int> local;

  int count() const { return static_cast<int>(node_start.size()) - 1; }
  int length(int group) const { return node_start[static_cast<std::size_t>(group) + 1] - node_start[static_cast<std::size_t>(group)]; }
};

// Groups the elements whose rows hold the same nodes (the same multiset, any order): element e's
// nodes are neighbours[e * stride + k], k < lengths[e].
ElementGroups group_elements(int stride, const std::vector<int>& lengths, const std::vector<int>& neighbours);

// The same grouping of edited rows, from `previous`, the grouping of the rows before the edit
// (as many elements, the same stride): only the `changed` elements' rows (increasing) are
// sorted and looked up, the others keep their node set, and the groups' order follows from one
// pass over the elements. A cut re-selects a few hundred of 20k elements' neighbourhoods; this
// is a few linear passes where group_elements sorts and hashes every row. `previous_group`,
// when given, gets per new group the previous group of the same nodes, -1 for a new set.
ElementGroups regroup_elements(const ElementGroups& previous, int stride, const std::vector<int>& lengths,
                               const std::vector<int>& neighbours, const std::vector<int>& changed,
                               std::vector<int>* previous_group = nullptr);

}  // namespace incise::physics
