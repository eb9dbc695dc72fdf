#!/usr/bin/env python3
"""Writes static_scene.gltf: a still scene for the service tests (no animation, so a live run
converges to one image): a lit floor, colored emissive panels with sharp edges at several depths
and a box, seen by a fixed camera. The buffer is embedded (a data: URI), so the display can send
this one file to samplers. Run: python3 make_static_scene.py > static_scene.gltf"""
import base64, json, struct

positions, normals, indices, prims = [], [], [], []
def quad(corners, normal, material):
    base = len(positions)
    start = len(indices)
    positions.extend(corners); normals.extend([normal] * 4)
    indices.extend([base, base + 1, base + 2, base, base + 2, base + 3])
    prims.append((start, 6, material))

materials = [
    {"name": "floor", "pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.7, 0.65, 1], "metallicFactor": 0, "roughnessFactor": 0.9}},
    {"name": "red", "emissiveFactor": [0.9, 0.15, 0.1], "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0}},
    {"name": "green", "emissiveFactor": [0.1, 0.8, 0.2], "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0}},
    {"name": "blue", "emissiveFactor": [0.15, 0.25, 0.9], "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0}},
    {"name": "box", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.8, 0.3, 1], "metallicFactor": 0, "roughnessFactor": 0.6}},
]
quad([(-4, 0, 2), (4, 0, 2), (4, 0, -6), (-4, 0, -6)], (0, 1, 0), 0)
quad([(-2.5, 0.3, -4), (-0.8, 0.3, -4), (-0.8, 2.2, -4), (-2.5, 2.2, -4)], (0, 0, 1), 1)
quad([(-0.5, 0.8, -3), (0.9, 0.8, -3), (0.9, 2.5, -3), (-0.5, 2.5, -3)], (0, 0, 1), 2)
quad([(1.2, 0.2, -2.2), (2.4, 0.2, -2.2), (2.4, 1.3, -2.2), (1.2, 1.3, -2.2)], (0, 0, 1), 3)
# A box at (0.2, 0, -1.2), 0.8 wide.
x0, x1, y0, y1, z0, z1 = -0.2, 0.6, 0.0, 0.8, -1.6, -0.8
quad([(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], (0, 0, 1), 4)
quad([(x1, y0, z1), (x1, y0, z0), (x1, y1, z0), (x1, y1, z1)], (1, 0, 0), 4)
quad([(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)], (-1, 0, 0), 4)
quad([(x0, y1, z1), (x1, y1, z1), (x1, y1, z0), (x0, y1, z0)], (0, 1, 0), 4)

pos = b"".join(struct.pack("<3f", *p) for p in positions)
nor = b"".join(struct.pack("<3f", *n) for n in normals)
idx = b"".join(struct.pack("<I", i) for i in indices)
buf = pos + nor + idx
n = len(positions)
lo = [min(p[k] for p in positions) for k in range(3)]
hi = [max(p[k] for p in positions) for k in range(3)]
views = [{"buffer": 0, "byteOffset": 0, "byteLength": len(pos)},
         {"buffer": 0, "byteOffset": len(pos), "byteLength": len(nor)},
         {"buffer": 0, "byteOffset": len(pos) + len(nor), "byteLength": len(idx)}]
accessors = [{"bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3", "min": lo, "max": hi},
             {"bufferView": 1, "componentType": 5126, "count": n, "type": "VEC3"}]
primitives = []
for start, count, mat in prims:
    accessors.append({"bufferView": 2, "byteOffset": start * 4, "componentType": 5125, "count": count, "type": "SCALAR"})
    primitives.append({"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": len(accessors) - 1, "material": mat})
gltf = {
    "asset": {"version": "2.0", "generator": "afr tests/service/data/make_static_scene.py"},
    "scene": 0,
    "scenes": [{"nodes": [0, 1, 2]}],
    "nodes": [
        {"mesh": 0},
        {"camera": 0, "translation": [0.3, 1.4, 2.2], "rotation": [-0.1736482, 0, 0, 0.9848078]},
        {"translation": [1.5, 3.0, 0.5], "extensions": {"KHR_lights_punctual": {"light": 0}}},
    ],
    "cameras": [{"type": "perspective", "perspective": {"yfov": 0.9, "znear": 0.05}}],
    "meshes": [{"primitives": primitives}],
    "materials": materials,
    "extensionsUsed": ["KHR_lights_punctual"],
    "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 40.0, "color": [1, 1, 1]}]}},
    "buffers": [{"byteLength": len(buf), "uri": "data:application/octet-stream;base64," + base64.b64encode(buf).decode()}],
    "bufferViews": views,
    "accessors": accessors,
}
print(json.dumps(gltf, indent=1))
