#include "physics/solve/rest_preconditioner.hpp"

#include "physics/core/implicit_euler.hpp"
#include "physics/core/stopwatch.hpp"

#include <stdexcept>

namespace incise::physics {

const char* to_string(PreconditionerKind kind) {
  switch (kind) {
    case PreconditionerKind::jacobi: return "jacobi";
    case PreconditionerKind::warped_cholesky: return "warped_cholesky";
    case PreconditionerKind::two_level: return "two_level";
    case PreconditionerKind::multigrid: return "multigrid";
    case PreconditionerKind::multigrid_current: return "multigrid_current";
  }
  return "?";
}

RestPreconditioner::Pending RestPreconditioner::start(const DeformableModel& model, const std::vector<std::uint8_t>& fixed,
                                                      double mass_coefficient, double stiffness_coefficient,
                                                      std::uint64_t revision, long long step,
                                                      const PreconditionerSettings& settings, Executor& executor,
                                                      CutSeparation separation) {
  Pending pending;
  pending.revision = revision;
  pending.started = step;
  pending.due = step + settings.latency;
  pending.result = std::make_shared<FactorPtr>();
  // Everything the job reads is its own copy: the model may be cut again meanwhile.
  auto assemble = model.rest_stiffness_job();
  const bool multigrid =
      settings.kind == PreconditionerKind::multigrid || settings.kind == PreconditionerKind::multigrid_current;
  const double coarse_spacing =
      settings.kind == PreconditionerKind::two_level || multigrid ? settings.coarsening * model.node_spacing() : 0.0;
  const int smoothing = multigrid ? settings.smoothing : 0;
  const bool single = settings.kind == PreconditionerKind::multigrid && settings.single_precision;
  // The current cycle scales its smoother by the node blocks (jacobi_scaling.hpp); its fallback
  // for a model without an assembled system (implicit_euler.hpp), the rest cycle, by the
  // diagonal.
  const bool node_blocks = settings.kind == PreconditionerKind::multigrid_current && assembles_current_stiffness(model);
  pending.done = executor.run_async([result = pending.result, assemble = std::move(assemble),
                                     masses = model.lumped_masses(), rest = model.rest_positions(), fixed,
                                     mass_coefficient, stiffness_coefficient, coarse_spacing, smoothing, single,
                                     node_blocks, separation = std::move(separation)] {
    const BlockMatrix stiffness = assemble();
    if (coarse_spacing > 0) {
      const CoarseSpace coarse = make_coarse_space(rest, coarse_spacing, fixed, &stiffness, &separation);
      *result = std::make_shared<const RestFactor>(stiffness, masses, fixed, mass_coefficient, stiffness_coefficient,
                                                   default_factor_backend(), &coarse, smoothing, single, node_blocks);
    } else {
      *result = std::make_shared<const RestFactor>(stiffness, masses, fixed, mass_coefficient, stiffness_coefficient);
    }
  });
  ++builds_;
  return pending;
}

const RestFactor* RestPreconditioner::prepare(const PreconditionerSettings& settings, const DeformableModel& model, const std::vector<std::uint8_t>& fixed,
                                              double mass_coefficient, double stiffness_coefficient, std::uint64_t revision,
                                              long long step, Executor& executor, PreconditionerReport& report,
                                              const std::function<CutSeparation()>& separation) {
  if (settings.kind == PreconditionerKind::jacobi || unsupported_) return nullptr;
  if (!current_) {
    if (!model.rest_stiffness_job() || ((settings.kind == PreconditionerKind::two_level || settings.kind == PreconditionerKind::multigrid ||
                                         settings.kind == PreconditionerKind::multigrid_current) &&
                                          !(model.node_spacing() > 0))) {
      unsupported_ = true;  // the model offers no rest stiffness: Jacobi
      return nullptr;
    }
    // The first factor, at the first step: on the critical path, the solve needs it now.
    Pending first = start(model, fixed, mass_coefficient, stiffness_coefficient, revision, step, settings, serial_executor(),
                          separation ? separation() : CutSeparation{});
    first.done.get();
    current_ = *first.result;
    current_revision_ = revision;
    report.built_here = true;
  }
  if (lacking_.empty() || lacking_.back().first != revision) {
    if (revision != current_revision_) lacking_.emplace_back(revision, step);
  }
  if (pending_ && step >= pending_->due) {
    const Stopwatch wait;
    try {
      pending_->done.get();  // rethrows the build's error
      current_ = *pending_->result;
      current_revision_ = pending_->revision;
      while (!lacking_.empty() && lacking_.front().first <= current_revision_) lacking_.pop_front();
      report.adopted = true;
    } catch (const std::exception& e) {
      // Any SPD approximation still preconditions: the one in use goes on (older, so more
      // iterations), and this topology is not tried again; the next cut's is.
      report.build_error = e.what();
      failed_revision_ = pending_->revision;
      failed_ = true;
    }
    report.wait_ms = wait.ms();
    pending_.reset();
  }
  if (!pending_ && revision != current_revision_ && !(failed_ && revision == failed_revision_))
    pending_ = std::make_shared<Pending>(start(model, fixed, mass_coefficient, stiffness_coefficient, revision, step, settings, executor,
                                                    separation ? separation() : CutSeparation{}));
  report.age = lacking_.empty() ? 0 : step - lacking_.front().second;
  report.build_ms = current_->build_ms();
  return current_.get();
}

}  // namespace incise::physics
