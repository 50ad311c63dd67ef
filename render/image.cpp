#include "render/image.hpp"

#include <fstream>
#include <stdexcept>
#include <string>

// Static linkage keeps these symbols private to this file: the window library also
// links Debian's libstb, which exports the same names.
#define STB_IMAGE_WRITE_STATIC
#define STB_IMAGE_WRITE_IMPLEMENTATION
#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wunused-function"
#endif
#include <stb_image_write.h>
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif

namespace render {

void write_png(const std::filesystem::path& path, const Image& image) {
    const std::string name = path.string();
    if (image.width <= 0 || image.height <= 0 ||
        image.rgba.size() != size_t(image.width) * size_t(image.height) * 4)
        throw std::runtime_error("write_png: image for '" + name + "' is " + std::to_string(image.width) + "x" +
                                 std::to_string(image.height) + " with " + std::to_string(image.rgba.size()) +
                                 " bytes, which is not width*height*4");

    // Encode to memory and write with a stream: stb's own file output reports no reason
    // for a failure and takes a narrow char path.
    std::string encoded;
    auto append = [](void* context, void* data, int size) {
        static_cast<std::string*>(context)->append(static_cast<const char*>(data), size_t(size));
    };
    if (!stbi_write_png_to_func(append, &encoded, image.width, image.height, 4, image.rgba.data(), image.width * 4))
        throw std::runtime_error("write_png: could not encode '" + name + "'");

    std::ofstream file(path, std::ios::binary | std::ios::trunc);
    if (!file) throw std::runtime_error("write_png: cannot open '" + name + "' for writing");
    file.write(encoded.data(), std::streamsize(encoded.size()));
    file.close();
    if (!file) throw std::runtime_error("write_png: failed while writing '" + name + "'");
}

}  // namespace render
