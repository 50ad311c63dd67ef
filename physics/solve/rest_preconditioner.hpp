// A body's rest-shape preconditioner over the steps: which factor its solves use, and when a
// cut's new one takes over.
//
// The factor of A0 = (1 + dt alpha) M + (dt beta + dt^2) K0 (or of its coarse system) is
// built at the first step, on its critical path. A topology change (a cut re-selects neighbourhoods, moves masses, pins particles)
// leaves it a valid preconditioner of the new system, only a less exact one, so the steps go
// on with it while the new factor is built beside them (Executor::run_async; Courtecuisse et
// al. 2014 update theirs asynchronously likewise). The new factor takes over exactly
// `latency` steps after the change that started it, waiting for it if it is late: which
// factor a step uses depends on the step count only, never on the threads' timing, so
// replays stay bit-for-bit.
#pragma once

#include "physics/core/executor.hpp"
#include "physics/core/model.hpp"
#include "physics/solve/coarse_space.hpp"
#include "physics/solve/rest_factor.hpp"

#include <cstdint>
#include <deque>
#include <functional>
#include <utility>
#include <future>
#include <memory>
#include <string>
#include <vector>

namespace incise::physics {

enum class PreconditionerKind {
  jacobi,           // the diagonal of A: no factor
  warped_cholesky,  // the rest factor warped by the node rotations (warped_preconditioner.hpp)
  // Jacobi plus the coarse correction of an embedded grid twice the node spacing (additive
  // two-level: P^-1 = D^-1 + R P (P^T A0 P)^-1 P^T R^T; coarse_space.hpp), warped likewise.
  two_level,
  // The same coarse space and factor in a multiplicative V-cycle of the rest system, warped:
  // Chebyshev smoothing of the Jacobi-scaled assembled A0 before and after the coarse
  // correction (multigrid.hpp, block_system.hpp).
  multigrid,
  // The same factor, but the cycle of the current system: the step assembles A in blocks
  // (ImplicitEulerSettings::assembled_system), multiplies by it in CG and smooths with it; only
  // the coarse correction is warped (physics/core/implicit_euler.cpp).
  multigrid_current,
};

const char* to_string(PreconditionerKind kind);

struct PreconditionerSettings {
  PreconditionerKind kind = PreconditionerKind::warped_cholesky;
  int latency = 4;  // steps between a topology change and its factor taking over
  double coarsening = 2;  // two_level, multigrid: the coarse grid's spacing over the model's node spacing
  int smoothing = 2;      // multigrid: the Chebyshev smoother's degree (A products per smoothing)
  bool single_precision = false;  // multigrid: the smoother's copy of A0 and D0^-1 in float
};

// What the step reports about it.
struct PreconditionerReport {
  long long age = 0;        // steps since the topology change the factor in use lags, 0 = current
  double build_ms = 0;      // the factor in use: its build time (on its thread)
  double wait_ms = 0;       // this step waited for a late factor
  bool adopted = false;     // a new factor took over this step
  bool built_here = false;  // built on the step's critical path (the first one)
  // A build beside the steps that failed (its error): the steps go on with the factor they
  // had, and no build starts again for that topology.
  std::string build_error;
};

class RestPreconditioner {
 public:
  // Before step `step`'s solve: the factor it uses (nullptr: Jacobi, for that kind or a model
  // that offers no rest stiffness). `revision` counts the model's topology changes
  // (BodyData::topology_revision); `masses`, `fixed` and the coefficients are the current
  // system's. Starts a build on `executor` when the topology moved past the last one started.
  // `separation` (optional): a copy of the body's cut for a build's coarse space
  // (make_coarse_space), asked for when a build starts.
  const RestFactor* prepare(const PreconditionerSettings& settings, const DeformableModel& model, const std::vector<std::uint8_t>& fixed, double mass_coefficient,
                            double stiffness_coefficient, std::uint64_t revision, long long step, Executor& executor,
                            PreconditionerReport& report, const std::function<CutSeparation()>& separation = {});

  int builds() const { return builds_; }

 private:
  using FactorPtr = std::shared_ptr<const RestFactor>;
  struct Pending {
    // A build still running when its body goes waits to be done: the executor's thread may
    // outlive the body (engine::BackgroundQueue), and the process must not end mid-build.
    Pending() = default;
    Pending(Pending&&) = default;
    Pending& operator=(Pending&&) = default;
    ~Pending() {
      if (done.valid()) done.wait();
    }
    std::shared_ptr<FactorPtr> result;  // written by the job
    std::shared_future<void> done;
    std::uint64_t revision = 0;
    long long due = 0;        // the step it takes over at
    long long started = 0;    // the step that started it
  };
  Pending start(const DeformableModel& model, const std::vector<std::uint8_t>& fixed, double mass_coefficient,
                double stiffness_coefficient, std::uint64_t revision, long long step, const PreconditionerSettings& settings,
                Executor& executor, CutSeparation separation);

  FactorPtr current_;
  std::uint64_t current_revision_ = 0;
  // The topology revisions the factor in use lacks, with the step each was first seen at.
  std::deque<std::pair<std::uint64_t, long long>> lacking_;
  std::shared_ptr<Pending> pending_;
  std::uint64_t failed_revision_ = 0;  // the topology a build failed for (0: none)
  bool failed_ = false;
  int builds_ = 0;
  bool unsupported_ = false;
};

}  // namespace incise::physics
