// The corotated EFG model's step (physics/efg/corotational_efg.hpp): each element's rotation
// from the MLS deformation gradient, the elastic forces, the stiffness's product and diagonal,
// and the elastic energy, whose rotations the next step's update_rotations reuses. The build
// is in corotational_efg.cpp, the cut's edits in efg_cut_edits.cpp.
#include "physics/efg/corotational_efg.hpp"
#include "physics/efg/rotation_extraction.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace incise::physics {

namespace {

using Index = Eigen::Index;
using Quaternion = Eigen::Quaterniond;

// Linear strain and Hooke stress of a displacement gradient.
struct StrainStress {
  Mat3 strain;
  Mat3 stress;
};

StrainStress hooke(const Mat3& displacement_gradient, double lambda, double mu) {
  const Mat3 strain = 0.5 * (displacement_gradient + displacement_gradient.transpose());
  return {strain, 2.0 * mu * strain + lambda * strain.trace() * Mat3::Identity()};
}

}  // namespace

// The helpers a pass calls for every element are forced inline (gnu::always_inline): as calls
// they cost a quarter of a stiffness product at 20k elements (perf).
[[gnu::always_inline]] inline Mat3 CorotationalEfg::gather(const Vector& x, int element,
                                                           const std::vector<Vec3>& coefficients) const {
  const size_t base = static_cast<size_t>(element) * stride_;
  Mat3 sum = Mat3::Zero();
  for (int k = 0; k < row_lengths_[element]; ++k) {
    sum.noalias() += x.segment<3>(3 * static_cast<Index>(neighbours_[base + k])) * coefficients[base + k].transpose();
  }
  return sum;
}

const std::vector<Vec3>& CorotationalEfg::rotation_coefficients() const {
  return shape_->settings.rotation == EfgRotation::shape_matching ? matching_coefficients_ : shape_gradients_;
}

namespace {

// grad u = sum_n (R^T x_n - X_n) (x) grad phi_n = R^T G - G0 with G = sum_n x_n (x) grad phi_n.
[[gnu::always_inline]] inline StrainStress element_strain(const Mat3& rotation, const Mat3& gradient, const Mat3& rest_gradient, double lambda,
                            double mu) {
  return hooke(rotation.transpose() * gradient - rest_gradient, lambda, mu);
}

// -V R sigma: the element's elastic force on neighbour n is this times grad phi_n.
[[gnu::always_inline]] inline Mat3 force_matrix(double volume, const Mat3& rotation, const Mat3& stress) { return -volume * rotation * stress; }

}  // namespace

void CorotationalEfg::update_rotations(const Vector& x) {
  // elastic_energy already extracted the rotations at these very positions from these warm
  // starts (the previous step's end): the same computation, so its results are taken as they
  // are. Bitwise equal positions only: any other x is extracted afresh.
  const bool cached = energy_positions_.size() == x.size() && x.size() > 0 &&
                      std::memcmp(energy_positions_.data(), x.data(), sizeof(double) * static_cast<size_t>(x.size())) == 0 &&
                      energy_valid_.size() == static_cast<size_t>(element_count());
  // The others are extracted rotation_lanes at a time (rotation_extraction.hpp), each element
  // as alone.
  executor_->parallel_for(element_count(), [&](int begin, int end) {
    Mat3 fits[rotation_lanes];
    int lanes[rotation_lanes];
    int count = 0;
    auto extract = [&] {
      if (count == 0) return;
      Quaternion found[rotation_lanes];
      for (int i = 0; i < count; ++i) found[i] = orientations_[lanes[i]];
      extract_rotations(fits, found, count);
      for (int i = 0; i < count; ++i) {
        orientations_[lanes[i]] = found[i];
        rotations_[lanes[i]] = found[i].toRotationMatrix();
      }
      count = 0;
    };
    for (int e = begin; e < end; ++e) {
      if (cached && energy_valid_[e]) {
        orientations_[e] = energy_orientations_[e];
        rotations_[e] = orientations_[e].toRotationMatrix();
        continue;
      }
      fits[count] = gather(x, e, rotation_coefficients());
      lanes[count] = e;
      if (++count == rotation_lanes) extract();
    }
    extract();
  }, std::max(1, shape_->settings.threaded_elements / 2));
  // The warm starts moved on: the kept rotations no longer repeat an extraction from them. The
  // energy's force matrices stay good for forces at these positions (add_elastic_forces).
  if (cached) {
    force_positions_.swap(energy_positions_);
  } else {
    force_positions_.resize(0);
  }
  energy_positions_.resize(0);
}

