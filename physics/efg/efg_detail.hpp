// What the files of CorotationalEfg share besides its class: its error messages and the
// longest row a neighbourhood may have.
#pragma once

#include "physics/core/model.hpp"

#include <sstream>
#include <stdexcept>
#include <string>

namespace incise::physics::efg_detail {

// The longest row a neighbourhood may have; far more than the 8 to 12 that cuts produce, it
// only stops a runaway selection.
inline constexpr int longest_row = 64;

[[noreturn]] inline void fail(const std::string& what) { throw std::invalid_argument("CorotationalEfg: " + what); }

inline std::string format_point(const Vec3& p) {
  std::ostringstream stream;
  stream.precision(6);
  stream << "(" << p.x() << ", " << p.y() << ", " << p.z() << ")";
  return stream.str();
}

}  // namespace incise::physics::efg_detail
