// Corotated element-free Galerkin (EFG) model on a background grid: Magnoux 2020, chapters 4
// and 6, with the corotation of Brunet, Magnoux et al. 2019. Every equation and the fixed
// typos are in seed-004 §1.
//
// - Integration grid: cubes of side a, one integration point at each centre (one-point
//   quadrature); each cube's volume V_e is the part inside the body, estimated by sampling.
// - Particles (the degrees of freedom) on every other grid vertex, 2a apart; each integration
//   point takes the corners of its particle cell as neighbours (8, or the 4 nearest). In a
//   partial cube the point sits at the centroid of the part inside (EfgSettings::centroid_points).
// - Linear MLS shape functions with the quartic spline, computed once in the rest shape.
// - Per element, a rotation R_e, frozen between update_rotations calls: the polar rotation of
//   the MLS deformation gradient F_e = sum_n x_n (x) grad phi_n (EfgSettings::rotation, default
//   deformation_gradient), or, as in the thesis, of the shape-matching fit F_e = sum_n x_n (x)
//   c_n (the least-squares linear fit of the neighbours' motion); with it (Algorithm 3 made
//   corotational):
//     grad u_e = sum_n (R_e^T x_n - X_n) (x) grad phi_n,   sigma = 2 mu eps + lambda tr(eps) I,
//     f_n += -V_e R_e sigma grad phi_n,   K p likewise with R_e^T p_n and no rest term.
//
// Rotation (thesis §7.1.1: thin slices move spontaneously or go unstable with shape
// matching, fix proposed there: take the rotation from the deformation field). Only with R_e
// the polar rotation of the very F_e the strain is taken from is R_e^T F_e symmetric, so that
// each element's F_e (R_e sigma)^T is symmetric: its forces then exert no net torque and are
// the exact gradient of elastic_energy (the dR terms vanish), i.e. conservative. With the
// shape-matching fit they are neither wherever the fit and the MLS gradient differ. For a full
// cube with a centred point and its 8 cell corners (equal weights) the two coincide exactly,
// so the bulk is unchanged; they differ in partial cubes and in neighbourhoods re-selected by
// cuts. Hence the default: on a cut slice the net torque and the energy gained drop by eight
// orders of magnitude or more (test EfgRotation, the stability bench's thin-slice study) while
// B1 deflects the same to the printed digits (docs/physics-choices.md, "rotation").
//
// Lumped masses m_i = sum_e phi_i(x_e) rho V_e. A particle outside the body that only far
// corners reach can get a negative mass (phi < 0 there); it is taken out of those
// neighbourhoods (refilled with the nearest allowed particles if needed) and dropped.
//
// Storage follows Magnoux ch. 6: per-element rows of a fixed stride (ELL) for the neighbour
// indices, phi, grad phi and the shape matching coefficients, with a row-length vector, so a
// GPU backend can take the same arrays. Neighbourhoods stay editable (set_neighbourhood);
// particles are never added.
//
// Element loops run on the model's executor (physics/core/executor.hpp; the engine hands one
// built on its threads, a model given none runs them on the calling thread): the scatters go
// over 4 fixed partitions of the elements, each into its own buffer in element order, and the
// buffers are added in partition order. The result is therefore bitwise the same for any
// executor and thread count (more than 4 threads would idle in the scatters). The const
// methods use internal scratch memory and the executor: one call at a time per model.
#pragma once

#include "physics/core/executor.hpp"
#include "physics/core/model.hpp"
#include "physics/fem/material.hpp"
#include "physics/solve/element_assembly.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <utility>
#include <span>
#include <vector>

namespace incise::physics {

namespace efg_build {
struct ParticleGrid;  // efg_build.hpp
}

// A zero-thickness planar cut: the open parallelogram corner + s edge_u + t edge_v, s, t in
// (0, 1). A point exactly on its plane counts as lying on the side edge_u x edge_v points to;
// a segment through the rim is not cut.
struct CutRectangle {
  Vec3 corner = Vec3::Zero();
  Vec3 edge_u = Vec3::Zero();
  Vec3 edge_v = Vec3::Zero();

