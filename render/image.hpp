#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

namespace render {

struct Image {
    int width = 0;
    int height = 0;
    std::vector<uint8_t> rgba;  // 4 bytes per pixel, top row first

    // Pixel access for tests and tools; no bounds checks beyond the vector's own.
    const uint8_t* pixel(int x, int y) const { return rgba.data() + (size_t(y) * size_t(width) + size_t(x)) * 4; }
};

// Throws std::runtime_error naming the path when the image is malformed or the file
// cannot be written.
void write_png(const std::filesystem::path& path, const Image& image);

}  // namespace render