bool CorotationalEfg::energy_forces_at(const Vector& x) const {
  return force_positions_.size() == x.size() && x.size() > 0 &&
         std::memcmp(force_positions_.data(), x.data(), sizeof(double) * static_cast<size_t>(x.size())) == 0 &&
         energy_valid_.size() == static_cast<size_t>(element_count());
}

[[gnu::always_inline]] inline Mat3 CorotationalEfg::element_force_matrix(const Vector& x, int element, bool from_energy) const {
  if (from_energy && energy_valid_[element]) return energy_forces_[element];
  const Mat3& rotation = rotations_[element];
  const StrainStress local = element_strain(rotation, gather(x, element, shape_gradients_), rest_gradients_[element],
                                            shape_->lambda, shape_->mu);
  return force_matrix(volumes_[element], rotation, local.stress);
}

[[gnu::always_inline]] inline Mat3 CorotationalEfg::element_stiffness_matrix(const Vector& p, int element) const {
  const Mat3& rotation = rotations_[element];
  const StrainStress local = hooke(rotation.transpose() * gather(p, element, shape_gradients_), shape_->lambda, shape_->mu);
  return volumes_[element] * rotation * local.stress;
}

[[gnu::always_inline]] inline void CorotationalEfg::scatter(int element, const Mat3& scaled, Vector& buffer) const {
  const size_t base = static_cast<size_t>(element) * stride_;
  for (int k = 0; k < row_lengths_[element]; ++k) {
    buffer.segment<3>(3 * static_cast<Index>(neighbours_[base + k])).noalias() += scaled * shape_gradients_[base + k];
  }
}

void CorotationalEfg::update_partition_nodes() const {
  if (!partition_nodes_stale_) return;
  for (int part = 0; part < partition_count; ++part) {
    int first = node_count(), last = 0;
    for (int e = partition_begin(part); e < partition_begin(part + 1); ++e) {
      const size_t base = static_cast<size_t>(e) * stride_;
      for (int k = 0; k < row_lengths_[e]; ++k) {
        first = std::min(first, neighbours_[base + k]);
        last = std::max(last, neighbours_[base + k] + 1);
      }
    }
    partition_nodes_[part] = {first, std::max(first, last)};
  }
  partition_nodes_stale_ = false;
}

int CorotationalEfg::partition_begin(int part) const {
  return static_cast<int>(static_cast<long long>(element_count()) * part / partition_count);
}

template <int Outputs, typename ElementTerm>
void CorotationalEfg::accumulate(const std::array<Vector*, Outputs>& outs, const ElementTerm& term) const {
  static_assert(Outputs >= 1 && Outputs <= max_outputs);
  const int elements = element_count();
  const Index size = 3 * static_cast<Index>(node_count());
  update_partition_nodes();
  // Fixed partitions of the elements, each scattering into its own buffer in element order;
  // the buffers are then added in partition order. Neither depends on the thread count. A
  // partition's buffer is zeroed and read over the nodes its rows reach only: elsewhere it
  // would hold +0, and adding +0 leaves every partial sum as it is (a buffer's entries start
  // at +0 and so are never -0, nor is a sum of them).
  executor_->parallel_for(partition_count, [&](int begin, int end) {
    for (int part = begin; part < end; ++part) {
      std::array<Vector*, Outputs> buffers;
      const auto [first, last] = partition_nodes_[part];
      for (int o = 0; o < Outputs; ++o) {
        Vector& buffer = partition_buffers_[o][part];
        if (buffer.size() != size) buffer.resize(size);
        buffer.segment(3 * static_cast<Index>(first), 3 * static_cast<Index>(last - first)).setZero();
        buffers[o] = &buffer;
      }
      for (int e = partition_begin(part); e < partition_begin(part + 1); ++e) term(e, buffers);
    }
  }, elements >= shape_->settings.threaded_elements ? 1 : partition_count);
  executor_->parallel_for(node_count(), [&](int begin, int end) {
    for (int o = 0; o < Outputs; ++o) {
      Vector& out = *outs[o];
      for (int node = begin; node < end; ++node) {
        for (Index i = 3 * static_cast<Index>(node); i < 3 * static_cast<Index>(node) + 3; ++i) {
          double sum = 0;
          for (int part = 0; part < partition_count; ++part) {
            if (node >= partition_nodes_[part].first && node < partition_nodes_[part].second)
              sum += partition_buffers_[o][part][i];
          }
          out[i] += sum;
        }
      }
    }
  }, std::max(1, shape_->settings.threaded_elements / 4));
}

