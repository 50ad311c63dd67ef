#include "physics/cp/constraints.hpp"

namespace incise::physics {

namespace {

Vec3 at(const Vector& x, int node) { return x.segment<3>(3 * static_cast<Eigen::Index>(node)); }

}  // namespace

double constraint_measure(const Constraint& c, const Vector& x) {
  const Vec3 xi = at(x, c.nodes[0]);
  const Vec3 xj = at(x, c.nodes[1]);
  switch (c.kind) {
    case ConstraintKind::distance:
      return (xj - xi).norm();
    case ConstraintKind::area:
      return 0.5 * (xj - xi).cross(at(x, c.nodes[2]) - xi).norm();
    case ConstraintKind::volume:
      return (xj - xi).dot((at(x, c.nodes[2]) - xi).cross(at(x, c.nodes[3]) - xi)) / 6.0;
  }
  return 0;
}

double constraint_gradient(const Constraint& c, const Vector& x, std::array<Vec3, 4>& gradient) {
  for (Vec3& g : gradient) g.setZero();
  const Vec3 xi = at(x, c.nodes[0]);
  const Vec3 xj = at(x, c.nodes[1]);
  switch (c.kind) {
    case ConstraintKind::distance: {
      const Vec3 d = xj - xi;
      const double length = d.norm();
      if (length > 0) {
        gradient[1] = d / (length * c.rest);
        gradient[0] = -gradient[1];
      }
      return (length - c.rest) / c.rest;
    }
    case ConstraintKind::area: {
      const Vec3 xk = at(x, c.nodes[2]);
      const Vec3 u = (xj - xi).cross(xk - xi);
      const double norm = u.norm();
      if (norm > 0) {
        // dA/dx_i = (x_j - x_k) x n / 2, and cyclically (eq. A.27).
        const Vec3 n = u / norm;
        const double scale = 0.5 / c.rest;
        gradient[0] = scale * (xj - xk).cross(n);
        gradient[1] = scale * (xk - xi).cross(n);
        gradient[2] = scale * (xi - xj).cross(n);
      }
      return (0.5 * norm - c.rest) / c.rest;
    }
    case ConstraintKind::volume: {
      const Vec3 xk = at(x, c.nodes[2]);
      const Vec3 xl = at(x, c.nodes[3]);
      const Vec3 w2 = (xk - xi).cross(xl - xi);
      const Vec3 w3 = (xl - xi).cross(xj - xi);
      const Vec3 w4 = (xj - xi).cross(xk - xi);
      // dC/dx = w / (6 V0): the 1/V0 that eq. 3.7 / A.46 lose in the force (digest A.5.1) is here.
      const double scale = 1.0 / (6.0 * c.rest);
      gradient[1] = scale * w2;
      gradient[2] = scale * w3;
      gradient[3] = scale * w4;
      gradient[0] = -(gradient[1] + gradient[2] + gradient[3]);  // w1 = -(w2 + w3 + w4)
      return ((xj - xi).dot(w2) / 6.0 - c.rest) / c.rest;
    }
  }
  return 0;
}

}  // namespace incise::physics
