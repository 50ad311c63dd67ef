// A part of -df/dx that a model keeps out of its K because it need not be symmetric (the
// mass-spring's correction forces, physics/mss/hex_mass_spring.hpp), with the frames frozen by
// DeformableModel::update_rotations. A model offers it by deriving from this as well; the
// implicit step (implicit_euler.hpp) finds it by dynamic_cast, adds it to its matrix as it
// adds K's share (dt^2 K_extra), and solves with BiCGSTAB instead of CG where it is not
// symmetric.
#pragma once

#include "physics/core/model.hpp"

namespace incise::physics {

class ExtraStiffness {
 public:
  virtual ~ExtraStiffness() = default;
  virtual bool has_extra_stiffness() const = 0;  // false: none at present (the step ignores it)
  virtual bool extra_stiffness_symmetric() const = 0;
  virtual void add_extra_stiffness_product(const Vector& p, Vector& out) const = 0;  // out += K_extra p
  virtual void add_extra_stiffness_diagonal(Vector& diag) const = 0;                 // diag += its diagonal
};

// The model's extra stiffness where it offers one that is present, else null.
inline const ExtraStiffness* extra_stiffness(const DeformableModel& model) {
  const auto* extra = dynamic_cast<const ExtraStiffness*>(&model);
  return extra && extra->has_extra_stiffness() ? extra : nullptr;
}

}  // namespace incise::physics