  // True if the segment from `from` to `to` passes through the parallelogram.
  bool blocks(const Vec3& from, const Vec3& to) const;
};

// Where each element's rotation R_e comes from (see the file comment).
enum class EfgRotation {
  shape_matching,        // polar(sum_n x_n (x) c_n), the least-squares fit (thesis, [72])
  deformation_gradient,  // polar(sum_n x_n (x) grad phi_n), the MLS gradient at the point
};

struct EfgSettings {
  double spacing = 0.005;        // a, side of the integration cubes (m); particles are 2a apart
  int neighbours = 8;            // per integration point: 8 (cell corners) or 4 (nearest corners)
  // h = support_factor x the distance to the farthest neighbour (> 1, so that every neighbour
  // weighs). The thesis's constant is 3, on a "radius of the region of influence" it leaves
  // undefined (seed-004 §1.4). Read as 3 x the farthest corner (h = 7.8 a) the weights are
  // nearly flat, the fit ignores the cells' bilinear modes and the model is far too soft (B1
  // +29 % at 0.6k dofs). A factor near 1 keeps the fit local; below 1.05 the farthest corner's
  // weight vanishes (w(1 / 1.05) = 3e-4) and B1 stiffens. 1.1 is B1's best, and at the
  // thesis's size (about 10k dofs) every accuracy case is as accurate as with 2/sqrt(3) (h = 3 a
  // at a cube's centre) or better; the cut beam in stretching, the worst case, is the most
  // sensitive (its cut neighbourhoods reach 3.5 a and more: a larger factor widens their
  // support and softens the region by the cut). docs/physics-choices.md has the table.
  // Stating h relative to the farthest neighbour keeps every neighbour weighing for
  // off-centre points and cut neighbourhoods.
  double support_factor = 1.1;
  // Volume estimation: samples_per_axis^3 points per cube (the thesis gives no count). 4 puts
  // the sampled boundary up to a/8 off the true one, which moves a beam's second moment of area
  // by several % (the hexagon's top z = 13 mm sampled as 12.5 mm at a = 5 mm: -7 %).
  int samples_per_axis = 8;
  bool estimate_volumes = true;  // false: a cube with any sample inside counts a full a^3
  // Where a partial cube's integration point sits. The thesis puts it at the cube centre
  // (false), which may lie outside the body: the one-point rule then weighs the strain at the
  // wrong place, and the hexagon beam's second moment of area comes out +9 % (a = 5 mm), -0.4 %
  // (3.3 mm), +1.4 % (2 mm), a bending error that does not decrease monotonically. At the
  // centroid of the inside samples (true) the rule integrates linear fields exactly on the
  // part that is inside. Full cubes are unaffected.
  bool centroid_points = true;
  // Models with fewer elements run their loops on the calling thread only, whatever their
  // executor: handing a sub-millisecond loop to another thread costs more than it saves, and
  // far more when the cores are shared. The partitions, and so the results, are the same
  // either way.
  int threaded_elements = 4096;
  int row_capacity = 0;          // stride of the rows; 0 = the longest row at build
  // Cuts made at build time (the visibility criterion). For each element, the cell corners
  // whose link to its integration point crosses a cut are replaced: by the particle one step
  // beyond the hidden corner's neighbour in the cell along an axis, else by the nearest
  // visible particles, until there are `neighbours` particles spanning 3 dimensions.
  std::vector<CutRectangle> cuts;
  // true: a hidden corner is replaced along the axis nearest the hiding cut's normal first, i.e.
  // by the particle behind the element's own side of its cell. false: the nearest of the
  // three axis candidates, which next to a crack front is often the particle on the cut plane
  // below the front, a link around the tip that stiffens the cut beam (the accuracy bench's
  // stretch_cut, a few points nearer the reference with this rule: docs/physics-choices.md).
  bool replace_along_cut_normal = true;
  // Particles on a cut's front edge (r = 0) are hidden from the integration points on the
  // cut's negative side that lie beside the cut farther than this from the front line.
  // infinity (a link through the rim is not cut): every point within a cell of the front
  // stays tied to it, so the crack is effectively up to 2a shorter and the cut beam too stiff.
  // 0: the front particles reach those points only from the positive side and from beyond the
  // front, so the field beside the cut opens right down to the front line. On the accuracy
  // bench's cut beams 0 converges like O(a) and is the nearest to the extrapolated references
  // at 10k dofs (docs/physics-choices.md has the table).
  double front_hidden_beyond = 0;
  // The rotation of the corotation (file comment: "Rotation").
  EfgRotation rotation = EfgRotation::deformation_gradient;
};

// Each render-surface vertex follows one integration point: x_v = sum_i w_i x_i with the MLS
// shape functions of that point's neighbourhood evaluated at the vertex (seed-004 §2.6).
// Rows of a fixed stride, like the model's.
struct SurfaceEmbedding {
  int stride = 0;
  std::vector<int> elements;     // per vertex: the nearest integration point
  std::vector<int> row_lengths;  // per vertex
  std::vector<int> particles;    // vertex * stride + k
  std::vector<double> weights;   // vertex * stride + k
  int vertex_count() const { return static_cast<int>(elements.size()); }
};

// The model's read-only part (MuJoCo's mjModel to the rows' mjData): what the build decides
// once and no step or cut changes. A cut re-selects neighbourhoods, recomputes their shape
// functions, moves masses and deactivates elements: those stay in the model's own data. Copies
// of a model share this part.
struct EfgRestShape {
  Material material;
  EfgSettings settings;
  double lambda = 0, mu = 0;
  Vec3 origin = Vec3::Zero();
  std::array<int, 3> cube_counts{};
  Vector positions;                                   // particles' rest positions, 3n
  std::vector<std::array<int, 3>> particle_cells;     // per particle
  std::vector<Vec3> centres;                          // per element: its integration point
  std::vector<std::array<int, 3>> element_cubes;      // per element
  std::vector<int> element_of_cube;  // cube index -> element, -1 for empty cubes
};

struct EfgRestStiffnessCache;  // efg_rest_stiffness.cpp
std::shared_ptr<EfgRestStiffnessCache> make_efg_rest_stiffness_cache();

class CorotationalEfg final : public DeformableModel {
 public:
  // The body is {X in [box_min, box_max] : inside(X)}. The grids are centred on the box, with
  // an even number of cubes of side a per axis covering it: when an extent is a multiple of
  // 2a, particles lie on both faces.
  // Throws std::invalid_argument on bad settings or material, if nothing is inside, if an
  // integration point has no valid neighbourhood, or if a particle's lumped mass is not
  // positive (the message names the element or the particle).
  // The build's loops, and the element loops after it, run on `executor` (see set_executor).
  CorotationalEfg(const std::function<bool(const Vec3&)>& inside, Vec3 box_min, Vec3 box_max,
                  const Material& material, const EfgSettings& settings,
                  Executor* executor = nullptr);
  // The box itself.
  CorotationalEfg(Vec3 box_min, Vec3 box_max, const Material& material,
                  const EfgSettings& settings, Executor* executor = nullptr);
  ~CorotationalEfg() override;
  CorotationalEfg(CorotationalEfg&&) noexcept;
  CorotationalEfg& operator=(CorotationalEfg&&) noexcept;
  // Copies everything, the scratch of the element loops included; the copy runs its loops on
  // the same executor until set_executor says otherwise.
  CorotationalEfg(const CorotationalEfg&);
  CorotationalEfg& operator=(const CorotationalEfg&);

