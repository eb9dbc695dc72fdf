#!/usr/bin/env python3
"""Writes a glTF lit by many point lights: a floor with a 5 x 5 grid of boxes under N lights
(KHR_lights_punctual, no range) on a grid 2.5 above it, warm and cool in turn, of unequal
intensities that add up to the same light for every N (with --moving, the camera slides to
the side and back over 8 s). For the tracer's light picking
(TracerOptions::light_samples, docs/sampler.md "Many lights"): every light reaches most of the
floor, and the boxes block some of them from each point near them.

    bench/many_lights_scene.py out/lights64.gltf --lights 64
    build/bench/afr-render out/lights64.gltf --light-samples 2 -s 320x240 --spp 4 -o out/l.png
"""
import argparse
import base64
import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from animated_pointers_scene import Buffer, box  # noqa: E402


def scene(n, moving=False):
    b = Buffer()
    cube_p, cube_i = box(0.5)
    cube = b.add(cube_p, "VEC3", bounds=True)
    cube_indices = b.add(cube_i, "SCALAR", component=5123)
    floor = b.add([-8, 0, 8, 8, 0, 8, 8, 0, -8, -8, 0, -8], "VEC3", bounds=True)
    floor_indices = b.add([0, 1, 2, 0, 2, 3], "SCALAR", component=5123)
    nodes = [{"mesh": 1},
             {"camera": 0, "translation": [0, 3, 9], "rotation": [-0.17, 0, 0, 0.985]}]
    for i in range(5):
        for j in range(5):
            nodes.append({"mesh": 0, "translation": [-4 + 2 * i, 0.5, -4 + 2 * j]})
    side = math.ceil(math.sqrt(n))
    weights = [1 + (i * 7) % 5 for i in range(n)]
    lights = []
    for i in range(n):
        x = -6 + 12 * ((i % side) + 0.5) / side
        z = -6 + 12 * ((i // side) + 0.5) / side
        color = [1, 0.85, 0.7] if i % 2 == 0 else [0.75, 0.85, 1]
        lights.append({"type": "point", "color": color,
                       "intensity": 60.0 * weights[i] / sum(weights)})
        nodes.append({"extensions": {"KHR_lights_punctual": {"light": i}},
                      "translation": [x, 2.5, z]})
    doc = {
        "asset": {"version": "2.0", "generator": "afr bench/many_lights_scene.py"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "buffers": [{"byteLength": len(b.data), "uri": "data:application/octet-stream;base64," +
                     base64.b64encode(b.data).decode()}],
        "bufferViews": b.views,
        "accessors": b.accessors,
        "materials": [{"name": "matte", "pbrMetallicRoughness": {
            "baseColorFactor": [0.8, 0.8, 0.8, 1], "metallicFactor": 0, "roughnessFactor": 0.7}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": cube}, "indices": cube_indices,
                                    "material": 0}]},
                   {"primitives": [{"attributes": {"POSITION": floor}, "indices": floor_indices,
                                    "material": 0}]}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}],
        "extensions": {"KHR_lights_punctual": {"lights": lights}},
        "nodes": nodes,
        "scenes": [{"nodes": list(range(len(nodes)))}],
        "scene": 0,
    }
    if moving:
        # The camera slides 4 to the side and back in 8 s, looking ahead all the while.
        times = b.add([0.0, 4.0, 8.0], "SCALAR", bounds=True)
        places = b.add([-2, 3, 9, 2, 3, 9, -2, 3, 9], "VEC3")
        doc["animations"] = [{"samplers": [{"input": times, "output": places}],
                              "channels": [{"sampler": 0,
                                            "target": {"node": 1, "path": "translation"}}]}]
        doc["buffers"][0] = {"byteLength": len(b.data),
                             "uri": "data:application/octet-stream;base64," +
                             base64.b64encode(b.data).decode()}
        doc["bufferViews"], doc["accessors"] = b.views, b.accessors
    return doc


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", help="the .gltf to write")
    parser.add_argument("--lights", type=int, default=64, help="how many point lights (>= 1)")
    parser.add_argument("--moving", action="store_true",
                        help="the camera slides to the side and back over 8 s")
    args = parser.parse_args()
    if args.lights < 1:
        sys.exit("many_lights_scene.py: --lights must be at least 1")
    with open(args.out, "w") as out:
        json.dump(scene(args.lights, args.moving), out)
