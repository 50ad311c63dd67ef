#include "physics/cut/cut_body.hpp"

#include <numeric>

namespace incise::physics {

// Every member is copied here: a member added to CutData must be added to this list.
CutData::CutData(const CutData& other, CorotationalEfg& model)
    : cutter(other.cutter ? std::make_unique<VolumeCutter>(*other.cutter, model) : nullptr),
      surface(other.surface ? std::make_unique<FrontSurface>(*other.surface) : nullptr),
      rest_cut(other.rest_cut ? std::make_unique<RestCut>(*other.rest_cut) : nullptr),
      mapping(other.mapping),
      topology(other.topology),
      linked(other.linked),
      blade_pieces(other.blade_pieces),
      stroke_folds(other.stroke_folds),
      engaged(other.engaged),
      rest_edge(other.rest_edge),
      rest_edge_far(other.rest_edge_far),
      previous_positions(other.previous_positions),
      orphans_pinned(other.orphans_pinned) {
  // The mapping's candidates were binned from the body's model: the copy's are its copy's.
  if (mapping.cubes.model) mapping.cubes.model = &model;
}

CutData make_cut_data(const BodyModel& model, BodyData& body, const CutModel& cut_model, std::vector<Vec3> vertices,
                      std::vector<std::array<int, 3>> triangles, const std::function<bool(const Vec3&)>* inside) {
  CutData cut;
  CorotationalEfg& efg = *body.efg;
  cut.surface = std::make_unique<FrontSurface>(std::move(vertices), std::move(triangles), cut_model.front_width());
  // The rest cut binned at twice the surface cell: its triangles are about that size.
  cut.rest_cut = std::make_unique<RestCut>(2 * cut_model.surface_cell);
  cut.cutter = std::make_unique<VolumeCutter>(efg, 1e-6, 0.5 * cut_model.spacing);
  body.embedding.emplace();
  std::vector<int> all(cut.surface->vertices().size());
  std::iota(all.begin(), all.end(), 0);
  FrontMappingReport mapping;
  FrontVisibility through_body;
  through_body.inside = inside;
  map_front_surface(efg, cut.surface->vertices(), cut.surface->triangles(), cut.surface->vertex_planes(), all,
                    *body.embedding, mapping, inside != nullptr ? &through_body : nullptr);
  cut.mapping.unseen_at_build = mapping.unseen;
  cut.mapping.plane_counts.assign(all.size(), 0);
  cut.mapping.mapped_base = cut.surface->base_vertex_count();
  cut.mapping.identity.first = cut.mapping.mapped_base;
  cut.topology = surface_topology(cut.surface->triangles());
  // The linked-across check's link boxes taken now rather than at the first cut, whose step
  // they would slow.
  update_elements_linked_across(efg, *cut.rest_cut, cut.linked.linked, model.rest_lo, model.rest_hi, nullptr,
                                &cut.linked.link_boxes, &cut.linked.seen, &cut.linked.index);
  body.surface = cut.surface->triangles();
  body.render_triangles.clear();
  for (const auto& t : body.surface)
    for (int v : t) body.render_triangles.push_back(static_cast<std::uint32_t>(v));
  body.render_cut_face = cut.surface->on_cut_face();
  return cut;
}

}  // namespace incise::physics
