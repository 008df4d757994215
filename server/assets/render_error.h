// The error both sides raise when a valid document cannot be rendered: the renderer for what it cannot
// do, the store for an asset the document names that cannot be read.
#pragma once

#include <stdexcept>

namespace refract::scene {

// Raised for a scene that is valid JSON but cannot be rendered (unknown mesh name, over the memory
// budget, ...). The message is for the user; the resident state of every scene is unchanged.
class RenderError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

}  // namespace refract::scene
