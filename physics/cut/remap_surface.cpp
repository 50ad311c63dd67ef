#include "physics/cut/remap_surface.hpp"

#include "physics/core/mix.hpp"
#include "physics/core/stopwatch.hpp"

#include <algorithm>
#include <bit>
#include <cstring>
#include <iterator>
#include <limits>
#include <optional>
#include <utility>

namespace incise::physics {

namespace {

// One remapping, its stages as methods over what they share. The base's vertices below
// `kept` keep their index and their row unless a trigger names them (the base as the last
// mapping saw it: a stroke ended since then turned its vertices into base ones, which are
// matched like the stroke's).
class FrontRemap {
 public:
  FrontRemap(CutContext& ctx, const RemapRegion& region)
      : ctx(ctx), region(region), body(ctx.body), cut(ctx.cut), front(*ctx.cut.surface), vertices(front.vertices()),
        triangles(front.triangles()), planes(front.vertex_planes()), embedding(*ctx.body.embedding),
        centres(ctx.body.efg->element_centres()), before_slots(ctx.cut.mapping.changed_slots),
        n(static_cast<int>(vertices.size())), base_vertices(front.base_vertex_count()), slots_now(triangles.size()),
        slots_before(body.surface.size()),
        kept(std::min({base_vertices, cut.mapping.mapped_base, embedding.vertex_count()})),
        lowest(std::min(kept, cut.mapping.identity.first)),
        inset(0.1 * front.front_width() / 1.5) {}  // a tenth of a surface cell

  void run() {
    find_changed_slots();
    find_touched();
    count_edges_before();
    plane_and_element_triggers();
    move_matched_rows();
    index_triangles_around();
    find_cut_faces();
    map_rows();
    write_surface();
    check();
  }

 private:
  void find_changed_slots();
  void find_touched();
  void count_edges_before();
  void plane_and_element_triggers();
  void move_matched_rows();
  void index_triangles_around();
  void find_cut_faces();
  void map_rows();
  void write_surface();
  void check();
  // How far (per axis) vertex v lies from its integration point.
  double reach_of(int v) const {
    return (centres[static_cast<std::size_t>(embedding.elements[static_cast<std::size_t>(v)])] - vertices[static_cast<std::size_t>(v)]).cwiseAbs().maxCoeff();
  }

