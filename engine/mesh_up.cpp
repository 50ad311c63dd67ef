#include "engine/mesh_up.hpp"

#include <string>

namespace incise::engine {

std::array<double, 3> turn_up(const std::array<double, 3>& p, std::string_view up) {
  const auto [x, y, z] = p;
  if (up == "z") return {x, y, z};
  if (up == "y") return {x, -z, y};
  if (up == "x") return {y, z, x};
  if (up == "-z") return {x, -y, -z};
  if (up == "-y") return {x, z, -y};
  if (up == "-x") return {z, y, -x};
  throw MeshError("mesh_up '" + std::string(up) + "' is not an axis: \"x\", \"y\", \"z\", \"-x\", \"-y\" or \"-z\"");
}

}  // namespace incise::engine
