// The contract between deformable models, the integrators and the engine.
//
// Static model data (rest shape, shape functions, material) lives inside a model and is
// built once; the dynamic state (positions, velocities) is a separate State, in the manner
// of MuJoCo's mjModel / mjData: copying or resetting a simulation is copying the State.
#pragma once

#include "physics/core/executor.hpp"
#include "physics/solve/block_matrix.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <vector>

namespace incise::physics {

using Vector = Eigen::VectorXd;  // 3n entries, node-major: x0 y0 z0 x1 y1 z1 ...
using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

// Dynamic state of one body.
struct State {
  Vector positions;
  Vector velocities;
};

// A deformable model with corotation frames frozen during a step (the corotational
// linearisation of seed 004 Annex B): forces are -R K (R^T x - X), stiffness R K R^T.
class DeformableModel {
 public:
  virtual ~DeformableModel() = default;
  virtual int node_count() const = 0;
  virtual const Vector& rest_positions() const = 0;  // 3n
  virtual const Vector& lumped_masses() const = 0;   // n, all > 0
  // Recompute the per-element rotations from x; they stay frozen until the next call.
  virtual void update_rotations(const Vector& x) = 0;
  // f += elastic forces at x.
  virtual void add_elastic_forces(const Vector& x, Vector& f) const = 0;
  // out += K p, K = -df/dx with the frozen rotations (symmetric, positive semi-definite).
  virtual void add_stiffness_product(const Vector& p, Vector& out) const = 0;
  // f += elastic forces at x and out += K p, as the two calls above give them; a model may do
  // both in one pass over its elements.
  virtual void add_forces_and_stiffness_product(const Vector& x, Vector& f, const Vector& p, Vector& out) const {
    add_elastic_forces(x, f);
    add_stiffness_product(p, out);
  }
  // diag += diagonal of K (for the Jacobi preconditioner).
  virtual void add_stiffness_diagonal(Vector& diag) const = 0;
  virtual double elastic_energy(const Vector& x) const = 0;

  // A model's own damping force, linear in the velocity with the frames frozen by
  // update_rotations: f_damping = -D v, D symmetric PSD (a mass-spring's dashpots). The
  // integrators apply it only where has_damping() (so the others' arithmetic is untouched);
  // the scene's Rayleigh damping is separate.
  virtual bool has_damping() const { return false; }
  virtual void add_damping_product(const Vector& /*p*/, Vector& /*out*/) const {}  // out += D p
  virtual void add_damping_diagonal(Vector& /*diag*/) const {}                     // diag += diagonal of D
  // The largest dt an explicit integrator may take on this model (explicit_step refuses a
  // larger one); infinity: the model names no bound.
  virtual double explicit_step_limit() const { return std::numeric_limits<double>::infinity(); }

  // For rest-shape preconditioners (physics/solve/): a job that assembles K0, the stiffness
  // with every rotation the identity, from its own copy of what it reads, so that it may run
  // on another thread while the model changes (a cut). Empty: the model offers none, and its
  // solves are Jacobi-preconditioned.
  virtual std::function<BlockMatrix()> rest_stiffness_job() const { return {}; }
  // K, the stiffness with the rotations frozen by update_rotations, assembled in 3x3 blocks
  // (both triangles): what add_stiffness_product multiplies by, to round-off. Valid until the
  // next call or a change of the model. nullptr: the model offers none (the step's products
  // stay matrix-free). Not called unless a solver asks for it (solver.preconditioner
  // "multigrid_current").
  virtual const BlockMatrix* current_stiffness() const { return nullptr; }
  // Whether current_stiffness gives one, without assembling it.
  virtual bool has_current_stiffness() const { return false; }
  // Lays current_stiffness's plan for the model's rows as they are now: the part of it a
  // topology change makes, the refill staying with the step. For a caller with a thread to
  // spare after a cut (physics/cut/apply_topology.cpp): it touches nothing but the plan, so it
  // may run beside work that reads the model and does not call current_stiffness.
  virtual void plan_current_stiffness() const {}
  // Per node, the mean of the frozen rotations of the elements around it (unit quaternions):
  // the warp of a rest-shape preconditioner. Empty: the identity.
  virtual void node_rotations(std::vector<Eigen::Quaterniond>& out) const { out.clear(); }
  // The typical distance between neighbouring nodes at rest, which a two-level
  // preconditioner's coarse grid doubles (physics/solve/coarse_space.hpp). 0: unknown.
  virtual double node_spacing() const { return 0; }
  // Where the model's loops run (physics/core/executor.hpp): a solver's own loops over the
  // nodes (a preconditioner's products) borrow it. The calling thread unless the model has one.
  virtual Executor& executor() const { return serial_executor(); }
  // A deep copy whose future is the same as this one's, bit for bit (copying a body's data
  // copies its model: the model changes as it steps and as it is cut). What the model only
  // borrows (an EFG model's executor) is borrowed by the copy too; its owner re-points it.
  virtual std::unique_ptr<DeformableModel> clone() const = 0;
};

// A point force with its own stiffness, added to the implicit system (penalty contact,
// springs to a tool): force f at node, stiffness K = -df/dx (3x3, symmetric PSD).
struct NodalSpring {
  int node = 0;
  Vec3 force = Vec3::Zero();
  Mat3 stiffness = Mat3::Zero();
};

}  // namespace incise::physics
