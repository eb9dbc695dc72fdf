#!/usr/bin/env python3
"""Writes a glTF of nested media (KHR_materials_volume): a sealed glass tank half full of
water, on a floor under a sky, seen from the side. For the tracer's Media (docs/scene-model.md,
"Transmission and refraction") and for what the ray depth buys.

The glass is a closed solid: an outer box with outward faces and a cavity box with inward
ones. The water is a box with outward faces that reaches 0.05 into the glass's walls and floor,
so that no two surfaces coincide: a ray in the glass enters the water inside the wall, and from
there the water, entered last, is the medium it is in (glass to water: 1.5 to 1.33). A ray
through the water crosses six surfaces before it is out again, so the tracers' default depth
of 3 ends it black; the file leaves the depth to `--ray-depth`, or writes it with --depth N
(the root's extras.afr_ray_depth, which every node that loads the file follows).

    bench/glass_of_water_scene.py out/water.gltf
    for d in 3 6 8; do
      build/bench/afr-render out/water.gltf --ray-depth $d -s 160x160 --spp 4 -o out/water-$d.png
      oiiotool out/water-$d.png --cut 40x24+60+64 --printstats | grep Avg   # below the surface
    done
"""
import argparse
import base64
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from animated_pointers_scene import Buffer, box  # noqa: E402


def scene(depth=None):
    b = Buffer()
    cube_p, cube_i = box(0.5)
    outward = b.add(cube_p, "VEC3", bounds=True)
    outward_indices = b.add(cube_i, "SCALAR", component=5123)
    inward = [i for t in range(0, len(cube_i), 3) for i in (cube_i[t], cube_i[t + 2], cube_i[t + 1])]
    inward_indices = b.add(inward, "SCALAR", component=5123)
    floor = b.add([-8, 0, 8, 8, 0, 8, 8, 0, -8, -8, 0, -8], "VEC3", bounds=True)
    floor_indices = b.add([0, 1, 2, 0, 2, 3], "SCALAR", component=5123)

    def medium(name, ior, color, distance, tint):
        return {"name": name,
                "pbrMetallicRoughness": {"baseColorFactor": tint + [1], "metallicFactor": 0,
                                         "roughnessFactor": 0},
                "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1},
                               "KHR_materials_ior": {"ior": ior},
                               "KHR_materials_volume": {"thicknessFactor": 1,
                                                        "attenuationColor": color,
                                                        "attenuationDistance": distance}}}

    def solid(mesh_indices, material):
        return {"primitives": [{"attributes": {"POSITION": outward}, "indices": mesh_indices,
                                "material": material}]}

    def placed(mesh, lo, hi):
        return {"mesh": mesh, "translation": [(a + b) / 2 for a, b in zip(lo, hi)],
                "scale": [b - a for a, b in zip(lo, hi)]}

    doc = {
        "asset": {"version": "2.0", "generator": "afr bench/glass_of_water_scene.py"},
        "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_ior",
                           "KHR_materials_volume", "KHR_lights_punctual"],
        "buffers": [{"byteLength": len(b.data), "uri": "data:application/octet-stream;base64," +
                     base64.b64encode(b.data).decode()}],
        "bufferViews": b.views,
        "accessors": b.accessors,
        "materials": [
            medium("glass", 1.5, [0.92, 0.97, 0.95], 4.0, [1, 1, 1]),
            medium("water", 1.33, [0.55, 0.85, 0.95], 1.5, [1, 1, 1]),
            {"name": "floor", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.7, 0.5, 1],
                                                       "metallicFactor": 0}}],
        "meshes": [solid(outward_indices, 0), solid(inward_indices, 0),
                   solid(outward_indices, 1),
                   {"primitives": [{"attributes": {"POSITION": floor},
                                    "indices": floor_indices, "material": 2}]}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.1}}],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "directional", "intensity": 2.5}]}},
        "nodes": [
            placed(0, [-1, 0, -1], [1, 2.5, 1]),              # the glass
            placed(1, [-0.85, 0.15, -0.85], [0.85, 2.35, 0.85]),  # its cavity
            placed(2, [-0.9, 0.1, -0.9], [0.9, 1.6, 0.9]),     # the water
            {"mesh": 3},
            {"camera": 0, "translation": [0, 1.2, 5.5]},
            {"extensions": {"KHR_lights_punctual": {"light": 0}},
             "rotation": [-0.4, 0.3, 0.1, 0.86]},
        ],
        "scenes": [{"nodes": [0, 1, 2, 3, 4, 5],
                    "extras": {"afr_background": [0.55, 0.7, 0.95], "afr_ambient": [0.1, 0.1, 0.1]}}],
        "scene": 0,
    }
    if depth is not None:
        doc["extras"] = {"afr_ray_depth": depth}
    return doc


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", help="the .gltf to write")
    parser.add_argument("--depth", type=int, help="write this ray depth into the file")
    args = parser.parse_args()
    with open(args.out, "w") as out:
        json.dump(scene(args.depth), out)
