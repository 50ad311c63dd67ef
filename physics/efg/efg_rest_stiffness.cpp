// What a rest-shape preconditioner needs from the EFG model (physics/solve/): K0 and the warp.
//
// K0 is assembled by block rows: row n sums, over the elements that hold node n in increasing
// order and over their neighbours in row order, the blocks that element adds, which is the
// order an element-by-element assembly adds them in, so each block has the same bits either
// way. A row depends on the elements holding its node only, so the job keeps the last K0 and
// the element rows it read (EfgRestStiffnessCache) and recomputes only the block rows of the
// nodes of elements a cut changed (re-selected, resized, removed); every other row is copied.
// The result is the same bits as a whole assembly, whatever the cache held.
#include "physics/efg/corotational_efg.hpp"
#include "physics/fem/tet_element.hpp"
#include "physics/solve/warped_preconditioner.hpp"

#include <algorithm>
#include <climits>
#include <mutex>
#include <stdexcept>

namespace incise::physics {

namespace {

// A copy of the element rows: the job runs beside the steps, which a cut may re-select meanwhile.
struct Rows {
  int nodes, stride;
  double lambda, mu;
  std::vector<int> lengths, neighbours;
  std::vector<Vec3> gradients;
  std::vector<double> volumes;

  int elements() const { return static_cast<int>(volumes.size()); }
  bool active(int e) const { return e < elements() && volumes[static_cast<size_t>(e)] > 0; }
  std::span<const int> row(int e) const {
    return {neighbours.data() + static_cast<size_t>(e) * stride, static_cast<size_t>(lengths[static_cast<size_t>(e)])};
  }
};

// Element e's row the same in both (its blocks are then the same bits).
bool same_element(const Rows& a, const Rows& b, int e) {
  if (a.active(e) != b.active(e)) return false;
  if (!a.active(e)) return true;
  const size_t i = static_cast<size_t>(e), base = i * static_cast<size_t>(a.stride);
  const size_t length = static_cast<size_t>(a.lengths[i]);
  return a.volumes[i] == b.volumes[i] && a.lengths[i] == b.lengths[i] &&
         std::equal(a.neighbours.begin() + base, a.neighbours.begin() + base + length, b.neighbours.begin() + base) &&
         std::equal(a.gradients.begin() + base, a.gradients.begin() + base + length, b.gradients.begin() + base);
}

// Node n's (element, slot) pairs as flat indices e stride + a, in increasing order.
struct Incidence {
  std::vector<int> start, slots;
  explicit Incidence(const Rows& r) : start(static_cast<size_t>(r.nodes) + 2, 0) {
    for (int e = 0; e < r.elements(); ++e)
      if (r.active(e))
        for (int node : r.row(e)) ++start[static_cast<size_t>(node) + 2];
    for (size_t n = 2; n < start.size(); ++n) start[n] += start[n - 1];
    slots.resize(static_cast<size_t>(start.back()));
    for (int e = 0; e < r.elements(); ++e)
      if (r.active(e))
        for (int a = 0; a < r.lengths[static_cast<size_t>(e)]; ++a)
          slots[static_cast<size_t>(start[static_cast<size_t>(r.neighbours[static_cast<size_t>(e) * r.stride + a]) + 1]++)] =
              e * r.stride + a;
    start.pop_back();  // start[n] .. start[n + 1] are node n's
  }
};

// Appends node n's block row: its columns (every node sharing an element with it, and itself)
// and blocks. `position` (nodes entries, -1 outside the row) is left as it was found.
void assemble_row(const Rows& r, const Incidence& incidence, int n, std::vector<int>& position,
                  std::vector<int>& columns, std::vector<Mat3>& blocks) {
  const size_t first = columns.size();
  columns.push_back(n);
  position[static_cast<size_t>(n)] = 0;
  for (int k = incidence.start[static_cast<size_t>(n)]; k < incidence.start[static_cast<size_t>(n) + 1]; ++k) {
    const int e = incidence.slots[static_cast<size_t>(k)] / r.stride;
    for (int m : r.row(e))
      if (position[static_cast<size_t>(m)] < 0) {
        position[static_cast<size_t>(m)] = 0;
        columns.push_back(m);
      }
  }
  std::sort(columns.begin() + static_cast<std::ptrdiff_t>(first), columns.end());
  for (size_t k = first; k < columns.size(); ++k) position[static_cast<size_t>(columns[k])] = static_cast<int>(k - first);
  blocks.resize(columns.size(), Mat3::Zero());
  Mat3* row = blocks.data() + first;
  // The corotated K p of add_stiffness_product with R = I: block (n, m) of element e is
  // V_e (lambda g_n g_m^T + mu g_m g_n^T + mu (g_n . g_m) I), the isotropic block.
  for (int k = incidence.start[static_cast<size_t>(n)]; k < incidence.start[static_cast<size_t>(n) + 1]; ++k) {
    const int slot = incidence.slots[static_cast<size_t>(k)];
    const int e = slot / r.stride;
    const double volume = r.volumes[static_cast<size_t>(e)];
    const size_t base = static_cast<size_t>(e) * r.stride;
    for (int b = 0; b < r.lengths[static_cast<size_t>(e)]; ++b)
      row[position[static_cast<size_t>(r.neighbours[base + b])]] +=
          volume * isotropic_stiffness_block(r.gradients[static_cast<size_t>(slot)], r.gradients[base + b], r.lambda, r.mu);
  }
  for (size_t k = first; k < columns.size(); ++k) position[static_cast<size_t>(columns[k])] = -1;
}

}  // namespace

struct EfgRestStiffnessCache {
  std::mutex mutex;
  std::shared_ptr<const Rows> rows;  // null: nothing assembled yet
  std::vector<int> row_start, columns;
  std::vector<Mat3> blocks;
};

std::shared_ptr<EfgRestStiffnessCache> make_efg_rest_stiffness_cache() { return std::make_shared<EfgRestStiffnessCache>(); }

namespace {

// The nodes whose block rows differ between `before`'s K0 and `after`'s: those of every
// element whose row changed, as it was and as it is. All of them when nothing is comparable.
std::vector<std::uint8_t> changed_rows(const Rows* before, const Rows& after) {
  if (!before || before->nodes != after.nodes || before->stride != after.stride || before->lambda != after.lambda ||
      before->mu != after.mu)
    return std::vector<std::uint8_t>(static_cast<size_t>(after.nodes), 1);
  std::vector<std::uint8_t> changed(static_cast<size_t>(after.nodes), 0);
  const int elements = std::max(before->elements(), after.elements());
  for (int e = 0; e < elements; ++e) {
    if (e < before->elements() && e < after.elements() && same_element(*before, after, e)) continue;
    for (const Rows* r : {before, &after})
      if (r->active(e))
        for (int node : r->row(e)) changed[static_cast<size_t>(node)] = 1;
  }
  return changed;
}

}  // namespace

std::function<BlockMatrix()> CorotationalEfg::rest_stiffness_job() const {
  if (static_cast<long long>(element_count()) * stride_ >= INT_MAX)
    throw std::length_error("CorotationalEfg: too many element rows for the rest stiffness's indices");
  auto rows = std::make_shared<const Rows>(
      Rows{node_count(), stride_, shape_->lambda, shape_->mu, row_lengths_, neighbours_, shape_gradients_, volumes_});
  return [rows, cache = rest_stiffness_cache_] {
    const Rows& r = *rows;
    std::unique_lock<std::mutex> lock;
    if (cache) lock = std::unique_lock<std::mutex>(cache->mutex);
    const std::vector<std::uint8_t> changed = changed_rows(cache ? cache->rows.get() : nullptr, r);
    const Incidence incidence(r);
    std::vector<int> row_start(static_cast<size_t>(r.nodes) + 1, 0), columns;
    std::vector<Mat3> blocks;
    if (cache) {
      columns.reserve(cache->columns.size());
      blocks.reserve(cache->blocks.size());
    }
    std::vector<int> position(static_cast<size_t>(r.nodes), -1);
    for (int n = 0; n < r.nodes; ++n) {
      if (changed[static_cast<size_t>(n)]) {
        assemble_row(r, incidence, n, position, columns, blocks);
      } else {
        const auto first = static_cast<std::ptrdiff_t>(cache->row_start[static_cast<size_t>(n)]);
        const auto last = static_cast<std::ptrdiff_t>(cache->row_start[static_cast<size_t>(n) + 1]);
        columns.insert(columns.end(), cache->columns.begin() + first, cache->columns.begin() + last);
        blocks.insert(blocks.end(), cache->blocks.begin() + first, cache->blocks.begin() + last);
      }
      row_start[static_cast<size_t>(n) + 1] = static_cast<int>(columns.size());
    }
    if (!cache) return BlockMatrix(r.nodes, std::move(row_start), std::move(columns), std::move(blocks));
    cache->rows = rows;
    cache->row_start = std::move(row_start);
    cache->columns = std::move(columns);
    cache->blocks = std::move(blocks);
    return BlockMatrix(r.nodes, cache->row_start, cache->columns, cache->blocks);
  };
}

// Each node's mean of its elements' rotations, the nodes on the executor's threads: the sums
// of NodeRotations' serial pass over the elements (their order per node, their bits), which
// ran every multigrid_current step on its critical path.
void CorotationalEfg::node_rotations(std::vector<Eigen::Quaterniond>& out) const {
  const int nodes = node_count();
  if (node_incidence_.revision != topology_revision_ || node_incidence_.start.size() != static_cast<size_t>(nodes) + 1)
    lay_node_incidence();
  const std::vector<int>& start = node_incidence_.start;
  const std::vector<int>& elements = node_incidence_.elements;
  out.resize(static_cast<size_t>(nodes));
  executor_->parallel_for(nodes, [&](int begin, int end) {
    for (int node = begin; node < end; ++node) {
      Eigen::Vector4d sum = Eigen::Vector4d::Zero();
      for (int i = start[static_cast<size_t>(node)]; i < start[static_cast<size_t>(node) + 1]; ++i) {
        const size_t e = static_cast<size_t>(elements[static_cast<size_t>(i)]);
        NodeRotations::accumulate(sum, orientations_[e], volumes_[e]);
      }
      out[static_cast<size_t>(node)] = NodeRotations::normalised(sum);
    }
  }, 256);
}

void CorotationalEfg::lay_node_incidence() const {
  const int nodes = node_count();
  std::vector<int>& start = node_incidence_.start;
  std::vector<int>& elements = node_incidence_.elements;
  start.assign(static_cast<size_t>(nodes) + 1, 0);
  for (int e = 0; e < element_count(); ++e) {
    if (!(volumes_[static_cast<size_t>(e)] > 0)) continue;
    const size_t base = static_cast<size_t>(e) * stride_;
    for (int k = 0; k < row_lengths_[static_cast<size_t>(e)]; ++k) ++start[static_cast<size_t>(neighbours_[base + k]) + 1];
  }
  for (int node = 0; node < nodes; ++node) start[static_cast<size_t>(node) + 1] += start[static_cast<size_t>(node)];
  elements.resize(static_cast<size_t>(start.back()));
  std::vector<int> next(start.begin(), start.end() - 1);
  for (int e = 0; e < element_count(); ++e) {
    if (!(volumes_[static_cast<size_t>(e)] > 0)) continue;
    const size_t base = static_cast<size_t>(e) * stride_;
    for (int k = 0; k < row_lengths_[static_cast<size_t>(e)]; ++k)
      elements[static_cast<size_t>(next[static_cast<size_t>(neighbours_[base + k])]++)] = e;
  }
  node_incidence_.revision = topology_revision_;
}

double CorotationalEfg::node_spacing() const { return 2 * shape_->settings.spacing; }  // the particle grid's

}  // namespace incise::physics
