#include "physics/solve/current_vcycle.hpp"

#include <stdexcept>

namespace incise::physics {

namespace {

constexpr int rows_per_thread = 256;  // as CurrentSystem::multiply

}  // namespace

CurrentVcycle::CurrentVcycle(const CurrentSystem& system, const RestFactor& factor,
                             const std::vector<Eigen::Quaterniond>& rotations, ChebyshevSmoother smoother,
                             Executor& executor, CycleEntries entries, PairedBlocks* workspace)
    : system_(system),
      factor_(factor),
      rotations_(rotations),
      smoother_(smoother),
      executor_(executor),
      steps_(smoother),
      scaling_(smoother.node_blocks ? JacobiScaling::node_blocks(system.diagonal_blocks(executor), executor)
                                    : JacobiScaling(jacobi_inverse(system.diagonal()))),
      rows_(system.rows()) {
  if (smoother_.degree < 1 || !(smoother_.upper > 0) || !(smoother_.ratio > 1))
    throw std::invalid_argument("CurrentVcycle: the smoother needs a degree >= 1, upper > 0 and ratio > 1");
  if (!factor_.coarse() || factor_.size() != 3 * system_.nodes() || factor_.transfer().nodes() != system_.nodes())
    throw std::invalid_argument("CurrentVcycle: the factor is not a coarse one of the system's nodes");
  if (!rotations_.empty() && static_cast<int>(rotations_.size()) != system_.nodes())
    throw std::invalid_argument("CurrentVcycle: one rotation per node");
  if (entries != CycleEntries::double_precision && system_.block_count() > 0) {
    const bool half = entries == CycleEntries::half_smoother;
    paired_ = workspace ? workspace : &own_paired_;
    paired_->build(rows_, system_.nodes(), executor_, half);
    smoother_precision_ = half ? PairedPrecision::half : PairedPrecision::single;
    // Zeroed: the 4th float of every node and the zero node stay 0 (paired_blocks.hpp).
    for (std::vector<float>* operand : {&step_operand_, &next_operand_, &product_operand_})
      operand->assign(paired_->operand_size(), 0.0f);
  }
}

void CurrentVcycle::round(const Vector& v, std::vector<float>& operand, Eigen::Index begin, Eigen::Index end) const {
  if (paired_)
    PairedBlocks::round_operand(rows_, v.data(), operand.data(), static_cast<int>(begin / 3), static_cast<int>(end / 3));
}

void CurrentVcycle::multiply(const Vector& p, Vector& out) {
  if (!paired_) return system_.multiply(p, out, executor_);
  if (p.size() != 3 * static_cast<Eigen::Index>(system_.nodes()))
    throw std::invalid_argument("CurrentVcycle::multiply: the vector's size is not the system's");
  out.resize(p.size());
  executor_.parallel_for(system_.nodes(), [&](int begin, int end) {
    PairedBlocks::round_operand(rows_, p.data(), product_operand_.data(), begin, end);
  }, rows_per_thread);
  executor_.parallel_for(system_.nodes(), [&](int begin, int end) {
    paired_->multiply_rows(rows_, p.data(), product_operand_.data(), out.data(), begin, end);
  }, rows_per_thread);
}

template <class Finish>
void CurrentVcycle::product_pass(const Vector& from, const std::vector<float>& operand, const Finish& finish) {
  const double* x = from.data();
  double* product = product_.data();
  double* residual = residual_.data();
  // A range's product stays in cache for its rows' finish (at most 4 ranges a thread); smaller
  // chunks of it cost more in calls than they gain (32 rows: +4 % a cycle on one thread).
  executor_.parallel_for(system_.nodes(), [&](int begin, int end) {
    if (!paired_)
      system_.multiply_rows(x, product, begin, end);
    else
      paired_->multiply_rows(rows_, x, operand.data(), product, begin, end, smoother_precision_);
    const Eigen::Index first = 3 * static_cast<Eigen::Index>(begin), last = 3 * static_cast<Eigen::Index>(end);
    for (Eigen::Index i = first; i < last; ++i) residual[i] -= product[i];
    finish(first, last);
  }, rows_per_thread);
}

void CurrentVcycle::smooth_steps(Vector& x) {
  const double* residual = residual_.data();
  double* out = x.data();
  for (int k = 1; k < smoother_.degree; ++k) {
    const double a = steps_.a[static_cast<size_t>(k)], b = steps_.b[static_cast<size_t>(k)];
    const double* step = step_.data();
    double* next = next_step_.data();
    product_pass(step_, step_operand_, [&](Eigen::Index begin, Eigen::Index end) {
      scaling_.apply(residual, next, begin, end);  // D^-1 r, then the step over it
      for (Eigen::Index i = begin; i < end; ++i) {
        next[i] = a * step[i] + b * next[i];
        out[i] += next[i];
      }
      round(next_step_, next_operand_, begin, end);
    });
    step_.swap(next_step_);
    step_operand_.swap(next_operand_);
  }
}

void CurrentVcycle::coarse_correction(Vector& x) {
  const CoarseTransfer& transfer = factor_.transfer();
  executor_.parallel_for(transfer.coarse_nodes(), [&](int begin, int end) {
    transfer.restrict_nodes(turned_.data(), coarse_.data(), begin, end);
  }, rows_per_thread);
  factor_.solve_factored(coarse_, executor_);
  // The correction goes to step_, the next product's operand.
  double* correction = step_.data();
  double* out = x.data();
  executor_.parallel_for(system_.nodes(), [&](int begin, int end) {
    for (int node = begin; node < end; ++node) {
      const Eigen::Index offset = 3 * static_cast<Eigen::Index>(node);
      Vec3 value = Vec3::Zero();
      if (!system_.is_fixed(node)) {
        value = transfer.prolong_node(coarse_.data(), node);
        if (!rotations_.empty()) value = rotations_[static_cast<size_t>(node)] * Vec3(value);
      }
      for (int a = 0; a < 3; ++a) {
        correction[offset + a] = value[a];
        out[offset + a] += value[a];
      }
    }
    round(step_, step_operand_, 3 * static_cast<Eigen::Index>(begin), 3 * static_cast<Eigen::Index>(end));
  }, rows_per_thread);
}

void CurrentVcycle::operator()(const Vector& r, Vector& z) {
  const int nodes = system_.nodes();
  const Eigen::Index size = 3 * static_cast<Eigen::Index>(nodes);
  if (r.size() != size) throw std::invalid_argument("CurrentVcycle: the vector's size is not the system's");
  for (Vector* v : {&residual_, &step_, &next_step_, &product_, &turned_}) v->resize(size);
  coarse_.resize(factor_.factored_size());
  z.resize(size);
  const double theta = steps_.theta;
  double* residual = residual_.data();
  double* step = step_.data();
  double* x = z.data();
  // Pre-smoothing: residual = r zeroed on the fixed nodes, x = 0 + s_0.
  executor_.parallel_for(nodes, [&](int begin, int end) {
    for (int node = begin; node < end; ++node) {
      const bool fixed = system_.is_fixed(node);
      const Eigen::Index first = 3 * static_cast<Eigen::Index>(node);
      for (Eigen::Index i = first; i < first + 3; ++i) residual[i] = fixed ? 0.0 : r[i];
      scaling_.apply(residual, step, first, first + 3);
      for (Eigen::Index i = first; i < first + 3; ++i) {
        step[i] = step[i] / theta;
        x[i] = 0.0 + step[i];
      }
    }
    round(step_, step_operand_, 3 * static_cast<Eigen::Index>(begin), 3 * static_cast<Eigen::Index>(end));
  }, rows_per_thread);
  smooth_steps(z);
  // The last step's product, and R^T of the residual it leaves.
  product_pass(step_, step_operand_, [&](Eigen::Index begin, Eigen::Index end) {
    for (Eigen::Index node = begin / 3; node < end / 3; ++node) {
      const Vec3 value(residual_.segment<3>(3 * node));
      turned_.segment<3>(3 * node) =
          rotations_.empty() ? value : Vec3(rotations_[static_cast<size_t>(node)].conjugate() * value);
    }
  });
  coarse_correction(z);
  // The correction's product, and the post-smoothing's first step.
  double* next = next_step_.data();
  product_pass(step_, step_operand_, [&](Eigen::Index begin, Eigen::Index end) {
    scaling_.apply(residual, next, begin, end);
    for (Eigen::Index i = begin; i < end; ++i) {
      next[i] = next[i] / theta;
      x[i] += next[i];
    }
    round(next_step_, next_operand_, begin, end);
  });
  step_.swap(next_step_);
  step_operand_.swap(next_operand_);
  smooth_steps(z);
}

}  // namespace incise::physics
