#include "gltf/gltf_geometry.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "gltf/glb_container.h"
#include "gltf/gltf_error.h"

namespace refract::gltf {
namespace {

// No callback reads a file: URIs were refused before (checked_json); this is the second lock.
bool no_file(const std::string&, void*) { return false; }
std::string same_path(const std::string& path, void*) { return path; }
bool refuse_read(std::vector<unsigned char>*, std::string* err, const std::string& path, void*) {
    if (err) *err += "refused to read '" + path + "': the daemon reads no files for a client\n";
    return false;
}
bool refuse_write(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
    if (err) *err += "refused to write a file\n";
    return false;
}
// Textures have no meaning here: images are kept undecoded (and reported by the importer).
bool keep_undecoded(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int,
                    void*) {
    return true;
}

// The bytes an accessor spans, checked: its view inside its buffer, its elements inside its view.
struct Span {
    const unsigned char* data = nullptr;
    size_t count = 0, stride = 0, element = 0;
};

Span accessor_span(const tinygltf::Model& model, int index, const std::string& path) {
    const auto fail = [&](const std::string& rule) -> Span {
        throw GltfError(path, "accessor " + std::to_string(index) + " " + rule);
    };
    if (index < 0 || static_cast<size_t>(index) >= model.accessors.size()) return fail("does not exist");
    const tinygltf::Accessor& a = model.accessors[static_cast<size_t>(index)];
    if (a.sparse.isSparse) return fail("is sparse, which is not supported for geometry");
    if (a.count == 0) return fail("is empty");
    if (a.bufferView < 0 || static_cast<size_t>(a.bufferView) >= model.bufferViews.size())
        return fail("has no buffer view");
    const tinygltf::BufferView& view = model.bufferViews[static_cast<size_t>(a.bufferView)];
    if (view.buffer < 0 || static_cast<size_t>(view.buffer) >= model.buffers.size()) return fail("names no buffer");
    const size_t buffer_size = model.buffers[static_cast<size_t>(view.buffer)].data.size();
    if (view.byteOffset > buffer_size || view.byteLength > buffer_size - view.byteOffset)
        return fail("reads buffer view " + std::to_string(a.bufferView) + ", which reaches past its buffer (" +
                    std::to_string(view.byteOffset) + " + " + std::to_string(view.byteLength) + " > " +
                    std::to_string(buffer_size) + " bytes)");
    const int component = tinygltf::GetComponentSizeInBytes(static_cast<uint32_t>(a.componentType));
    const int components = tinygltf::GetNumComponentsInType(static_cast<uint32_t>(a.type));
    if (component <= 0 || components <= 0) return fail("has an unknown component type or type");
    Span s;
    s.count = a.count;
    s.element = static_cast<size_t>(component) * static_cast<size_t>(components);
    s.stride = view.byteStride ? view.byteStride : s.element;
    if (s.stride < s.element) return fail("has a byteStride smaller than its element");
    const size_t limit = std::numeric_limits<size_t>::max();
    if (a.count - 1 > (limit - s.element) / s.stride || a.byteOffset > view.byteLength ||
        (a.count - 1) * s.stride + s.element > view.byteLength - a.byteOffset)
        return fail("reaches past its buffer view (" + std::to_string(a.count) + " elements of " +
                    std::to_string(s.element) + " bytes every " + std::to_string(s.stride) + " from byte " +
                    std::to_string(a.byteOffset) + " of " + std::to_string(view.byteLength) + ")");
    s.data = model.buffers[static_cast<size_t>(view.buffer)].data.data() + view.byteOffset + a.byteOffset;
    return s;
}

std::vector<glm::vec3> positions(const tinygltf::Model& model, const tinygltf::Primitive& primitive,
                                 const std::string& path, const mesh::MeshLimits& limits) {
    const auto it = primitive.attributes.find("POSITION");
    if (it == primitive.attributes.end()) throw GltfError(path, "has no POSITION attribute");
    const std::string where = path + "/attributes/POSITION";
    const Span s = accessor_span(model, it->second, where);
    const tinygltf::Accessor& a = model.accessors[static_cast<size_t>(it->second)];
    if (a.type != TINYGLTF_TYPE_VEC3 || a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
        throw GltfError(where, "POSITION must be VEC3 of FLOAT");
    if (s.count > limits.max_vertices)
        throw GltfError(where, std::to_string(s.count) + " vertices, over the limit of " + std::to_string(limits.max_vertices));
    std::vector<glm::vec3> out(s.count);
    for (size_t i = 0; i < s.count; ++i) {
        std::memcpy(&out[i], s.data + i * s.stride, sizeof(glm::vec3));
        for (int c = 0; c < 3; ++c)
            if (!std::isfinite(out[i][c]) || std::fabs(out[i][c]) > limits.max_abs_coordinate)
                throw GltfError(where, "vertex " + std::to_string(i) + " is not finite or beyond 1e6");
    }
    return out;
}

std::vector<uint32_t> indices(const tinygltf::Model& model, const tinygltf::Primitive& primitive, size_t vertices,
                              const std::string& path) {
    std::vector<uint32_t> out;
    if (primitive.indices < 0) {
        out.resize(vertices);
        for (size_t i = 0; i < vertices; ++i) out[i] = static_cast<uint32_t>(i);
        return out;
    }
    const std::string where = path + "/indices";
    const Span s = accessor_span(model, primitive.indices, where);
    const tinygltf::Accessor& a = model.accessors[static_cast<size_t>(primitive.indices)];
    if (a.type != TINYGLTF_TYPE_SCALAR || s.element > 4 || a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT)
        throw GltfError(where, "indices must be SCALAR unsigned integers");
    out.resize(s.count);
    for (size_t i = 0; i < s.count; ++i) {
        uint32_t v = 0;
        if (s.element == 1) v = s.data[i * s.stride];
        else if (s.element == 2) { uint16_t w; std::memcpy(&w, s.data + i * s.stride, 2); v = w; }
        else std::memcpy(&v, s.data + i * s.stride, 4);
        if (v >= vertices)
            throw GltfError(where, "index " + std::to_string(i) + " is " + std::to_string(v) + ", past the " +
                                       std::to_string(vertices) + " vertices");
        out[i] = v;
    }
    return out;
}

// Triangles of a list, strip or fan, in glTF's winding (counter-clockwise from outside).
std::vector<glm::uvec3> triangles(const std::vector<uint32_t>& idx, int mode) {
    std::vector<glm::uvec3> out;
    if (mode == TINYGLTF_MODE_TRIANGLES) {
        for (size_t i = 0; i + 2 < idx.size(); i += 3) out.emplace_back(idx[i], idx[i + 1], idx[i + 2]);
    } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
        for (size_t i = 0; i + 2 < idx.size(); ++i)
            out.push_back(i % 2 ? glm::uvec3(idx[i + 1], idx[i], idx[i + 2]) : glm::uvec3(idx[i], idx[i + 1], idx[i + 2]));
    } else {
        for (size_t i = 1; i + 1 < idx.size(); ++i) out.emplace_back(idx[0], idx[i], idx[i + 1]);
    }
    return out;
}

}  // namespace

tinygltf::Model load_model(std::string_view bytes) {
    // tinygltf takes the length as 32 bits.
    if (bytes.size() > std::numeric_limits<unsigned>::max()) throw GltfError("", "a glTF of 4 GiB or more");
    tinygltf::TinyGLTF loader;
    loader.SetStoreOriginalJSONForExtrasAndExtensions(true);
    loader.SetImageLoader(keep_undecoded, nullptr);
    loader.SetFsCallbacks({no_file, same_path, refuse_read, refuse_write, nullptr});
    tinygltf::Model model;
    std::string err, warn;
    const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
    const bool ok = is_glb(bytes)
                        ? loader.LoadBinaryFromMemory(&model, &err, &warn, data, static_cast<unsigned>(bytes.size()), "")
                        : loader.LoadASCIIFromString(&model, &err, &warn, bytes.data(),
                                                     static_cast<unsigned>(bytes.size()), "");
    if (!ok) throw GltfError("", "not a usable glTF: " + (err.empty() ? warn : err));
    return model;
}

glm::dmat4 local_matrix(const tinygltf::Node& node, const std::string& path) {
    const auto finite = [&](const std::vector<double>& values, const char* what) {
        for (double v : values)
            if (!std::isfinite(v)) throw GltfError(path + "/" + what, "not finite (NaN or infinite)");
    };
    finite(node.matrix, "matrix");
    finite(node.translation, "translation");
    finite(node.rotation, "rotation");
    finite(node.scale, "scale");
    glm::dmat4 m(1.0);
    if (node.matrix.size() == 16) {
        for (int i = 0; i < 16; ++i) m[i / 4][i % 4] = node.matrix[static_cast<size_t>(i)];
        return m;
    }
    if (node.translation.size() == 3) m[3] = glm::dvec4(node.translation[0], node.translation[1], node.translation[2], 1.0);
    glm::dmat3 rs(1.0);
    if (node.rotation.size() == 4) {
        glm::dvec4 q(node.rotation[0], node.rotation[1], node.rotation[2], node.rotation[3]);
        if (!(glm::length(q) > 0.0)) throw GltfError(path + "/rotation", "a zero quaternion is no rotation");
        q = glm::normalize(q);
        const double x = q.x, y = q.y, z = q.z, w = q.w;
        rs = glm::dmat3(glm::dvec3(1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w)),
                        glm::dvec3(2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w)),
                        glm::dvec3(2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y)));
    }
    if (node.scale.size() == 3)
        for (int c = 0; c < 3; ++c) rs[c] *= node.scale[static_cast<size_t>(c)];
    for (int c = 0; c < 3; ++c) m[c] = glm::dvec4(rs[c], 0.0);
    return m;
}

