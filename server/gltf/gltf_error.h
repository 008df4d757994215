// A glTF that cannot be imported: `path` is the JSON pointer of the offending part of the glTF
// ("/meshes/2/primitives/0"; "" for the whole file, "(root)" in the message), or "(glb)" for the binary
// container itself.
#pragma once

#include <stdexcept>
#include <string>

namespace refract::gltf {

class GltfError : public std::runtime_error {
public:
    GltfError(std::string path, const std::string& rule)
        : std::runtime_error((path.empty() ? "(root)" : path) + ": " + rule), path_(std::move(path)) {}
    const std::string& path() const { return path_; }

private:
    std::string path_;
};

}  // namespace refract::gltf