  CutContext& ctx;
  const RemapRegion& region;
  BodyData& body;
  CutData& cut;
  const FrontSurface& front;
  const std::vector<Vec3>& vertices;
  const std::vector<std::array<int, 3>>& triangles;
  const VertexPlanes& planes;
  SurfaceEmbedding& embedding;
  const std::vector<Vec3>& centres;
  const std::vector<int>& before_slots;  // the slots the stroke had changed at the last mapping
  const int n, base_vertices;
  const std::size_t slots_now, slots_before;
  const int kept, lowest;
  const double inset;
  Stopwatch watch;
  // find_changed_slots: the slots changed now; per slot 1 changed now, 8 looked at in the edge
  // recount; the slots with a corner at or above `lowest`; those that can differ.
  std::vector<int> now_slots, stroke_slots, differing;
  std::vector<std::uint8_t> slot_flags;
  // find_touched: the stroke's vertices matched to the last mapping's (`same`; `same_point`:
  // the same point, whatever its triangles, which keeps its row), the box of what changed, and
  // the vertices whose edges' use can have changed (`touched_base`: those below kept).
  FrontVertexIdentity identity;
  std::vector<int> same, same_point;
  Vec3 changed_lo = Vec3::Constant(1e300), changed_hi = Vec3::Constant(-1e300);
  std::vector<std::uint8_t> touched_now, touched_before;
  std::vector<int> touched_base;
  // count_edges_before: the edges between touched vertices, before and after, and their count
  // before (or a whole recount).
  std::vector<std::array<int, 3>> edges_before, edges_now;
  bool recount = false;
  SurfaceTopology touched_edges_before;
  // The rows to redo, and the base vertices given planes.
  std::vector<int> remap, planed;
  // move_matched_rows: the vertices whose row moved with them (their fixed flag and, on the
  // CPU, their position along), which have a row, and those to map afresh.
  std::vector<int> moved_from, fresh;
  std::vector<Vec3> moved_positions;
  std::vector<std::uint8_t> has_row;  // per vertex from kept on
  std::vector<std::pair<std::size_t, std::uint8_t>> moved_fixed_at;  // set once the rows are all mapped
  // index_triangles_around: the changed slots around each vertex (the stroke's in compressed
  // rows, the base's as sorted pairs), and the mapping's view of them.
  std::vector<int> stroke_around_start, stroke_around;
  std::vector<std::pair<int, int>> base_around;
  TrianglesAround around;
  // find_cut_faces: each cut face once, and per vertex whether it is on one.
  std::vector<std::array<Vec3, 3>> faces;
  std::vector<std::uint8_t> on_face;
  std::optional<CutFaceIndex> face_index;
  // map_rows: the kept rows near what changed (tested for the second trigger), those whose
  // segment a cut face crosses, and the mapping's counts.
  std::vector<int> near, crossed;
  FrontMappingReport mapped;
};

void FrontRemap::find_changed_slots() {
  now_slots = front.replaced_slots();
  for (std::size_t s = static_cast<std::size_t>(front.base_triangle_count()); s < slots_now; ++s) now_slots.push_back(static_cast<int>(s));
  // Per slot: 1 changed now, 8 looked at in the edge recount below.
  slot_flags.assign(std::max(slots_now, slots_before), 0);
  for (const int s : now_slots) slot_flags[static_cast<std::size_t>(s)] |= 1;
  // The triangles with a corner at or above `lowest` (the stroke's, and those of a stroke
  // ended since the last mapping, now base triangles around its vertices), increasing.
  stroke_slots = now_slots;
  for (int v = lowest; v < base_vertices; ++v)
    for (const int s : front.base_triangles_around(v))
      if (!(slot_flags[static_cast<std::size_t>(s)] & 1)) stroke_slots.push_back(s);
  std::sort(stroke_slots.begin(), stroke_slots.end());
  stroke_slots.erase(std::unique(stroke_slots.begin(), stroke_slots.end()), stroke_slots.end());
  // The slots that can differ (changed then, or with a stroke's vertex now), increasing.
  std::set_union(stroke_slots.begin(), stroke_slots.end(), before_slots.begin(), before_slots.end(), std::back_inserter(differing));
}

void FrontRemap::find_touched() {
  // The stroke's vertices are numbered anew at each sample, but those behind the front come
  // out the same: matched to the last mapping's (front_vertex_identity), they keep
  // their row and flag, and only the new ones (and those the triggers below name) are mapped.
  identity = front_vertex_identity(vertices, triangles, planes, front.crack_front(), lowest, stroke_slots);
  same = match_front_vertices(cut.mapping.identity, identity, &same_point);
  const auto old_position = [&](int u) -> const Vec3& {
    return u < cut.mapping.identity.first ? vertices[static_cast<size_t>(u)]
                                         : cut.mapping.stroke_rest[static_cast<size_t>(u - cut.mapping.identity.first)];
  };
  // Where the surface changed: the triangles with a vertex that is new (or whose triangles
  // changed), now and at the last mapping (for those gone). Only a segment reaching into
  // this box can have changed side (the second trigger, below).
  // The same triangles' corners are where the edges' use can have changed: a triangle made
  // or gone changes the triangles of each of its corners, so each is a new (unmatched) vertex
  // or a base one. The surface's edge counts are kept by recounting the edges between two of
  // them, before and after (surface_topology).
  touched_now.assign(vertices.size(), 0);
  touched_before.assign(static_cast<std::size_t>(embedding.vertex_count()), 0);
  {
    const auto grow = [&](const Vec3& x) {
      changed_lo = changed_lo.cwiseMin(x);
      changed_hi = changed_hi.cwiseMax(x);
    };
    const auto is_new = [&](int v) { return v >= kept && same[static_cast<size_t>(v)] < 0; };
    for (const int s : stroke_slots) {
      const auto& tri = triangles[static_cast<std::size_t>(s)];
      if (is_new(tri[0]) || is_new(tri[1]) || is_new(tri[2]))
        for (const int v : tri) {
          grow(vertices[static_cast<size_t>(v)]);
          touched_now[static_cast<size_t>(v)] = 1;
          if (v < kept) touched_base.push_back(v);
        }
    }
    std::vector<std::uint8_t> still(static_cast<size_t>(embedding.vertex_count() - std::min(kept, embedding.vertex_count())), 0);
    for (int v = kept; v < n; ++v)
      if (const int u = same[static_cast<size_t>(v)]; u >= kept && u < embedding.vertex_count()) still[static_cast<size_t>(u - kept)] = 1;
    const auto is_gone = [&](int u) { return u >= kept && still[static_cast<size_t>(u - kept)] == 0; };
    // The last mapping's vertices at or above kept were its stroke's: their triangles were
    // in its changed slots.
    for (const int s : before_slots) {
      if (static_cast<std::size_t>(s) >= slots_before) continue;
      const auto& tri = body.surface[static_cast<std::size_t>(s)];
      if (is_gone(tri[0]) || is_gone(tri[1]) || is_gone(tri[2]))
        for (const int u : tri) {
          grow(old_position(u));
          touched_before[static_cast<size_t>(u)] = 1;
          if (u < kept) touched_base.push_back(u);
        }
    }
    std::sort(touched_base.begin(), touched_base.end());
    touched_base.erase(std::unique(touched_base.begin(), touched_base.end()), touched_base.end());
    for (const int v : touched_base) touched_now[static_cast<size_t>(v)] = touched_before[static_cast<size_t>(v)] = 1;
  }
}

void FrontRemap::count_edges_before() {
  // The edges between two touched vertices lie on the differing triangles or on the unchanged
  // ones around a touched base vertex (the same before and after).
  for (const int s : differing) {
    if (static_cast<std::size_t>(s) < slots_before) edges_before.push_back(body.surface[static_cast<std::size_t>(s)]);
    if (static_cast<std::size_t>(s) < slots_now) edges_now.push_back(triangles[static_cast<std::size_t>(s)]);
    slot_flags[static_cast<std::size_t>(s)] |= 8;
  }
  // The base's triangles away from the cut (all corners below kept, not all touched): the
  // unchanged ones are the same in both, so only the differing ones can make their counts
  // differ; if they do (a triangle lost or made away from the cut, which the stroke never
  // does), the surface is counted whole.
  const auto untouched_base = [&](const std::vector<std::array<int, 3>>& list, const std::vector<std::uint8_t>& touched) {
    long count = 0;
    for (const auto& tri : list)
      if (tri[0] < kept && tri[1] < kept && tri[2] < kept &&
          !(touched[static_cast<size_t>(tri[0])] && touched[static_cast<size_t>(tri[1])] && touched[static_cast<size_t>(tri[2])]))
        ++count;
    return count;
  };
  recount = untouched_base(edges_before, touched_before) != untouched_base(edges_now, touched_now);
  for (const int v : touched_base) {
    if (v >= base_vertices) continue;
    for (const int s : front.base_triangles_around(v)) {
      if (slot_flags[static_cast<std::size_t>(s)] & 8) continue;
      slot_flags[static_cast<std::size_t>(s)] |= 8;
      edges_before.push_back(triangles[static_cast<std::size_t>(s)]);
      edges_now.push_back(triangles[static_cast<std::size_t>(s)]);
    }
  }
  touched_edges_before = surface_topology(edges_before, touched_before);
}

void FrontRemap::plane_and_element_triggers() {
  // The kept base rows whose planes or element changed (the first and third triggers): the
  // base vertices given planes by a stroke at the last mapping or since (the ends of cut
  // edges, corners of the split triangles, which hold a stroke's vertex), and those on a
  // re-selected element.
  // A kept vertex lies within front_reach (per axis) of its integration point (the rows below
  // kept are the last mapping's until the remapping below, which extends it again).
  for (int v = cut.mapping.reach_upto; v < kept; ++v) cut.mapping.reach = std::max(cut.mapping.reach, reach_of(v));
  cut.mapping.reach_upto = std::max(cut.mapping.reach_upto, kept);
  planed = cut.mapping.planed;
  {
    for (const int s : stroke_slots)
      for (const int v : triangles[static_cast<std::size_t>(s)])
        if (v < kept) planed.push_back(v);
    std::sort(planed.begin(), planed.end());
    planed.erase(std::unique(planed.begin(), planed.end()), planed.end());
    for (const int v : planed) {
      const auto index = static_cast<std::size_t>(v);
      if (v < kept && planes[index].size() != (index < cut.mapping.plane_counts.size() ? cut.mapping.plane_counts[index] : 0)) remap.push_back(v);
    }
    // Those on a re-selected element are among the base's vertices in the box of its points
    // grown by front_reach (the surface's own bins; not every vertex looked at).
    Vec3 changed_centres_lo = Vec3::Constant(1e300), changed_centres_hi = Vec3::Constant(-1e300);
    for (std::size_t e = 0; e < region.changed.size(); ++e)
      if (region.changed[e] != 0) {
        changed_centres_lo = changed_centres_lo.cwiseMin(centres[e]);
        changed_centres_hi = changed_centres_hi.cwiseMax(centres[e]);
      }
    if ((changed_centres_lo.array() <= changed_centres_hi.array()).all()) {
      const Vec3 grown = Vec3::Constant(cut.mapping.reach + 1e-3 * body.efg->spacing());
      std::vector<int> on_changed;
      front.base_vertices_in(changed_centres_lo - grown, changed_centres_hi + grown, on_changed);
      std::erase_if(on_changed, [&](int v) {
        return v >= kept || region.changed[static_cast<std::size_t>(embedding.elements[static_cast<std::size_t>(v)])] == 0;
      });
      std::vector<int> merged;
      std::set_union(remap.begin(), remap.end(), on_changed.begin(), on_changed.end(), std::back_inserter(merged));
      remap.swap(merged);
    }
  }
}

void FrontRemap::move_matched_rows() {
  // The matched stroke vertices take their rows along (from a copy: the numbers overlap),
  // and so do those at the same point whose triangles changed (the front's new vertices
  // joined to them): none of seed 004 §2.6's triggers names them. Their segment is tested
  // below with the others' (the second trigger), and the wrong-side count looks at them.
  std::vector<int> moved_elements, moved_lengths, moved_particles;
  std::vector<double> moved_weights;
  std::vector<std::uint8_t> moved_wrong, moved_fixed;
  // Their positions too (the CPU's: those update_surface formed from the particles as they
  // still are, the same sums set_surface_position would do again).
  const bool keep_positions = !ctx.on_gpu;
  const int stride = embedding.stride;
  for (int v = kept; v < n; ++v) {
    const int u = same_point[static_cast<std::size_t>(v)];
    if (u < 0 || u >= embedding.vertex_count() || region.changed[static_cast<std::size_t>(embedding.elements[static_cast<std::size_t>(u)])] != 0) continue;
    moved_from.push_back(v);
    moved_elements.push_back(embedding.elements[static_cast<size_t>(u)]);
    moved_lengths.push_back(embedding.row_lengths[static_cast<size_t>(u)]);
    const auto row = static_cast<std::ptrdiff_t>(u) * stride;
    moved_particles.insert(moved_particles.end(), embedding.particles.begin() + row, embedding.particles.begin() + row + stride);
    moved_weights.insert(moved_weights.end(), embedding.weights.begin() + row, embedding.weights.begin() + row + stride);
    moved_wrong.push_back(static_cast<size_t>(u) < cut.mapping.wrong_side.size() ? cut.mapping.wrong_side[static_cast<size_t>(u)] : 0);
    moved_fixed.push_back(static_cast<size_t>(u) < body.fixed_vertices.size() ? body.fixed_vertices[static_cast<size_t>(u)] : 0);
    if (keep_positions) moved_positions.push_back(3 * static_cast<Eigen::Index>(u) + 3 <= body.surface_positions.size()
                                                      ? Vec3(body.surface_positions.segment<3>(3 * static_cast<Eigen::Index>(u)))
                                                      : Vec3::Constant(std::numeric_limits<double>::quiet_NaN()));
  }
  fit_rows(embedding, n, stride);
  cut.mapping.wrong_side.resize(vertices.size(), 0);
  std::fill(cut.mapping.wrong_side.begin() + kept, cut.mapping.wrong_side.end(), 0);
  has_row.assign(static_cast<std::size_t>(n - kept), 0);
  for (std::size_t k = 0; k < moved_from.size(); ++k) {
    const auto v = static_cast<std::size_t>(moved_from[k]);
    embedding.elements[v] = moved_elements[k];
    embedding.row_lengths[v] = moved_lengths[k];
    std::copy_n(moved_particles.begin() + static_cast<std::ptrdiff_t>(k) * stride, stride, embedding.particles.begin() + static_cast<std::ptrdiff_t>(v) * stride);
    std::copy_n(moved_weights.begin() + static_cast<std::ptrdiff_t>(k) * stride, stride, embedding.weights.begin() + static_cast<std::ptrdiff_t>(v) * stride);
    cut.mapping.wrong_side[v] = moved_wrong[k];
    moved_fixed_at.emplace_back(v, moved_fixed[k]);
    has_row[v - static_cast<std::size_t>(kept)] = 1;
  }
  // What is left of the stroke's vertices is mapped anew (after the trigger test below, which
  // looks at the rows kept).
  for (int v = kept; v < n; ++v)
    if (!has_row[static_cast<std::size_t>(v - kept)]) fresh.push_back(v);
  cut.mapping.stroke_rest.assign(vertices.begin() + identity.first, vertices.end());
  if (identity.first != kept) {
    identity = front_vertex_identity(vertices, triangles, planes, front.crack_front(), kept, stroke_slots);
    cut.mapping.stroke_rest.assign(vertices.begin() + kept, vertices.end());
  }
  cut.mapping.identity = std::move(identity);
}

void FrontRemap::index_triangles_around() {
  // The triangles around each vertex, for the mapping's normals and one-rings: a base vertex's
  // unchanged base triangles and, for every vertex, the changed slots it is a corner of: for
  // the stroke's vertices in compressed rows (counted, then filled), for the base's (the
  // corners of split triangles: few) as sorted (vertex, slot) pairs.
  stroke_around_start.assign(static_cast<std::size_t>(std::max(0, n - base_vertices)) + 1, 0);
  for (const int s : now_slots)
    for (const int v : triangles[static_cast<std::size_t>(s)])
      if (v >= base_vertices) ++stroke_around_start[static_cast<std::size_t>(v - base_vertices) + 1];
      else base_around.emplace_back(v, s);
  for (std::size_t k = 1; k < stroke_around_start.size(); ++k) stroke_around_start[k] += stroke_around_start[k - 1];
  stroke_around.resize(static_cast<std::size_t>(stroke_around_start.back()));
  {
    std::vector<int> fill(stroke_around_start.begin(), stroke_around_start.end() - 1);
    for (const int s : now_slots)
      for (const int v : triangles[static_cast<std::size_t>(s)])
        if (v >= base_vertices) stroke_around[static_cast<std::size_t>(fill[static_cast<std::size_t>(v - base_vertices)]++)] = s;
  }
  std::sort(base_around.begin(), base_around.end());
  around = [this](int v, std::vector<int>& out) {
    const std::size_t first = out.size();
    if (v >= base_vertices) {
      const auto k = static_cast<std::size_t>(v - base_vertices);
      out.insert(out.end(), stroke_around.begin() + stroke_around_start[k], stroke_around.begin() + stroke_around_start[k + 1]);
    } else {
      for (const int s : front.base_triangles_around(v))
        if (!(slot_flags[static_cast<std::size_t>(s)] & 1)) out.push_back(s);
      for (auto it = std::lower_bound(base_around.begin(), base_around.end(), std::pair<int, int>(v, -1));
           it != base_around.end() && it->first == v; ++it)
        out.push_back(it->second);
    }
    std::sort(out.begin() + static_cast<std::ptrdiff_t>(first), out.end());
  };
}

void FrontRemap::find_cut_faces() {
  // The cut faces, each once (both sides' copies lie on it, with the same corners), and per
  // vertex whether it is on one (see FrontVisibility): the base's that the stroke
  // left and the changed slots' (in slot order).
  on_face.assign(vertices.size(), 0);
  {
    std::vector<int> face_slots;
    for (const int s : front.base_cut_face_slots())
      if (!(slot_flags[static_cast<std::size_t>(s)] & 1)) face_slots.push_back(s);
    for (const int s : now_slots)
      if (front.on_cut_face()[static_cast<std::size_t>(s)]) face_slots.push_back(s);
    std::sort(face_slots.begin(), face_slots.end());
    // Each face's corners sorted, as its key; the first slot of each key is kept, in slot
    // order: a key is looked up among those met so far (open addressing on its bits, -0 as 0).
    std::vector<std::array<double, 9>> keys(face_slots.size());
    std::vector<int> table(std::bit_ceil(2 * face_slots.size() + 1), -1);
    const std::size_t mask = table.size() - 1;
    for (std::size_t k = 0; k < face_slots.size(); ++k) {
      const auto& tri = triangles[static_cast<std::size_t>(face_slots[k])];
      for (const int v : tri) on_face[static_cast<size_t>(v)] = 1;
      std::array<Vec3, 3> corners{vertices[static_cast<size_t>(tri[0])], vertices[static_cast<size_t>(tri[1])], vertices[static_cast<size_t>(tri[2])]};
      std::sort(corners.begin(), corners.end(), [](const Vec3& l, const Vec3& r) {
        return std::lexicographical_compare(l.data(), l.data() + 3, r.data(), r.data() + 3);
      });
      auto& key = keys[k];
      // The nine coordinates' bits each times its own odd constant, summed, then mixed once:
      // independent products, not a chain of nine mixes (any hash gives the same faces).
      std::uint64_t sum = 0;
      for (int c = 0; c < 3; ++c)
        for (int d = 0; d < 3; ++d) {
          const double x = corners[static_cast<size_t>(c)][d] + 0.0;
          key[static_cast<size_t>(3 * c + d)] = x;
          std::uint64_t bits = 0;
          std::memcpy(&bits, &x, sizeof bits);
          sum += bits * (0x9e3779b97f4a7c15ULL + 2 * static_cast<std::uint64_t>(3 * c + d));
        }
      std::size_t at = mix64(sum) & mask;
      bool met = false;
      for (; table[at] >= 0; at = (at + 1) & mask)
        if (keys[static_cast<std::size_t>(table[at])] == key) {
          met = true;
          break;
        }
      if (met) continue;
      table[at] = static_cast<int>(k);
      faces.push_back(corners);
    }
  }
}

void FrontRemap::map_rows() {
  // The kept rows whose segment the cut crosses now (the second trigger, taken on the cut as
  // the surface shows it rather than on this step's sweep, which the stroke may have left out
  // in part: samples held, the front's transient part). Only a segment reaching into the box
  // of what the stroke made since the last mapping can have changed side: the other faces
  // were there when it was last tested. A base vertex's segment reaches at most front_reach
  // from it, so the base's vertices are taken from the box grown by that.
  face_index.emplace(*body.efg, faces);
  const auto segment_near = [&](int v) {
    const Vec3& x = vertices[static_cast<size_t>(v)];
    const Vec3& q = centres[static_cast<size_t>(embedding.elements[static_cast<size_t>(v)])];
    const Vec3 lo = x.cwiseMin(q).array() - inset, hi = x.cwiseMax(q).array() + inset;
    return (lo.array() <= changed_hi.array()).all() && (hi.array() >= changed_lo.array()).all();
  };
  if ((changed_lo.array() <= changed_hi.array()).all()) {
    const Vec3 grown = Vec3::Constant(cut.mapping.reach + inset);
    std::vector<int> candidates;
    front.base_vertices_in(changed_lo - grown, changed_hi + grown, candidates);
    for (const int v : candidates)
      if (v < kept && segment_near(v)) near.push_back(v);
    for (int v = kept; v < n; ++v)
      if (has_row[static_cast<std::size_t>(v - kept)] && segment_near(v)) near.push_back(v);
  }
  // (An empty subset would count every vertex.)
  if (!near.empty())
    count_wrong_side(*body.efg, vertices, triangles, embedding, *face_index, inset, near, &crossed, on_face, &around);
  std::vector<int> merged;
  std::set_union(remap.begin(), remap.end(), crossed.begin(), crossed.end(), std::back_inserter(merged));
  remap.swap(merged);
  merged.clear();
  std::set_union(remap.begin(), remap.end(), fresh.begin(), fresh.end(), std::back_inserter(merged));
  remap.swap(merged);
  // Each vertex sees its point through no cut face (what wrong_side below measures), the
  // crack front's vertices excepted.
  FrontVisibility visibility{&*face_index, inset, front.crack_front(), on_face};
  map_front_surface(*body.efg, vertices, triangles, planes, remap, embedding, mapped, &visibility, &around, &cut.mapping.cubes);
  for (const int v : remap)
    if (v < kept) cut.mapping.reach = std::max(cut.mapping.reach, reach_of(v));
  cut.mapping.mapped_base = base_vertices;
  cut.mapping.plane_counts.resize(planes.size());
  for (const int v : planed) cut.mapping.plane_counts[static_cast<std::size_t>(v)] = planes[static_cast<std::size_t>(v)].size();
  for (std::size_t v = static_cast<std::size_t>(kept); v < planes.size(); ++v) cut.mapping.plane_counts[v] = planes[v].size();
  cut.mapping.planed = front.planed_base_vertices();
}

void FrontRemap::write_surface() {
  // The body's and the render's triangles: the differing slots.
  body.surface.resize(slots_now);
  body.render_triangles.resize(3 * slots_now);
  body.render_cut_face.resize(slots_now, 0);
  for (const int s : differing) {
    const auto slot = static_cast<std::size_t>(s);
    if (slot >= slots_now) continue;
    body.surface[slot] = triangles[slot];
    for (std::size_t c = 0; c < 3; ++c) body.render_triangles[3 * slot + c] = static_cast<std::uint32_t>(triangles[slot][c]);
    body.render_cut_face[slot] = front.on_cut_face()[slot];
  }
  cut.mapping.changed_slots = std::move(now_slots);
  // Which vertices only fixed particles carry: taken again for every row when the fixed
  // particles changed (orphans pinned), else for the rows mapped now, the others moved along.
  if (region.fixed_changed) {
    set_fixed_vertices(body);
  } else {
    body.fixed_vertices.resize(vertices.size(), 0);
    for (const auto& [v, flag] : moved_fixed_at) body.fixed_vertices[v] = flag;
    for (const int v : remap) body.fixed_vertices[static_cast<size_t>(v)] = fixed_vertex(body, v);
  }
  // Positions: on the CPU only the rows that changed (mapped, or moved with their vertex's
  // new number) are formed again, the others are those update_surface took from the same
  // particle positions; the GPU's are single precision, so all are taken again.
  if (ctx.on_gpu) {
    CorotationalEfg::surface_positions(embedding, body.state.positions, body.surface_positions);
  } else {
    body.surface_positions.conservativeResize(3 * static_cast<Eigen::Index>(n));
    for (const int v : remap)
      if (v < kept) set_surface_position(body, v);
    // The stroke's vertices: the moved rows not mapped again take their position along.
    std::vector<std::uint8_t> taken(static_cast<std::size_t>(n - kept), 0);
    for (std::size_t k = 0; k < moved_from.size(); ++k) {
      const int v = moved_from[k];
      if (std::binary_search(remap.begin(), remap.end(), v) || !moved_positions[k].allFinite()) continue;
      body.surface_positions.segment<3>(3 * static_cast<Eigen::Index>(v)) = moved_positions[k];
      taken[static_cast<std::size_t>(v - kept)] = 1;
    }
    for (int v = kept; v < n; ++v)
      if (!taken[static_cast<std::size_t>(v - kept)]) set_surface_position(body, v);
  }
  ctx.report.ms_mapping += watch.ms();
  watch.restart();
}

void FrontRemap::check() {
  if (recount) {
    cut.topology = surface_topology(body.surface);
  } else {
    const SurfaceTopology touched_edges_now = surface_topology(edges_now, touched_now);
    cut.topology.boundary_edges += touched_edges_now.boundary_edges - touched_edges_before.boundary_edges;
    cut.topology.nonmanifold_edges += touched_edges_now.nonmanifold_edges - touched_edges_before.nonmanifold_edges;
  }
  const SurfaceTopology topology = cut.topology;
  ctx.totals.worst_boundary_edges = std::max(ctx.totals.worst_boundary_edges, topology.boundary_edges);
  ctx.totals.worst_nonmanifold_edges = std::max(ctx.totals.worst_nonmanifold_edges, topology.nonmanifold_edges);
  ctx.totals.vertices_remapped += mapped.mapped;
  ctx.totals.relaxed_fallbacks += mapped.relaxed_fallbacks;
  // Against the cut faces the surface shows: a vertex pulled a tenth of a cell inside, joined
  // to its integration point, must cross them an even number of times.
  // The crack front's vertices, where the two sides meet, belong to neither: not counted.
  // Kept per vertex and taken again where it can have changed: the remapped vertices (those
  // near what the stroke made and not remapped were just tested, their rows as they are).
  const auto& crack = front.crack_front();
  const auto counts = [&](int v) { return cut.mapping.wrong_side[static_cast<std::size_t>(v)] != 0 && crack[static_cast<std::size_t>(v)] == 0 ? 1L : 0L; };
  for (int v = cut.mapping.wrong_upto; v < kept; ++v) cut.mapping.wrong_base += counts(v);
  cut.mapping.wrong_upto = std::max(cut.mapping.wrong_upto, kept);
  std::vector<int> across;
  if (!remap.empty()) count_wrong_side(*body.efg, vertices, triangles, embedding, *face_index, inset, remap, &across, on_face, &around);
  std::vector<int> tested;
  std::set_union(remap.begin(), remap.end(), near.begin(), near.end(), std::back_inserter(tested));
  for (const int v : tested) {
    if (v < kept) cut.mapping.wrong_base -= counts(v);
    cut.mapping.wrong_side[static_cast<std::size_t>(v)] = 0;
  }
  for (const int v : across) cut.mapping.wrong_side[static_cast<std::size_t>(v)] = 1;
  for (const int v : crossed)
    if (!std::binary_search(remap.begin(), remap.end(), v)) cut.mapping.wrong_side[static_cast<std::size_t>(v)] = 1;
  for (const int v : tested)
    if (v < kept) cut.mapping.wrong_base += counts(v);
  long wrong = cut.mapping.wrong_base;
  for (int v = kept; v < n; ++v) wrong += counts(v);
  ctx.totals.wrong_side = std::max(ctx.totals.wrong_side, wrong);
  ctx.totals.elements_linked_across = update_elements_linked_across(
      *body.efg, *cut.rest_cut, cut.linked.linked, region.lo, region.hi, &region.changed, &cut.linked.link_boxes, &cut.linked.seen, &cut.linked.index);
  ctx.report.ms_checks += watch.ms();
}

}  // namespace

void remap_front_surface(CutContext& ctx, const RemapRegion& region) {
  FrontRemap(ctx, region).run();
}

}  // namespace incise::physics
