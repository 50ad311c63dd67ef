// What every mesh reader shares: its error type and the scene's `mesh_up` turn. Apart from
// mesh_import.hpp so that the scene reader and the tetrahedral readers need no assimp.
#pragma once

#include <array>
#include <stdexcept>
#include <string_view>

namespace incise::engine {

class MeshError : public std::runtime_error {
  using std::runtime_error::runtime_error;
};

// A file's point in the scene's frame when the file's `up` axis ("x", "y", "z", "-x", "-y" or
// "-z"; scene key `mesh_up`) is the scene's +z: a rotation, so tetrahedra keep their
// orientation and surfaces their outside. Y-up files (glTF, most OBJ exporters) need "y".
// Throws MeshError for another value.
std::array<double, 3> turn_up(const std::array<double, 3>& p, std::string_view up);

}  // namespace incise::engine
