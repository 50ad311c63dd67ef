// Van Gelder's (1998) spring stiffnesses, the negative control of Fléchon's report (seed 003,
// §2.3; digest seed-000-003.md B.5 and D9): springs on the edges of a tetrahedral mesh whose
// stiffness is the leading term of his triangle formula with the triangles' areas replaced by
// the tetrahedra's volumes ("3-D uses the tet volumes analogously"), k_c = E / (1 + nu)
// sum_T V_T / c^2 over the tetrahedra T sharing edge c (rest length c). The triangle formula's
// second term, E nu / (1 - nu^2) (a^2 + b^2 - c^2) / (8 |T|), has no stated 3-D form and is
// left out: the formula is valid essentially for nu = 0 (the report), where it is Van Gelder's
// E sum V / c^2. Baudet measured its E some 25 % off in traction. Used by the tests and
// `incise bench accuracy`'s traction case, not as a scene model.
#pragma once

#include "physics/fem/tet_mesh.hpp"
#include "physics/mss/hex_mass_spring.hpp"

#include <vector>

namespace incise::physics {

// One spring per distinct tet edge (damping 0). Throws std::invalid_argument on a degenerate
// tetrahedron, a non-positive E or nu outside [0, 0.5).
std::vector<Spring> van_gelder_springs(const TetMesh& mesh, double youngs_modulus, double poisson_ratio);

}  // namespace incise::physics
