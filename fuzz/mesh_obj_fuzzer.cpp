// Bytes -> import_surface as a file named .obj (fuzz/surface_fuzzer.hpp).
#include "fuzz/surface_fuzzer.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::filesystem::path file = incise::fuzz::temp_file("mesh.obj");
  incise::fuzz::import_surface_bytes(file, data, size);
  return 0;
}