  // DeformableModel.
  int node_count() const override { return static_cast<int>(masses_.size()); }
  const Vector& rest_positions() const override { return shape_->positions; }
  const Vector& lumped_masses() const override { return masses_; }
  void update_rotations(const Vector& x) override;
  void add_elastic_forces(const Vector& x, Vector& f) const override;
  void add_stiffness_product(const Vector& p, Vector& out) const override;
  // Both in one pass over the rows, each bitwise as the two calls give it.
  void add_forces_and_stiffness_product(const Vector& x, Vector& f, const Vector& p, Vector& out) const override;
  void add_stiffness_diagonal(Vector& diagonal) const override;
  // With rotations extracted from x itself, so it is invariant under rigid motions of x.
  double elastic_energy(const Vector& x) const override;
  std::function<BlockMatrix()> rest_stiffness_job() const override;
  const BlockMatrix* current_stiffness() const override;  // efg_current_stiffness.cpp
  bool has_current_stiffness() const override { return true; }
  void plan_current_stiffness() const override;           // efg_current_stiffness.cpp
  void node_rotations(std::vector<Eigen::Quaterniond>& out) const override;
  double node_spacing() const override;
  std::unique_ptr<DeformableModel> clone() const override;

  // Where the element loops run: the given executor, which must outlive its use here, or the
  // calling thread (serial_executor) for nullptr. The model owns no thread.
  void set_executor(Executor* executor);
  Executor& executor() const override { return *executor_; }

