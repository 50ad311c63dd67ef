#include "physics/mss/mss_static.hpp"

#include <Eigen/LU>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseLU>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace incise::physics {

namespace {

using Index = Eigen::Index;

std::vector<Index> free_dofs(const std::vector<uint8_t>& fixed, Index nodes) {
  std::vector<Index> free;
  for (Index i = 0; i < nodes; ++i)
    if (fixed.empty() || !fixed[static_cast<std::size_t>(i)])
      for (int c = 0; c < 3; ++c) free.push_back(3 * i + c);
  return free;
}

}  // namespace

MassSpringStatic solve_mass_spring_static(HexMassSpring& model, const std::vector<uint8_t>& fixed,
                                          const Vector& prescribed, const Vector& load, int increments,
                                          double tolerance) {
  const Vector& rest = model.rest_positions();
  const Index size = rest.size();
  const std::vector<Index> free = free_dofs(fixed, size / 3);
  std::vector<Index> slot(static_cast<std::size_t>(size), -1);
  for (std::size_t i = 0; i < free.size(); ++i) slot[static_cast<std::size_t>(free[i])] = static_cast<Index>(i);
  MassSpringStatic result;
  result.positions = rest;
  double first_residual = -1, residual = 0;
  // The springs' tangent is symmetric (LDLT); with the corrections' derivative it is not (LU).
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> symmetric;
  Eigen::SparseLU<Eigen::SparseMatrix<double>> general;
  const bool corrected = model.corrections();
  for (int step = 1; step <= std::max(1, increments); ++step) {
    const double share = static_cast<double>(step) / std::max(1, increments);
    for (Index i = 0; i < size / 3; ++i)
      if (!fixed.empty() && fixed[static_cast<std::size_t>(i)])
        result.positions.segment<3>(3 * i) =
            rest.segment<3>(3 * i) + (prescribed.size() ? Vec3(share * prescribed.segment<3>(3 * i)) : Vec3::Zero());
    bool done = false;
    for (int iteration = 0; iteration < 200 && !done; ++iteration, ++result.iterations) {
      model.update_rotations(result.positions);
      Vector f = load.size() ? Vector(share * load) : Vector::Zero(size);
      model.add_elastic_forces(result.positions, f);
      Vector rhs(static_cast<Index>(free.size()));
      for (std::size_t i = 0; i < free.size(); ++i) rhs[static_cast<Index>(i)] = f[free[i]];
      residual = rhs.norm();
      if (first_residual < 0) first_residual = residual;
      {
        std::vector<Eigen::Triplet<double>> all, reduced;
        model.add_stiffness_triplets(all);
        if (corrected) model.add_correction_triplets(all);
        reduced.reserve(all.size());
        for (const auto& t : all) {
          const Index r = slot[static_cast<std::size_t>(t.row())], c = slot[static_cast<std::size_t>(t.col())];
          if (r >= 0 && c >= 0) reduced.emplace_back(r, c, t.value());
        }
        Eigen::SparseMatrix<double> k(static_cast<Index>(free.size()), static_cast<Index>(free.size()));
        k.setFromTriplets(reduced.begin(), reduced.end());
        bool ok = false;
        if (corrected) {
          general.compute(k);
          ok = general.info() == Eigen::Success;
        } else {
          symmetric.compute(k);
          ok = symmetric.info() == Eigen::Success;
        }
        if (!ok) throw std::runtime_error("mass-spring static: the tangent cannot be factorised");
      }
      const Vector dx = corrected ? Vector(general.solve(rhs)) : Vector(symmetric.solve(rhs));
      if (!dx.allFinite()) throw std::runtime_error("mass-spring static: the Newton update is not finite");
      for (std::size_t i = 0; i < free.size(); ++i) result.positions[free[i]] += dx[static_cast<Index>(i)];
      double largest = 0;
      for (Index i = 0; i < size / 3; ++i)
        largest = std::max(largest, (result.positions.segment<3>(3 * i) - rest.segment<3>(3 * i)).norm());
      done = dx.cwiseAbs().maxCoeff() <= tolerance * std::max(largest, 1e-300);
    }
    if (!done) {
      std::ostringstream out;
      out << "mass-spring static: increment " << step << " of " << increments << " did not converge in 200 iterations";
      throw std::runtime_error(out.str());
    }
  }
  model.update_rotations(result.positions);
  result.converged = true;
  result.residual = first_residual > 0 ? residual / first_residual : 0;
  return result;
}

