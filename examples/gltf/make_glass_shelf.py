#!/usr/bin/env python3
"""Writes glass_shelf.glb: four glass objects authored as glTF 2.0, the way a modelling tool exports them.

A crown-glass ball, an emerald block, a soap bubble and a flint ring, each its own mesh and material
(KHR_materials_transmission, _ior, _volume, _dispersion, _iridescence), a spot light and a directional
fill (KHR_lights_punctual, in candela and lux) and a camera. No library: the file is packed here, so
every number in it is one of the lines below. Refract's own settings that glTF has no words for (the
frame's size, the photons) ride in the scene's extras.refract. Run from anywhere:

    python3 examples/gltf/make_glass_shelf.py     # rewrites examples/gltf/glass_shelf.glb
"""
import json
import math
import struct
from pathlib import Path

LUMENS_PER_WATT = 683.0  # what Refract and Blender's glTF add-on convert with (docs/gltf.md)


def icosphere(subdivisions):
    t = (1 + 5 ** 0.5) / 2
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
             (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    verts = [tuple(c / math.hypot(*v) for c in v) for v in verts]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
             (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
             (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(subdivisions):
        cache, next_faces = {}, []

        def middle(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = [(verts[a][i] + verts[b][i]) / 2 for i in range(3)]
                n = math.hypot(*m)
                verts.append(tuple(c / n for c in m))
                cache[key] = len(verts) - 1
            return cache[key]

        for a, b, c in faces:
            ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
            next_faces += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = next_faces
    return verts, faces


def box():
    verts = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return verts, [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]


def torus(major, minor, segments=64, sides=24):
    verts, faces = [], []
    for i in range(segments):
        u = 2 * math.pi * i / segments
        for j in range(sides):
            v = 2 * math.pi * j / sides
            r = major + minor * math.cos(v)
            verts.append((r * math.cos(u), minor * math.sin(v), r * math.sin(u)))
    for i in range(segments):
        for j in range(sides):
            a, b = i * sides + j, ((i + 1) % segments) * sides + j
            c, d = ((i + 1) % segments) * sides + (j + 1) % sides, i * sides + (j + 1) % sides
            faces += [(a, d, c), (a, c, b)]
    return verts, faces


def look_rotation(direction, up=(0, 1, 0)):
    """The quaternion [x, y, z, w] turning a node's -Z towards `direction`, +Y towards `up`."""
    f = [c / math.hypot(*direction) for c in direction]
    r = [f[1] * up[2] - f[2] * up[1], f[2] * up[0] - f[0] * up[2], f[0] * up[1] - f[1] * up[0]]
    r = [c / math.hypot(*r) for c in r]
    u = [r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]]
    m = [[r[0], u[0], -f[0]], [r[1], u[1], -f[1]], [r[2], u[2], -f[2]]]  # rows of the rotation matrix
    w = math.sqrt(max(0.0, 1 + m[0][0] + m[1][1] + m[2][2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1 + m[0][0] - m[1][1] - m[2][2])) / 2, m[2][1] - m[1][2])
    y = math.copysign(math.sqrt(max(0.0, 1 - m[0][0] + m[1][1] - m[2][2])) / 2, m[0][2] - m[2][0])
    z = math.copysign(math.sqrt(max(0.0, 1 - m[0][0] - m[1][1] + m[2][2])) / 2, m[1][0] - m[0][1])
    return [x, y, z, w]


def glass(name, ior, attenuation_distance=None, attenuation_color=None, film=None):
    volume = {"thicknessFactor": 2.0}
    if attenuation_distance:
        volume.update(attenuationDistance=attenuation_distance, attenuationColor=attenuation_color)
    extensions = {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                  "KHR_materials_ior": {"ior": ior},
                  "KHR_materials_volume": volume,
                  "KHR_materials_dispersion": {"dispersion": 20 / 40}}  # one Abbe number (40) for the scene
    if film:
        extensions["KHR_materials_iridescence"] = film
    return {"name": name, "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.0},
            "extensions": extensions}


def main():
    gltf = {"asset": {"version": "2.0", "generator": "examples/gltf/make_glass_shelf.py"},
            "scene": 0, "scenes": [{"name": "glass shelf", "nodes": []}],
            "nodes": [], "meshes": [], "accessors": [], "bufferViews": [], "materials": [],
            "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_transmission", "KHR_materials_ior",
                               "KHR_materials_volume", "KHR_materials_dispersion", "KHR_materials_iridescence"]}
    binary = bytearray()

    def add_view(data, target):
        binary.extend(b"\0" * (-len(binary) % 4))
        gltf["bufferViews"].append({"buffer": 0, "byteOffset": len(binary), "byteLength": len(data), "target": target})
        binary.extend(data)
        return len(gltf["bufferViews"]) - 1

    def add_mesh(name, geometry, material):
        verts, faces = geometry
        positions = add_view(b"".join(struct.pack("<3f", *v) for v in verts), 34962)
        indices = add_view(b"".join(struct.pack("<3I", *f) for f in faces), 34963)
        lo = [min(v[i] for v in verts) for i in range(3)]
        hi = [max(v[i] for v in verts) for i in range(3)]
        gltf["accessors"] += [
            {"bufferView": positions, "componentType": 5126, "count": len(verts), "type": "VEC3",
             "min": [struct.unpack("<f", struct.pack("<f", c))[0] for c in lo],
             "max": [struct.unpack("<f", struct.pack("<f", c))[0] for c in hi]},
            {"bufferView": indices, "componentType": 5125, "count": 3 * len(faces), "type": "SCALAR"}]
        gltf["materials"].append(material)
        gltf["meshes"].append({"name": name, "primitives": [
            {"attributes": {"POSITION": len(gltf["accessors"]) - 2}, "indices": len(gltf["accessors"]) - 1,
             "material": len(gltf["materials"]) - 1}]})
        return len(gltf["meshes"]) - 1

    def add_node(node):
        gltf["nodes"].append(node)
        gltf["scenes"][0]["nodes"].append(len(gltf["nodes"]) - 1)

    # The objects stand on Refract's default floor (y = -1).
    add_node({"name": "crown_ball", "translation": [-0.95, -0.55, 0.1], "scale": [0.45] * 3,
              "mesh": add_mesh("ball", icosphere(3), glass("crown glass", 1.52))})
    add_node({"name": "emerald_block", "translation": [0.15, -0.65, -0.45], "scale": [0.35] * 3,
              "rotation": [0.0, math.sin(math.radians(15)), 0.0, math.cos(math.radians(15))],
              "mesh": add_mesh("block", box(), glass("emerald", 1.57, 0.6, [0.25, 0.8, 0.35]))})
    add_node({"name": "soap_bubble", "translation": [1.0, -0.42, 0.45], "scale": [0.5] * 3,
              "mesh": add_mesh("bubble", icosphere(3), glass("soap film on air", 1.001, film={
                  "iridescenceFactor": 1.0, "iridescenceIor": 1.33, "iridescenceThicknessMaximum": 600.0}))})
    add_node({"name": "flint_ring", "translation": [0.0, -0.88, 0.75],
              "mesh": add_mesh("ring", torus(0.35, 0.12), glass("flint glass", 1.65, 3.0, [0.9, 0.92, 1.0]))})

    key_position, key_target = [1.6, 3.0, 1.8], [0.0, -0.8, 0.2]
    outer = math.radians(28)
    gltf["extensions"] = {"KHR_lights_punctual": {"lights": [
        {"name": "key", "type": "spot", "color": [1.0, 0.96, 0.9], "intensity": 24 * LUMENS_PER_WATT,
         "spot": {"innerConeAngle": outer - 1e-9, "outerConeAngle": outer}},  # a hard cone, as Refract's
        {"name": "fill", "type": "directional", "color": [0.7, 0.8, 1.0], "intensity": 0.15 * LUMENS_PER_WATT}]}}
    add_node({"name": "key", "translation": key_position,
              "rotation": look_rotation([t - p for t, p in zip(key_target, key_position)]),
              "extensions": {"KHR_lights_punctual": {"light": 0}}})
    add_node({"name": "fill", "rotation": look_rotation([-0.4, -1.0, -0.6]),
              "extensions": {"KHR_lights_punctual": {"light": 1}}})

    eye, target = [0.0, 0.9, 5.2], [0.0, -0.5, 0.0]
    gltf["cameras"] = [{"type": "perspective", "perspective": {"yfov": math.radians(34), "aspectRatio": 1.5,
                                                              "znear": 0.05}}]
    add_node({"name": "camera", "camera": 0, "translation": eye,
              "rotation": look_rotation([t - e for t, e in zip(target, eye)])})

    gltf["scenes"][0]["extras"] = {"refract": {"image": {"width": 480, "height": 320},
                                               "photons": {"count": 262144}}}
    binary.extend(b"\0" * (-len(binary) % 4))
    gltf["buffers"] = [{"byteLength": len(binary)}]
    text = json.dumps(gltf, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    glb = struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(text) + 8 + len(binary))
    glb += struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(binary), b"BIN\0") + binary
    out = Path(__file__).with_name("glass_shelf.glb")
    out.write_bytes(glb)
    print(f"{out}: {len(glb)} bytes")


if __name__ == "__main__":
    main()