void CorotationalEfg::add_elastic_forces(const Vector& x, Vector& f) const {
  const bool from_energy = energy_forces_at(x);
  accumulate<1>({&f}, [&](int e, const std::array<Vector*, 1>& buffers) {
    scatter(e, element_force_matrix(x, e, from_energy), *buffers[0]);
  });
}

void CorotationalEfg::add_stiffness_product(const Vector& p, Vector& out) const {
  accumulate<1>({&out}, [&](int e, const std::array<Vector*, 1>& buffers) {
    scatter(e, element_stiffness_matrix(p, e), *buffers[0]);
  });
}

void CorotationalEfg::add_forces_and_stiffness_product(const Vector& x, Vector& f, const Vector& p,
                                                       Vector& out) const {
  const bool from_energy = energy_forces_at(x);
  accumulate<2>({&f, &out}, [&](int e, const std::array<Vector*, 2>& buffers) {
    const Mat3 force = element_force_matrix(x, e, from_energy);
    const Mat3 stiffness = element_stiffness_matrix(p, e);
    const size_t base = static_cast<size_t>(e) * stride_;
    for (int k = 0; k < row_lengths_[e]; ++k) {
      const Index node = 3 * static_cast<Index>(neighbours_[base + k]);
      const Vec3& g = shape_gradients_[base + k];
      buffers[0]->segment<3>(node).noalias() += force * g;
      buffers[1]->segment<3>(node).noalias() += stiffness * g;
    }
  });
}

void CorotationalEfg::add_stiffness_diagonal(Vector& diagonal) const {
  accumulate<1>({&diagonal}, [&](int e, const std::array<Vector*, 1>& buffers) {
    Vector& buffer = *buffers[0];
    const size_t base = static_cast<size_t>(e) * stride_;
    const Mat3& rotation = rotations_[e];
    for (int k = 0; k < row_lengths_[e]; ++k) {
      // K_nn = V R (lambda g g^T + mu g g^T + mu |g|^2 I) R^T (tet_element.hpp's block with
      // a = b), whose diagonal needs only R g.
      const Vec3& g = shape_gradients_[base + k];
      const Vec3 turned = rotation * g;
      buffer.segment<3>(3 * static_cast<Index>(neighbours_[base + k])) +=
          volumes_[e] * ((shape_->lambda + shape_->mu) * turned.cwiseProduct(turned) +
                         Vec3::Constant(shape_->mu * g.squaredNorm()));
    }
  });
}

double CorotationalEfg::elastic_energy(const Vector& x) const {
  energy_positions_ = x;
  force_positions_.resize(0);  // energy_forces_ are about to be taken at x
  energy_orientations_.resize(static_cast<size_t>(element_count()));
  energy_forces_.resize(static_cast<size_t>(element_count()));
  energy_valid_.assign(static_cast<size_t>(element_count()), 1);
  // With the rotation from the deformation gradient its fit is the gradient G itself.
  const bool fit_is_gradient = &rotation_coefficients() == &shape_gradients_;
  executor_->parallel_for(element_count(), [&](int begin, int end) {
    for (int first = begin; first < end; first += rotation_lanes) {
      const int count = std::min(rotation_lanes, end - first);
      Mat3 fits[rotation_lanes];
      for (int i = 0; i < count; ++i) {
        fits[i] = gather(x, first + i, rotation_coefficients());
        energy_orientations_[first + i] = orientations_[first + i];
      }
      extract_rotations(fits, energy_orientations_.data() + first, count);
      for (int i = 0; i < count; ++i) {
        const int e = first + i;
        const Mat3 rotation = energy_orientations_[e].toRotationMatrix();
        const Mat3 gradient = fit_is_gradient ? fits[i] : gather(x, e, shape_gradients_);
        const StrainStress local = element_strain(rotation, gradient, rest_gradients_[e], shape_->lambda, shape_->mu);
        // W = 1/2 sigma : eps = mu eps : eps + lambda / 2 tr(eps)^2.
        element_energies_[e] = 0.5 * volumes_[e] * (local.stress.cwiseProduct(local.strain)).sum();
        // The next step's forces at x, if it starts from x (update_rotations then takes these
        // very rotations): the same arithmetic as element_force_matrix's.
        energy_forces_[e] = force_matrix(volumes_[e], rotation, local.stress);
      }
    }
  }, std::max(1, shape_->settings.threaded_elements / 2));
  double energy = 0;
  for (double element_energy : element_energies_) energy += element_energy;
  return energy;
}

}  // namespace incise::physics