  // Topology. Rows: element * row_stride() + k for k < row_lengths()[element].
  int element_count() const { return static_cast<int>(volumes_.size()); }
  int row_stride() const { return stride_; }
  const std::vector<int>& row_lengths() const { return row_lengths_; }
  const std::vector<int>& neighbours() const { return neighbours_; }
  const std::vector<double>& shape_values() const { return shape_values_; }        // phi_n(x_e)
  const std::vector<Vec3>& shape_gradients() const { return shape_gradients_; }    // grad phi_n(x_e)
  // c_n with F_e = sum_n x_n (x) c_n the least-squares linear fit of the neighbourhood.
  const std::vector<Vec3>& matching_coefficients() const { return matching_coefficients_; }
  const std::vector<Vec3>& element_centres() const { return shape_->centres; }
  const std::vector<double>& element_volumes() const { return volumes_; }
  const std::vector<double>& element_supports() const { return supports_; }  // h per element
  const std::vector<Mat3>& rotations() const { return rotations_; }
  // Grid coordinates (i, j, k) of each particle (position grid_origin() + 2a (i, j, k)) and of
  // each element's cube (centre grid_origin() + a (i + 1/2, j + 1/2, k + 1/2); the element's
  // integration point, element_centres(), lies in that cube).
  const std::vector<std::array<int, 3>>& particle_grid_coordinates() const { return shape_->particle_cells; }
  const std::vector<std::array<int, 3>>& element_grid_coordinates() const { return shape_->element_cubes; }
  double spacing() const { return shape_->settings.spacing; }
  const Vec3& grid_origin() const { return shape_->origin; }
  const EfgSettings& settings() const { return shape_->settings; }
  const Material& material() const { return shape_->material; }
  // The read-only part (shared by copies of this model).
  const std::shared_ptr<const EfgRestShape>& rest_shape() const { return shape_; }
  double total_volume() const;  // sum of V_e

  // Replaces an element's neighbourhood (existing particle indices, at least 4, distinct,
  // spanning 3 dimensions), recomputes its shape functions in the rest shape and moves its
  // mass rho V_e to the new neighbours (seed-004 §2.4 steps 3 and 4). Grows the row stride if
  // needed. Throws std::invalid_argument, leaving the model unchanged, if the neighbourhood is
  // invalid or a particle's mass would become non-positive.
  void set_neighbourhood(int element, std::span<const int> particles);
  // Particles that set_neighbourhood left without any element, in the order it left them
  // (they keep their mass and influence nothing: pin them).
  const std::vector<int>& orphaned_particles() const { return orphans_; }
  // Cutting: takes an element out of the mechanics when no valid neighbourhood is left (the
  // thesis's isolated element, seed 004 §4.3.3): its volume becomes zero, its mass leaves its
  // particles (a particle left by every element is orphaned, one left with no mass keeps a
  // floor of 1e-3 of the element's mass). Its row stays, so the DOFs do not change.
  void deactivate_element(int element);
  bool element_active(int element) const { return volumes_[static_cast<size_t>(element)] > 0; }
  int deactivated_elements() const { return deactivated_; }
  int masses_floored() const { return masses_floored_; }
  // Elements whose mass is shared by the positive part of phi (see set_neighbourhood).
  int positive_mass_elements() const {
    return static_cast<int>(std::count(positive_mass_.begin(), positive_mass_.end(), 1));
  }

