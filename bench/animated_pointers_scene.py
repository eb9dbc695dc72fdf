#!/usr/bin/env python3
"""Writes a small glTF whose animation runs only through KHR_animation_pointer, for checking
what the running service shows of it against afr-render at the same scene time.

The scene: a checkered floor quad whose base color texture scrolls (KHR_texture_transform
offset, 1/8 of the texture, one checker square, per half second) and a box above it that
KHR_node_visibility hides from 2 s to 4 s (a STEP key). 4 s of animation; the service loops it.

    bench/animated_pointers_scene.py out/pointers.gltf
    deploy/run-local.sh 2 --scene out/pointers.gltf --seconds 12 --size 160x160
    # out/final.png is stamped with its display time T (the log's "wrote out/final.png (t=T)"):
    build/bench/afr-render out/pointers.gltf --loop -t T -s 160x160 -o out/reference.png
    oiiotool out/final.png out/reference.png --diff
"""
import base64
import json
import struct
import sys
import zlib


def png(width, height, rgb_rows):
    """An 8-bit RGB PNG of the given rows (lists of r, g, b values)."""

    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data +
                struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    raw = b"".join(b"\x00" + bytes(row) for row in rgb_rows)
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw)) +
            chunk(b"IEND", b""))


class Buffer:
    """One embedded buffer, a buffer view and an accessor per array."""

    def __init__(self):
        self.data = b""
        self.views = []
        self.accessors = []

    def add(self, values, kind, component=5126, bounds=False):
        fmt = {5126: "f", 5123: "H"}[component]
        data = struct.pack("<%d%s" % (len(values), fmt), *values)
        self.data += b"\0" * (-len(self.data) % 4)
        self.views.append({"buffer": 0, "byteOffset": len(self.data), "byteLength": len(data)})
        self.data += data
        width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}[kind]
        accessor = {"bufferView": len(self.views) - 1, "componentType": component, "type": kind,
                    "count": len(values) // width}
        if bounds:
            accessor["min"] = [min(values[i::width]) for i in range(width)]
            accessor["max"] = [max(values[i::width]) for i in range(width)]
        self.accessors.append(accessor)
        return len(self.accessors) - 1


def box(half):
    """Positions and indices of an axis-aligned box, outward faces, 4 vertices a face."""
    positions, indices = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            u, v = (axis + 1) % 3, (axis + 2) % 3
            first = len(positions) // 3
            for du, dv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = [0.0, 0.0, 0.0]
                p[axis], p[u], p[v] = sign * half, du * half, dv * half
                positions += p
            quad = (0, 1, 2, 0, 2, 3) if sign > 0 else (0, 2, 1, 0, 3, 2)
            indices += [first + k for k in quad]
    return positions, indices


def pointer_channel(sampler, pointer):
    return {"sampler": sampler,
            "target": {"path": "pointer",
                       "extensions": {"KHR_animation_pointer": {"pointer": pointer}}}}


def scene():
    checker = [[c for x in range(8) for c in ((230, 230, 230) if (x + y) % 2 else (30, 60, 200))]
               for y in range(8)]
    b = Buffer()
    floor_positions = b.add([-2, -2, 0, 2, -2, 0, 2, 2, 0, -2, 2, 0], "VEC3", bounds=True)
    floor_uvs = b.add([0, 2, 2, 2, 2, 0, 0, 0], "VEC2")
    floor_indices = b.add([0, 1, 2, 0, 2, 3], "SCALAR", component=5123)
    box_p, box_i = box(0.5)
    box_positions = b.add(box_p, "VEC3", bounds=True)
    box_indices = b.add(box_i, "SCALAR", component=5123)
    times = b.add([0, 2, 4], "SCALAR", bounds=True)
    offsets = b.add([0, 0, 0.5, 0, 1, 0], "VEC2")
    visible = b.add([1, 0, 1], "SCALAR")
    transform = {"KHR_texture_transform": {"offset": [0, 0]}}
    return {
        "asset": {"version": "2.0", "generator": "afr bench/animated_pointers_scene.py"},
        "extensionsUsed": ["KHR_texture_transform", "KHR_animation_pointer",
                           "KHR_node_visibility"],
        "buffers": [{"byteLength": len(b.data), "uri": "data:application/octet-stream;base64," +
                     base64.b64encode(b.data).decode()}],
        "bufferViews": b.views,
        "accessors": b.accessors,
        "images": [{"uri": "data:image/png;base64," +
                    base64.b64encode(png(8, 8, checker)).decode()}],
        "samplers": [{"magFilter": 9728}],
        "textures": [{"source": 0, "sampler": 0}],
        "materials": [
            {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "extensions": transform},
                                      "metallicFactor": 0}},
            {"pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.3, 0.1, 1],
                                      "metallicFactor": 0}}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": floor_positions, "TEXCOORD_0": floor_uvs},
                             "indices": floor_indices, "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": box_positions},
                             "indices": box_indices, "material": 1}]}],
        "nodes": [{"mesh": 0}, {"mesh": 1, "translation": [0, 0, 1]}],
        "scenes": [{"nodes": [0, 1]}],
        "scene": 0,
        "animations": [{
            "samplers": [{"input": times, "output": offsets},
                         {"input": times, "output": visible, "interpolation": "STEP"}],
            "channels": [
                pointer_channel(0, "/materials/0/pbrMetallicRoughness/baseColorTexture/"
                                   "extensions/KHR_texture_transform/offset"),
                pointer_channel(1, "/nodes/1/extensions/KHR_node_visibility/visible")]}],
    }


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: animated_pointers_scene.py OUT.gltf")
    with open(sys.argv[1], "w") as out:
        json.dump(scene(), out)