Eigen::MatrixXd mass_spring_rest_stiffness(HexMassSpring& model) {
  const Vector rest = model.rest_positions();
  const Index size = rest.size();
  model.update_rotations(rest);
  std::vector<Eigen::Triplet<double>> triplets;
  model.add_stiffness_triplets(triplets);
  Eigen::SparseMatrix<double> sparse(size, size);
  sparse.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::MatrixXd k = Eigen::MatrixXd(sparse);
  if (!model.corrections()) return k;
  const double h = 1e-6 * model.node_spacing();
  for (Index d = 0; d < size; ++d) {
    Vector plus = rest, minus = rest, fp = Vector::Zero(size), fm = Vector::Zero(size);
    plus[d] += h, minus[d] -= h;
    model.add_correction_forces(plus, fp);
    model.add_correction_forces(minus, fm);
    k.col(d) -= (fp - fm) / (2 * h);
  }
  return k;
}

Eigen::MatrixXd spring_network_stiffness(const Vector& rest, const std::vector<Spring>& springs) {
  Eigen::MatrixXd k = Eigen::MatrixXd::Zero(rest.size(), rest.size());
  for (const Spring& s : springs) {
    const Vec3 u = (rest.segment<3>(3 * s.b) - rest.segment<3>(3 * s.a)).normalized();
    const Mat3 block = s.stiffness * u * u.transpose();
    k.block<3, 3>(3 * s.a, 3 * s.a) += block;
    k.block<3, 3>(3 * s.b, 3 * s.b) += block;
    k.block<3, 3>(3 * s.a, 3 * s.b) -= block;
    k.block<3, 3>(3 * s.b, 3 * s.a) -= block;
  }
  return k;
}

TractionMeasure measure_traction(const Eigen::MatrixXd& k, const Vector& rest, const Vec3& size,
                                 const std::array<int, 3>& cells) {
  const Index n = rest.size() / 3;
  const double force = 1e-3, eps = 1e-9 * size.minCoeff();
  Vector load = Vector::Zero(3 * n);
  std::vector<bool> held(static_cast<std::size_t>(3 * n), false);
  for (Index i = 0; i < n; ++i) {
    const Vec3 p = rest.segment<3>(3 * i);
    const auto hold = [&](int c) { held[static_cast<std::size_t>(3 * i + c)] = true; };
    if (p.x() < eps) {
      hold(0);
      if (p.y() < eps && p.z() < eps) hold(1), hold(2);
      if (p.y() > size.y() - eps && p.z() < eps) hold(2);
      if (p.y() < eps && p.z() > size.z() - eps) hold(1);
    }
    if (p.x() > size.x() - eps) {
      const bool y_edge = p.y() < eps || p.y() > size.y() - eps, z_edge = p.z() < eps || p.z() > size.z() - eps;
      load[3 * i] = force * (y_edge ? 0.5 : 1.0) * (z_edge ? 0.5 : 1.0) / (cells[1] * cells[2]);
    }
  }
  std::vector<Index> free;
  for (Index d = 0; d < 3 * n; ++d)
    if (!held[static_cast<std::size_t>(d)]) free.push_back(d);
  const Index m = static_cast<Index>(free.size());
  Eigen::MatrixXd reduced(m, m);
  Vector rhs(m);
  for (Index a = 0; a < m; ++a) {
    rhs[a] = load[free[a]];
    for (Index b = 0; b < m; ++b) reduced(a, b) = k(free[a], free[b]);
  }
  const Vector solution = reduced.fullPivLu().solve(rhs);
  Vector u = Vector::Zero(3 * n);
  for (Index a = 0; a < m; ++a) u[free[a]] = solution[a];
  double stretch = 0, y_top = 0, y_bottom = 0;
  int loaded = 0, top = 0, bottom = 0;
  for (Index i = 0; i < n; ++i) {
    const Vec3 p = rest.segment<3>(3 * i);
    if (p.x() > size.x() - eps) stretch += u[3 * i], ++loaded;
    if (p.y() > size.y() - eps) y_top += u[3 * i + 1], ++top;
    if (p.y() < eps) y_bottom += u[3 * i + 1], ++bottom;
  }
  const double strain = stretch / loaded / size.x();
  const double lateral = (y_top / top - y_bottom / bottom) / size.y();
  return {force / (size.y() * size.z()) / strain, -lateral / strain};
}

PositionError position_error(const Vector& rest, const Vector& reference, const Vector& positions) {
  PositionError error;
  double sum = 0, largest = 0;
  const Index n = rest.size() / 3;
  for (Index i = 0; i < n; ++i) {
    error.reference_max = std::max(error.reference_max, (reference.segment<3>(3 * i) - rest.segment<3>(3 * i)).norm());
    const double d = (reference.segment<3>(3 * i) - positions.segment<3>(3 * i)).norm();
    sum += d * d;
    largest = std::max(largest, d);
  }
  error.rms_pct = 100 * std::sqrt(sum / static_cast<double>(n)) / error.reference_max;
  error.max_pct = 100 * largest / error.reference_max;
  return error;
}

}  // namespace incise::physics