  // Surface embedding (seed-004 §2.6): each vertex (3n rest positions) maps to its nearest
  // integration point (ties to the lower index) and that point's neighbourhood, with the MLS
  // shape functions evaluated at the vertex.
  // With `inside` (the body's inside test), to the nearest point it sees through the body: the
  // segment from the vertex to the point stays inside (sampled every a / 8, from a / 20 off the
  // vertex, which lies on the surface). Without it a vertex on a thin feature (a fin, a folded
  // edge thinner than the particle spacing) beside another part of the body across a gap may
  // take a point on the other part, and follows it rather than its own feature. A vertex that
  // sees no point within embed_visible_reach_rings cubes of the nearest takes the nearest, and
  // is counted in `unseen`.
  SurfaceEmbedding embed_surface(const Vector& rest_vertices,
                                 const std::function<bool(const Vec3&)>* inside = nullptr,
                                 int* unseen = nullptr) const;
  static constexpr int embed_visible_reach_rings = 3;
  // Whether the segment from a surface vertex to a point stays inside the body (`inside`),
  // sampled every a / 8 from a / 20 off the vertex: embed_surface's criterion, and the one
  // map_front_surface takes for a cuttable body's first mapping (FrontVisibility::inside).
  static bool sees_through_body(const std::function<bool(const Vec3&)>& inside, const Vec3& vertex, const Vec3& point,
                                double a);
  // out (resized to 3 x vertices) = the embedded vertex positions for particle positions x,
  // vertices on `executor`'s threads (each vertex its own sum: the same bits on any executor).
  static void surface_positions(const SurfaceEmbedding& embedding, const Vector& particle_positions,
                                Vector& out, Executor& executor = serial_executor());

 private:
  // The build, step by step: the settings checked, the grids laid over the box, the elements
  // sampled (V_e, seed 004 §1.2), their neighbourhoods selected (§1.3; cells' corners, those a
  // build-time cut hides replaced), the particles nothing uses dropped, the rows filled and
  // their shape functions computed, and the particles whose lumped mass is not positive
  // taken out of the neighbourhoods until every mass is (§1.5).
  void build(const std::function<bool(const Vec3&)>& inside, Vec3 box_min, Vec3 box_max);
  using ParticleGrid = efg_build::ParticleGrid;
  void validate_settings(const Vec3& box_min, const Vec3& box_max) const;
  ParticleGrid lay_grids(const Vec3& box_min, const Vec3& box_max);
  void sample_elements(const std::function<bool(const Vec3&)>& inside);
  std::vector<std::vector<int>> select_neighbourhoods(const ParticleGrid& grid) const;
  std::vector<int> visible_neighbourhood(const ParticleGrid& grid, int e, const std::array<int, 3>& cell,
                                         const std::vector<int>& corners) const;
  std::vector<int> keep_used_particles(const ParticleGrid& grid, const std::vector<std::vector<int>>& rows);
  void fill_rows(const std::vector<std::vector<int>>& rows, const std::vector<int>& particle_of_grid);
  void make_masses_positive(const ParticleGrid& grid, const std::vector<int>& particle_of_grid);
  // Recomputes phi, grad phi, the matching coefficients, the rest gradient and the support of
  // an element from its row; throws naming the element if the moment matrix is singular.
  void compute_element(int element);
  void compute_masses();
  // Removes the particles no row refers to (their masses must be zero) and renumbers.
  void drop_unused_particles();
  void restride(int stride);
  // sum_n x_n (x) c_n over the element's row, c the given per-slot coefficients.
  Mat3 gather(const Vector& x, int element, const std::vector<Vec3>& coefficients) const;
  // The coefficients of the rotation's fit (EfgSettings::rotation).
  const std::vector<Vec3>& rotation_coefficients() const;
  // Whether elastic_energy's force matrices hold the forces at x (update_rotations took its
  // rotations for x and nothing changed since), per element while energy_valid_.
  bool energy_forces_at(const Vector& x) const;
  // The matrices whose products with the row's grad phi_n give the element's contributions to
  // the forces at x (-V R sigma) and to K p (V R sigma(R^T sum_n p_n (x) grad phi_n)).
  Mat3 element_force_matrix(const Vector& x, int element, bool from_energy) const;
  Mat3 element_stiffness_matrix(const Vector& p, int element) const;
  // buffer_n += scaled grad phi_n over the element's row.
  void scatter(int element, const Mat3& scaled, Vector& buffer) const;
  int partition_begin(int part) const;  // the partition's first element
  void update_partition_nodes() const;
  // *outs[o] (3n) += the sum over elements of term(element, buffers), which adds the element's
  // contributions to *buffers[o] (3n); see the file comment for the summation order.
  template <int Outputs, typename ElementTerm>
  void accumulate(const std::array<Vector*, Outputs>& outs, const ElementTerm& term) const;

