// The beams of `incise bench accuracy` (bench/accuracy.cpp's file comment describes the
// report): their cases and meshes (accuracy_meshes.cpp), the models solved and timed on them
// (accuracy_models.cpp). Internal to the bench: the run loop (accuracy_runs.cpp) and the
// tests' entry points (accuracy.hpp) use it.
#pragma once

#include "physics/core/model.hpp"
#include "physics/cut/volume_cut.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/fem/static_solve.hpp"
#include "physics/fem/tet_mesh.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace incise::bench::accuracy {

using physics::Material;
using physics::Vec3;
using physics::Vector;

constexpr double beam_length = 0.2;
constexpr double hexagon_radius = 0.015;
constexpr double square_half_side = 0.01;
constexpr double cut_x = 0.1;
constexpr double gravity = 9.81;
inline const Material beam_material{10e6, 0.3, 1000};
// Euler-Bernoulli q L^4 / (8 E I) plus the Timoshenko shear term, as in the FEM tests.
constexpr double b1_beam_theory_tip = 5.947e-3;

enum class Shape { hexagon, square };

struct Case {
  std::string name;
  Shape shape;
  Vec3 acceleration;
  bool cut;
};
// bend, stretch, bend_cut, stretch_cut (the hexagon) and b1 (the square), in the report's order.
std::vector<Case> all_cases();

bool inside_shape(Shape shape, const Vec3& p);
Vec3 box_min(Shape shape);
Vec3 box_max(Shape shape);

// ---------------------------------------------------------------------------------------------
// Sections and meshes (accuracy_meshes.cpp).

struct Section {
  std::vector<Eigen::Vector2d> points;  // (y, z)
  std::vector<std::array<int, 3>> triangles;
};
Section hexagon_section(int m);
Section square_section(int cells);
double triangle_area(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c);

// The cut references' sections: rows either side of the crack front, crack_section_ny across.
constexpr int crack_section_ny = 8;
// The cut references: quarter-point elements take the crack front's singularity, so a milder
// grading does better than the uncut references' (accuracy_meshes.cpp).
constexpr double crack_grading_power = 1.5;
// The x layers of a cut reference with `nz` rows either side of the front.
std::vector<double> crack_layers(int nz, double power);

// 10-node tets from 4-node ones: a midpoint node per edge, shared between tets.
struct QuadraticMesh {
  physics::QuadraticTetMesh mesh;
  std::map<std::pair<int, int>, int> midpoints;  // sorted corner pair -> node
};
QuadraticMesh make_quadratic(const physics::TetMesh& linear);
void quarter_points_at_crack_front(QuadraticMesh& quadratic);
// Opens the cut: nodes on x = cut_x with z > 0 get a twin used by the tets on the x < cut_x
// side (instantiated for 4- and 10-node tets).
template <std::size_t corners>
void open_cut(Vector& rest, std::vector<std::array<int, corners>>& tets);
// The area-weighted mean displacement over the tip face x = L (exact face integrals; through
// the midside nodes when `quadratic` is given).
Vec3 tip_mean(const physics::TetMesh& linear, const Vector& u, const QuadraticMesh* quadratic);
std::vector<uint8_t> clamped_nodes(const Vector& rest);
// A tet mesh of a case's body at a resolution (accuracy_meshes.cpp says what `section`,
// `layers` and `graded` mean).
physics::TetMesh case_mesh(const Case& c, int section, int layers, bool graded = false);

// ---------------------------------------------------------------------------------------------
// Models, solves and timing (accuracy_models.cpp).

// HRZ lumping of the 10-node tet.
Vector quadratic_lumped_masses(const physics::QuadraticTetMesh& mesh, double density);
// Solves K u = load for several loads with one factorisation, u = 0 on the fixed nodes.
std::vector<Vector> solve_static_loads(const physics::SparseMatrix& stiffness, const std::vector<Vector>& loads,
                                       const std::vector<uint8_t>& fixed);

struct Timing {
  double ms_per_step = 0;
  double cg_iterations = 0;
  bool converged = true;
  std::string preconditioner = "jacobi";  // what ms_per_step's CG was preconditioned with
  double build_ms = 0;                    // its factor's build, once, before the timed steps
  // Today's Jacobi CG on the same steps, where the row has another preconditioner (NaN: none).
  double jacobi_ms_per_step = std::numeric_limits<double>::quiet_NaN();
  double jacobi_cg_iterations = std::numeric_limits<double>::quiet_NaN();
};
// Implicit Euler from rest under the load at dt = 1/60 with the scenes' CG: their default
// preconditioner where the model has a rest stiffness (EFG, tet FEM), and Jacobi beside it.
Timing time_steps(physics::DeformableModel& model, const std::vector<uint8_t>& fixed, const Vector& load, int steps);

// A linear model from an assembled stiffness (the 10-node tets have no corotational model):
// drives the same implicit Euler integrator for the timing of the tet10 rows.
std::unique_ptr<physics::DeformableModel> make_assembled_linear_model(physics::SparseMatrix stiffness, Vector rest,
                                                                      Vector masses);

// One reference mesh: 10-node tets (quarter points and the opened cut for the cut cases),
// solved statically for each case's load; `tips` per case.
struct ReferenceLevel {
  QuadraticMesh quadratic;
  physics::TetMesh linear;
  std::vector<uint8_t> fixed;
  std::vector<Vec3> tips;
};
ReferenceLevel solve_reference_level(const std::vector<Case>& cases, int section, int layers);

// The EFG models' tip face: the centroids of a fine triangulation, with their areas.
struct TipFace {
  Vector points;
  std::vector<double> weights;
  double area = 0;
};
TipFace make_tip_face(Shape shape);
// The area-weighted mean displacement over the tip face, through the surface embedding.
Vec3 efg_tip_mean(const physics::CorotationalEfg& model, const physics::SurfaceEmbedding& embedding,
                  const TipFace& face, const Vector& u);
// An EFG model of a case's body (settings.spacing set), the cut cases cut by the geometry
// (`cutter` false: settings.cuts) or by the cutter (the report in `cut_report`).
std::unique_ptr<physics::CorotationalEfg> make_case_efg(Shape shape, bool cut, bool cutter,
                                                        physics::EfgSettings settings,
                                                        physics::VolumeCutReport* cut_report = nullptr);

}  // namespace incise::bench::accuracy
