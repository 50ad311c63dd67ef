// The needle in a meshless (EFG) body (seed 002 §2.3 on seed 004's model). The needle acts on
// tissue points through its zones; an EFG body's particles are not such points (they lie on a
// grid twice the integration spacing, a boundary one often outside the body, seed 004 §1.3), so
// its tissue points are its integration points: each lies inside the body (the centroid of a
// partial cube's inside), they are twice as dense as the particles, and each carries the MLS
// shape functions of its neighbourhood, phi_n(x_e), which the model already keeps. With them
//   x_e = sum_n phi_n(x_e) x_n             (linear MLS reproduces the rest centres exactly),
//   f_n = phi_n(x_e) f_e                    (a point force at x_e, by virtual work; sum_n f_n = f_e),
// as the embedded surface passes a contact force to the particles (body_contact.hpp). The
// boundary points, the puncture's, are those of the cubes the body's surface crosses (a partial
// cube) or of a cube beside one without an element (across a face, or the grid's edge).
#pragma once

#include "physics/core/model.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/needle/needle_settings.hpp"
#include "physics/needle/needle_tissue.hpp"

#include <cstdint>
#include <utility>
#include <vector>

namespace incise::physics {

// The integration points as the needle's tissue: rest positions the element centres, neighbours
// within 1.8 integration spacings, the boundary as above (make_needle_tissue's intensities).
NeedleTissue make_efg_needle_tissue(const CorotationalEfg& efg, const NeedleSettings& settings);

// Per element, 1 when its integration point is on the body's boundary (see the file comment).
std::vector<std::uint8_t> efg_boundary_points(const CorotationalEfg& efg);

// out (3 x elements) = the integration points' positions for particle positions x.
void efg_point_positions(const CorotationalEfg& efg, const Vector& x, Vector& out);

// Forces on integration points as forces on the particles (f_n = sum_e phi_n(x_e) f_e), one
// spring per particle reached (no stiffness: the needle's forces are explicit), increasing
// particle; fixed particles take none.
std::vector<NodalSpring> efg_point_forces_on_particles(const CorotationalEfg& efg,
                                                       const std::vector<std::pair<int, Vec3>>& point_forces,
                                                       const std::vector<std::uint8_t>& fixed);

}  // namespace incise::physics