  // The read-only part, shared by copies; written through building_ during the build only.
  std::shared_ptr<const EfgRestShape> shape_;
  std::shared_ptr<EfgRestShape> building_;
  // The last rest stiffness job's rows and K0, which the next job updates where a cut changed
  // them (efg_rest_stiffness.cpp); shared by copies, the result being the same either way.
  std::shared_ptr<EfgRestStiffnessCache> rest_stiffness_cache_;

  // Particles.
  Vector masses_;

  // Elements.
  std::vector<double> volumes_;
  std::vector<double> supports_;
  std::vector<Mat3> rest_gradients_;  // sum_n X_n (x) grad phi_n, the identity up to rounding
  std::vector<Mat3> rotations_;
  // Cutting (set_neighbourhood): mass-sharing rule per element, rows using each particle
  // (built on the first edit), and the particles left by every element.
  std::vector<std::uint8_t> positive_mass_;
  std::vector<int> references_;
  std::vector<int> orphans_;
  int deactivated_ = 0;
  int masses_floored_ = 0;
  std::vector<Eigen::Quaterniond> orientations_;  // the same rotations, warm starts
  // elastic_energy's rotations, kept for the next update_rotations: a step's energy is taken at
  // the positions the next step starts from, from the same warm starts, so that extraction
  // would be repeated bit for bit. Valid while the positions are bitwise those below and, per
  // element, until set_neighbourhood changes its row (or update_rotations its warm start).
  mutable Vector energy_positions_;
  mutable std::vector<Eigen::Quaterniond> energy_orientations_;
  mutable std::vector<std::uint8_t> energy_valid_;  // per element
  // Its force matrices -V R sigma at energy_positions_: the next step's forces, whose gradient
  // and rotation are that very computation's when it starts there. update_rotations moves
  // energy_positions_ to force_positions_ when it took the energy's rotations. An element's
  // pair stays valid until set_neighbourhood changes its row or deactivate_element its volume.
  mutable std::vector<Mat3> energy_forces_;
  mutable Vector force_positions_;

  // Rows (ELL).
  int stride_ = 0;
  std::vector<int> row_lengths_;
  std::vector<int> neighbours_;
  std::vector<double> shape_values_;
  std::vector<Vec3> shape_gradients_;
  std::vector<Vec3> matching_coefficients_;

  // Scratch of the element loops: one accumulation buffer per partition of the elements (and
  // per output of a fused pass), and one energy per element. Each partition's buffers are used
  // over the nodes [first, second) its rows reach only (recomputed when rows change).
  static constexpr int partition_count = 4;
  static constexpr int max_outputs = 2;
  mutable std::array<std::array<Vector, partition_count>, max_outputs> partition_buffers_;
  mutable std::array<std::pair<int, int>, partition_count> partition_nodes_{};
  mutable bool partition_nodes_stale_ = true;
  mutable std::vector<double> element_energies_;
  // current_stiffness's plan (rebuilt when the rows change; it holds the turned gradients and
  // each element's weight: its volume, 0 for an element taken out).
  mutable ElementAssembly assembly_;
  // node_rotations' incidence: per node, the live elements (volume > 0) whose rows hold it, in
  // element order, an element once per entry of its row (efg_rest_stiffness.cpp). Laid again
  // when topology_revision_, which every edit of the rows or of which elements live moves,
  // is not the one it was laid at.
  struct NodeIncidence {
    long long revision = -1;
    std::vector<int> start, elements;
  };
  mutable NodeIncidence node_incidence_;
  long long topology_revision_ = 0;
  // current_stiffness's plan: the revision it was laid at (-1: none), and the elements whose
  // rows set_neighbourhood edited since (a plan is edited in those alone, no row compared).
  mutable long long planned_revision_ = -1;
  mutable std::vector<int> rows_edited_;
  void lay_node_incidence() const;
  Executor* executor_ = &serial_executor();
};

}  // namespace incise::physics
