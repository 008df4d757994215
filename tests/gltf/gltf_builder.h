// glTF files written by hand for the tests: JSON plus one binary buffer, packed as a .glb or as a .gltf
// with the buffer in a data: URI, so that each test states exactly what the file says.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

namespace refract::test {

struct GltfBuilder {
    nlohmann::json gltf = {{"asset", {{"version", "2.0"}}}, {"scene", 0}, {"scenes", {{{"nodes", nlohmann::json::array()}}}}};
    std::string bin;

    // Accessors over the positions and triangle indices, and a mesh of one primitive reading them.
    int add_mesh(const std::string& name, const std::vector<glm::vec3>& positions,
                 const std::vector<glm::uvec3>& triangles, int material = -1) {
        const int position_view = add_view(positions.data(), positions.size() * sizeof(glm::vec3));
        const int index_view = add_view(triangles.data(), triangles.size() * sizeof(glm::uvec3));
        auto& accessors = gltf["accessors"];
        accessors.push_back({{"bufferView", position_view}, {"componentType", 5126}, {"count", positions.size()},
                             {"type", "VEC3"}});
        accessors.push_back({{"bufferView", index_view}, {"componentType", 5125}, {"count", triangles.size() * 3},
                             {"type", "SCALAR"}});
        nlohmann::json primitive = {{"attributes", {{"POSITION", accessors.size() - 2}}}, {"indices", accessors.size() - 1}};
        if (material >= 0) primitive["material"] = material;
        gltf["meshes"].push_back({{"name", name}, {"primitives", {primitive}}});
        return static_cast<int>(gltf["meshes"].size() - 1);
    }

    // A node; `root`: listed in the scene (else a parent lists it as a child).
    int add_node(nlohmann::json node, bool root = true) {
        gltf["nodes"].push_back(std::move(node));
        const int index = static_cast<int>(gltf["nodes"].size() - 1);
        if (root) gltf["scenes"][0]["nodes"].push_back(index);
        return index;
    }

    std::string glb() const {
        nlohmann::json j = gltf;
        j["buffers"] = {{{"byteLength", bin.size()}}};
        std::string text = j.dump();
        text.resize((text.size() + 3) / 4 * 4, ' ');
        std::string data = bin;
        data.resize((data.size() + 3) / 4 * 4, '\0');
        std::string out = "glTF";
        put(out, 2);
        put(out, static_cast<uint32_t>(12 + 8 + text.size() + 8 + data.size()));
        put(out, static_cast<uint32_t>(text.size()));
        out += "JSON" + text;
        put(out, static_cast<uint32_t>(data.size()));
        out += std::string("BIN\0", 4) + data;
        return out;
    }

    std::string gltf_text() const {
        nlohmann::json j = gltf;
        j["buffers"] = {{{"byteLength", bin.size()}, {"uri", "data:application/octet-stream;base64," + base64(bin)}}};
        return j.dump();
    }

    static std::string base64(const std::string& bytes) {
        static const char* digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        std::string out;
        for (size_t i = 0; i < bytes.size(); i += 3) {
            uint32_t v = static_cast<uint32_t>(static_cast<unsigned char>(bytes[i])) << 16;
            if (i + 1 < bytes.size()) v |= static_cast<uint32_t>(static_cast<unsigned char>(bytes[i + 1])) << 8;
            if (i + 2 < bytes.size()) v |= static_cast<unsigned char>(bytes[i + 2]);
            const size_t n = std::min<size_t>(3, bytes.size() - i);  // bytes in this group: n + 1 digits
            for (size_t k = 0; k < 4; ++k) out += k <= n ? digits[(v >> (18 - 6 * k)) & 63] : '=';
        }
        return out;
    }

private:
    int add_view(const void* data, size_t size) {
        bin.resize((bin.size() + 3) / 4 * 4, '\0');
        gltf["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", size}});
        bin.append(static_cast<const char*>(data), size);
        return static_cast<int>(gltf["bufferViews"].size() - 1);
    }

    static void put(std::string& out, uint32_t v) {
        char b[4];
        std::memcpy(b, &v, 4);
        out.append(b, 4);
    }
};

}  // namespace refract::test