std::optional<mesh::Mesh> primitive_mesh(const tinygltf::Model& model, const tinygltf::Primitive& primitive,
                                         const std::string& path, const mesh::MeshLimits& limits) {
    const int mode = primitive.mode < 0 ? TINYGLTF_MODE_TRIANGLES : primitive.mode;
    if (mode < TINYGLTF_MODE_TRIANGLES || mode > TINYGLTF_MODE_TRIANGLE_FAN) return std::nullopt;
    const std::vector<glm::vec3> all = positions(model, primitive, path, limits);
    const std::vector<glm::uvec3> tris = triangles(indices(model, primitive, all.size(), path), mode);
    if (tris.empty()) throw GltfError(path, "has no triangles");
    if (tris.size() > limits.max_triangles)
        throw GltfError(path, std::to_string(tris.size()) + " triangles, over the limit of " +
                                  std::to_string(limits.max_triangles));
    // Unused vertices dropped, the rest in their order: the mesh an OBJ of it reads back as.
    std::vector<uint32_t> remap(all.size(), UINT32_MAX);
    for (const auto& t : tris)
        for (int c = 0; c < 3; ++c) remap[t[c]] = 0;
    mesh::Mesh m;
    for (size_t i = 0; i < all.size(); ++i)
        if (remap[i] == 0) {
            remap[i] = static_cast<uint32_t>(m.positions.size());
            m.positions.push_back(all[i]);
        }
    m.triangles.reserve(tris.size());
    for (const auto& t : tris) m.triangles.emplace_back(remap[t.x], remap[t.y], remap[t.z]);
    return m;
}

}  // namespace refract::gltf
