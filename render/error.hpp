#pragma once

#include <stdexcept>
#include <string>

namespace render {

// One exception type for "the graphics stack cannot do what we need", so callers
// (a headless CI run, the app at start-up) can tell it apart from logic errors and
// fall back or report instead of crashing.
class RenderError : public std::runtime_error {
public:
    explicit RenderError(const std::string& message) : std::runtime_error(message) {}
};

}  // namespace render
