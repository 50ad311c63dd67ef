#include "engine/models/efg_settings.hpp"

namespace incise::engine {

void read_efg_settings(Reader& er, BodySpec& b) {
  b.efg.neighbours = er.integer("neighbours", false, 8, 4, 8);
  if (b.efg.neighbours != 4 && b.efg.neighbours != 8)
    er.error(er.child("neighbours"), "must be 4 or 8");
  if (er.has("support_factor"))
    b.efg.support_factor = er.number("support_factor", false, 3, 1, 10, true);
  b.efg.samples_per_axis = er.integer("samples_per_axis", false, 4, 1, 64);
  b.efg.estimate_volumes = er.boolean("estimate_volumes", true);
  b.efg.threads = er.integer("threads", false, 2, 1, 64);
  if (er.has("surface_resolution"))
    b.efg.surface_resolution = er.number("surface_resolution", false, 0.005, 1e-4, 10, true);
  // A thin edge (thinner than a surface cell) comes out serrated from the voxel boundary; a
  // closed surface mesh is already the surface the blade should cut.
  const bool base_given = er.has("base_surface");
  b.efg.base_surface_mesh = er.text("base_surface", false, "voxel", {"voxel", "mesh"}) == "mesh";
  if (base_given && !b.cuttable)
    er.error(er.child("base_surface"), "only cuttable bodies (\"cuttable\": true) have a base surface to cut");
  if (b.efg.base_surface_mesh && !b.mesh)
    er.error(er.child("base_surface"), "'mesh' needs the body's surface from a `mesh` file");
  const bool cut_surface_given = er.has("cut_surface");
  // One cut-surface design: the voxel boundary separated along the cut gave way to the
  // thesis's front (seed 004 §2.5), which follows the blade's path rather than cells.
  if (er.text("cut_surface", false, "front", {"voxel", "front"}) == "voxel")
    er.error(er.child("cut_surface"), "'voxel' was removed: the thesis's front surface ('front', the default) "
                                      "replaced it; drop the key or write \"front\"");
  if (!b.cuttable && cut_surface_given)
    er.error(er.child("cut_surface"), "only cuttable bodies (\"cuttable\": true) have a cut surface");
}

}  // namespace incise::engine
