#!/usr/bin/env python3
"""Writes the seed corpora of the fuzz targets in tests/fuzz/corpus/ (docs/robustness.md).

  aff/          the hand-written scene of the AFF tests (every directive) and small excerpts
                of the BART kitchen (its view, lights, camera and toy car keyframes, a few
                small files whole), read from the shared folder (never copied whole)
  gltf/         small .gltf files with embedded buffers (and one .glb), one per feature of
                the loader: accessors (strided, sparse, normalized), strips and fans, textures,
                cameras, lights, node trees, animations, unsupported features
  camera_path/  bench/paths/toycar.path, the head of interactive.path, and variants (CRLF,
                tabs, comments)
  protocol/     not written here: encoded messages come from the codec itself, through
                AFR_FUZZ_CORPUS_DIR=... afr_protocol_test --gtest_filter=FuzzDecodeTest.SeedsAreAccepted

Run from the repository root:  python3 tests/fuzz/make_seeds.py [SHARED_DIR]
(deterministic output; SHARED_DIR defaults to ../shared).
"""
import base64
import json
import os
import re
import struct
import sys
import zlib

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CORPUS = os.path.join(ROOT, "tests", "fuzz", "corpus")


def write(target, name, data):
    folder = os.path.join(CORPUS, target)
    os.makedirs(folder, exist_ok=True)
    if isinstance(data, str):
        data = data.encode("latin-1")
    with open(os.path.join(folder, name), "wb") as f:
        f.write(data)


# ---- AFF -------------------------------------------------------------------------------------


def hand_scene():
    """The scene of tests/tools/hand_scene.h, taken from that header (LF line ends)."""
    with open(os.path.join(ROOT, "tests", "tools", "hand_scene.h"), encoding="latin-1") as f:
        header = f.read()
    body = header[header.index("hand_scene_text()"):]
    body = body[:body.index(";\n}")]
    parts = re.findall(r'R"\((.*?)\)"|"((?:[^"\\]|\\.)*)"', body, re.S)
    text = ""
    for raw, escaped in parts:
        text += raw if raw else escaped.encode("latin-1").decode("unicode_escape")
    return text


def block(lines, start_pattern, count=None):
    """From the first line matching start_pattern up to the closing '}' (or `count` lines)."""
    start = next(i for i, line in enumerate(lines) if re.match(start_pattern, line))
    end = start
    while end < len(lines) and (count is not None or lines[end].strip() != "}"):
        end += 1
        if count is not None and end - start >= count:
            break
    return "\n".join(lines[start:end + 1]) + "\n"


def aff_seeds(shared):
    write("aff", "hand.aff", hand_scene())
    aff = os.path.join(shared, "scenes", "bart-kitchen", "aff")
    with open(os.path.join(aff, "kitchen.aff"), encoding="latin-1") as f:
        kitchen = f.read().split("\n")
    head = kitchen[:kitchen.index("i 0 floor.aff")]
    write("aff", "kitchen_view.aff", "\n".join(head) + "\na 0.0 20.0 800\n")
    write("aff", "kitchen_camera.aff", "a 0.0 20.0 800\n" + block(kitchen, r"^k camera"))
    # The toy car: its x block (with its include replaced by one the fuzzer can find) and
    # its k block (transl of the worked example, scale, rot), cut to 12 rotation keys.
    toycar = block(kitchen, r"^k toycar").split("\n")
    rot = next(i for i, line in enumerate(toycar) if line.strip().startswith("rot"))
    toycar = toycar[:rot] + ["  rot 12"] + toycar[rot + 1:rot + 13] + ["}"]
    x = block(kitchen, r"^x toycar").replace("car.aff", "part.aff")
    write("aff", "kitchen_toycar.aff", "a 0.0 20.0 800\n" + x + "\n".join(toycar) + "\n")
    for name in ["floor.aff", "garden.aff", "car.aff", "param_glass.aff", "cupboard_box_small.aff",
                 "car_front_wheel_left.aff"]:
        with open(os.path.join(aff, name), "rb") as f:
            write("aff", "kitchen_" + name, f.read())
    write("aff", "include.aff", "d 2\ni 0 part.aff\ni 3 skipped.aff\nxs 1 1 1 0 1 0 0 0 0 0 {\n"
          "i 1 part.aff\n}\n")


# ---- glTF ------------------------------------------------------------------------------------

FLOAT, U8, U16, U32, I8, I16 = 5126, 5121, 5123, 5125, 5120, 5122


def png(width, height, rgb):
    """A tiny 8-bit RGB PNG."""
    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data +
                struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))
    raw = b"".join(b"\0" + bytes(rgb[y * width * 3:(y + 1) * width * 3]) for y in range(height))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


class Gltf:
    def __init__(self):
        self.doc = {"asset": {"version": "2.0"}}
        self.bin = bytearray()

    def view(self, data, stride=None):
        while len(self.bin) % 4:
            self.bin.append(0)
        v = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if stride:
            v["byteStride"] = stride
        self.bin += data
        self.doc.setdefault("bufferViews", []).append(v)
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, view, ctype, kind, count, **extra):
        a = {"componentType": ctype, "type": kind, "count": count}
        if view is not None:
            a["bufferView"] = view
        a.update(extra)
        self.doc.setdefault("accessors", []).append(a)
        return len(self.doc["accessors"]) - 1

    def floats(self, values, kind, **extra):
        width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[kind]
        data = struct.pack("<%df" % len(values), *values)
        return self.accessor(self.view(data), FLOAT, kind, len(values) // width, **extra)

    def indices(self, values, ctype=U16):
        fmt = {U8: "B", U16: "H", U32: "I"}[ctype]
        return self.accessor(self.view(struct.pack("<%d%s" % (len(values), fmt), *values)), ctype,
                             "SCALAR", len(values))

    def quad(self, **attributes):
        p = self.floats([0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0], "VEC3", min=[0, 0, 0], max=[1, 1, 0])
        prim = {"attributes": dict(POSITION=p, **attributes), "indices": self.indices([0, 1, 2, 0, 2, 3])}
        self.doc.setdefault("meshes", []).append({"name": "quad", "primitives": [prim]})
        self.doc.setdefault("nodes", []).append({"mesh": len(self.doc["meshes"]) - 1})
        self.doc["scenes"] = [{"nodes": [0]}]
        self.doc["scene"] = 0
        return prim

    def embedded(self):
        doc = dict(self.doc)
        doc["buffers"] = [{"byteLength": len(self.bin), "uri": "data:application/octet-stream;base64," +
                           base64.b64encode(bytes(self.bin)).decode()}]
        return json.dumps(doc, separators=(",", ":"))

    def glb(self):
        doc = dict(self.doc)
        doc["buffers"] = [{"byteLength": len(self.bin)}]
        text = json.dumps(doc, separators=(",", ":")).encode()
        text += b" " * (-len(text) % 4)
        data = bytes(self.bin) + b"\0" * (-len(self.bin) % 4)
        total = 12 + 8 + len(text) + 8 + len(data)
        return (b"glTF" + struct.pack("<II", 2, total) + struct.pack("<I", len(text)) + b"JSON" +
                text + struct.pack("<I", len(data)) + b"BIN\0" + data)


def gltf_seeds():
    g = Gltf()
    g.quad()
    write("gltf", "quad.gltf", g.embedded())
    write("gltf", "quad.glb", g.glb())

    g = Gltf()
    n = g.floats([0, 0, 1] * 4, "VEC3")
    t = g.floats([0, 0, 1, 0, 1, 1, 0, 1], "VEC2")
    g.quad(NORMAL=n, TEXCOORD_0=t)["material"] = 0
    image = png(2, 2, [255, 0, 0, 0, 255, 0, 0, 0, 255, 128, 128, 128])
    g.doc["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(image).decode()},
                       {"bufferView": g.view(image), "mimeType": "image/png"}]
    g.doc["samplers"] = [{"wrapS": 10497, "wrapT": 10497}, {"wrapS": 33071, "wrapT": 33648}]
    g.doc["textures"] = [{"source": 0, "sampler": 0}, {"source": 1, "sampler": 1}]
    g.doc["materials"] = [
        {"pbrMetallicRoughness": {"baseColorFactor": [1, 0.5, 0.25, 1], "baseColorTexture": {"index": 0},
                                  "metallicFactor": 0.2, "roughnessFactor": 0.7},
         "emissiveFactor": [0.1, 0.1, 0],
         "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 2}},
         "doubleSided": True, "extras": {"afr_ambient": [0.1, 0.2, 0.3]}},
        {"pbrMetallicRoughness": {"baseColorTexture": {"index": 1, "texCoord": 1}}, "alphaMode": "MASK",
         "normalTexture": {"index": 0}}]
    g.doc["extensionsUsed"] = ["KHR_materials_emissive_strength"]
    write("gltf", "textured.gltf", g.embedded())

    # Every material extension afr reads, each with its textures on two coordinate sets, on a
    # primitive without TANGENT (the loader generates tangents).
    g = Gltf()
    n = g.floats([0, 0, 1] * 4, "VEC3")
    t = g.floats([0, 0, 1, 0, 1, 1, 0, 1], "VEC2")
    g.quad(NORMAL=n, TEXCOORD_0=t, TEXCOORD_1=t)["material"] = 0
    image = png(1, 1, [128, 200, 64])
    g.doc["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(image).decode()}]
    g.doc["textures"] = [{"source": 0}]
    one = {"index": 0}
    other = {"index": 0, "texCoord": 1,
             "extensions": {"KHR_texture_transform": {"offset": [0.5, 0], "scale": [2, 2]}}}
    g.doc["materials"] = [
        {"normalTexture": one,
         "extensions": {
             "KHR_materials_transmission": {"transmissionFactor": 0.5, "transmissionTexture": one},
             "KHR_materials_ior": {"ior": 1.4},
             "KHR_materials_volume": {"thicknessFactor": 1, "attenuationDistance": 2,
                                      "attenuationColor": [0.9, 0.8, 0.7]},
             "KHR_materials_specular": {"specularFactor": 0.8, "specularTexture": other,
                                        "specularColorFactor": [1, 0.9, 0.8], "specularColorTexture": one},
             "KHR_materials_clearcoat": {"clearcoatFactor": 1, "clearcoatTexture": one,
                                         "clearcoatRoughnessFactor": 0.3, "clearcoatRoughnessTexture": other,
                                         "clearcoatNormalTexture": {"index": 0, "scale": 0.5}},
             "KHR_materials_sheen": {"sheenColorFactor": [1, 0.5, 0.5], "sheenColorTexture": one,
                                     "sheenRoughnessFactor": 0.5, "sheenRoughnessTexture": other},
             "KHR_materials_anisotropy": {"anisotropyStrength": 0.6, "anisotropyRotation": 0.5,
                                          "anisotropyTexture": other},
             "KHR_materials_iridescence": {"iridescenceFactor": 0.8, "iridescenceTexture": one,
                                           "iridescenceIor": 1.4, "iridescenceThicknessMinimum": 150,
                                           "iridescenceThicknessMaximum": 500,
                                           "iridescenceThicknessTexture": other}}}]
    g.doc["extensionsUsed"] = ["KHR_materials_transmission", "KHR_materials_ior", "KHR_materials_volume",
                               "KHR_materials_specular", "KHR_materials_clearcoat", "KHR_materials_sheen",
                               "KHR_materials_anisotropy", "KHR_materials_iridescence",
                               "KHR_texture_transform"]
    write("gltf", "material_extensions.gltf", g.embedded())

    # The specular-glossiness workflow with its textures over a metallic-roughness fallback, and
    # material variants.
    g = Gltf()
    g.quad(NORMAL=g.floats([0, 0, 1] * 4, "VEC3"),
           TEXCOORD_0=g.floats([0, 0, 1, 0, 1, 1, 0, 1], "VEC2"))["material"] = 0
    g.doc["meshes"][0]["primitives"][0]["extensions"] = {
        "KHR_materials_variants": {"mappings": [{"material": 1, "variants": [0]}]}}
    g.doc["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(image).decode()}]
    g.doc["textures"] = [{"source": 0}]
    g.doc["materials"] = [
        {"pbrMetallicRoughness": {"baseColorTexture": one},
         "extensions": {"KHR_materials_pbrSpecularGlossiness": {
             "diffuseFactor": [1, 0.8, 0.6, 1], "diffuseTexture": one, "specularFactor": [0.2, 0.2, 0.2],
             "glossinessFactor": 0.7, "specularGlossinessTexture": one}}},
        {"pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 1]}}]
    g.doc["extensions"] = {"KHR_materials_variants": {"variants": [{"name": "red"}]}}
    g.doc["extensionsUsed"] = ["KHR_materials_pbrSpecularGlossiness", "KHR_materials_variants"]
    g.doc["extensionsRequired"] = ["KHR_materials_pbrSpecularGlossiness", "KHR_materials_variants"]
    write("gltf", "specular_glossiness.gltf", g.embedded())

    # Strips and fans over one interleaved (strided) buffer view; 8-bit indices.
    g = Gltf()
    verts = []
    for x, y in [(0, 0), (1, 0), (0, 1), (1, 1), (0, 2)]:
        verts += [x, y, 0, 0, 0, 1]
    v = g.view(struct.pack("<30f", *verts), stride=24)
    p = g.accessor(v, FLOAT, "VEC3", 5, min=[0, 0, 0], max=[1, 2, 0])
    nrm = g.accessor(v, FLOAT, "VEC3", 5, byteOffset=12)
    g.doc["meshes"] = [{"primitives": [
        {"attributes": {"POSITION": p, "NORMAL": nrm}, "indices": g.indices([0, 1, 2, 3, 4], U8), "mode": 5},
        {"attributes": {"POSITION": p}, "indices": g.indices([0, 1, 3, 2], U32), "mode": 6},
        {"attributes": {"POSITION": p}, "mode": 4, "indices": g.indices([0, 1, 2])},
        {"attributes": {"POSITION": p}, "mode": 1}]}]
    g.doc["nodes"] = [{"mesh": 0}]
    write("gltf", "strip_fan.gltf", g.embedded())

    # Sparse accessors, on a buffer view and on zeros; normalized integer texture coordinates.
    g = Gltf()
    base = g.view(struct.pack("<12f", 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0))
    p = g.accessor(base, FLOAT, "VEC3", 4, sparse={
        "count": 1, "indices": {"bufferView": g.view(struct.pack("<H", 2)), "componentType": U16},
        "values": {"bufferView": g.view(struct.pack("<3f", 2, 2, 0))}})
    n = g.accessor(None, FLOAT, "VEC3", 4, sparse={
        "count": 2, "indices": {"bufferView": g.view(bytes([0, 3])), "componentType": U8},
        "values": {"bufferView": g.view(struct.pack("<6f", 0, 0, 1, 0, 0, 1))}})
    uv = g.accessor(g.view(struct.pack("<8h", 0, 0, 32767, 0, 32767, 32767, 0, -32768)), I16, "VEC2", 4,
                    normalized=True)
    g.doc["meshes"] = [{"primitives": [{"attributes": {"POSITION": p, "NORMAL": n, "TEXCOORD_0": uv},
                                        "indices": g.indices([0, 1, 2, 0, 2, 3])}]}]
    g.doc["nodes"] = [{"mesh": 0}]
    g.doc["extensionsUsed"] = ["KHR_mesh_quantization"]
    write("gltf", "sparse.gltf", g.embedded())

    # A node tree with every transform form, cameras, the three light types and scene extras.
    g = Gltf()
    g.quad()
    g.doc["nodes"] = [
        {"mesh": 0, "children": [1, 2], "translation": [1, 2, 3], "rotation": [0, 0.7071068, 0, 0.7071068],
         "scale": [2, 2, 2]},
        {"camera": 0, "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 1, 5, 1]},
        {"children": [3, 4], "extensions": {"KHR_lights_punctual": {"light": 0}}},
        {"extensions": {"KHR_lights_punctual": {"light": 1}}, "rotation": [0.3826834, 0, 0, 0.9238795]},
        {"extensions": {"KHR_lights_punctual": {"light": 2}}, "camera": 1},
        {"mesh": 0}]
    g.doc["scenes"] = [{"nodes": [0, 5], "extras": {"afr_background": [0.1, 0.2, 0.3],
                                                     "afr_ambient": [1, 1, 1]}}]
    g.doc["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.01, "aspectRatio": 1.5}},
                        {"type": "orthographic", "orthographic": {"xmag": 1, "ymag": 1, "znear": 0, "zfar": 10}}]
    g.doc["extensions"] = {"KHR_lights_punctual": {"lights": [
        {"type": "point", "color": [1, 0.9, 0.8], "intensity": 5, "extras": {"afr_falloff": "none"}},
        {"type": "spot", "intensity": 10, "range": 20, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.6}},
        {"type": "directional", "intensity": 2, "extras": {"afr_falloff": "inverse_square"}}]}}
    g.doc["extensionsUsed"] = ["KHR_lights_punctual"]
    write("gltf", "nodes_cameras_lights.gltf", g.embedded())

    # Animations: LINEAR translation, STEP scale, CUBICSPLINE rotation, LINEAR morph weights.
    g = Gltf()
    prim = g.quad()
    prim["targets"] = [{"POSITION": g.floats([0, 0, 1] * 4, "VEC3")}]
    g.doc["nodes"] = [{"mesh": 0}, {"children": [0]}]
    g.doc["scenes"] = [{"nodes": [1]}]
    times = g.floats([0, 1, 2], "SCALAR", min=[0], max=[2])
    g.doc["animations"] = [{"samplers": [
        {"input": times, "output": g.floats([0, 0, 0, 1, 0, 0, 1, 1, 0], "VEC3"), "interpolation": "LINEAR"},
        {"input": times, "output": g.floats([1, 1, 1, 2, 2, 2, 1, 1, 1], "VEC3"), "interpolation": "STEP"},
        {"input": times, "output": g.floats([0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0] +
                                            [0, 0, 0, 0, 0, 0.7071068, 0, 0.7071068, 0, 0, 0, 0] +
                                            [0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0], "VEC4"),
         "interpolation": "CUBICSPLINE"},
        {"input": times, "output": g.floats([0, 1, 0], "SCALAR"), "interpolation": "LINEAR"}],
        "channels": [{"sampler": 0, "target": {"node": 1, "path": "translation"}},
                     {"sampler": 1, "target": {"node": 0, "path": "scale"}},
                     {"sampler": 2, "target": {"node": 0, "path": "rotation"}},
                     {"sampler": 3, "target": {"node": 0, "path": "weights"}}]}]
    write("gltf", "animation.gltf", g.embedded())

    # A skin of two joints (unsigned byte joints, normalized unsigned short weights, inverse bind
    # matrices) on a quad with a POSITION and NORMAL morph target, and a CUBICSPLINE weights
    # channel beside a rotation of the second joint.
    g = Gltf()
    joints = g.accessor(g.view(struct.pack("<16B", *([0, 1, 0, 0] * 4))), U8, "VEC4", 4)
    weights = g.accessor(g.view(struct.pack("<16H", *([65535, 0, 0, 0, 32768, 32767, 0, 0] * 2))),
                         U16, "VEC4", 4, normalized=True)
    prim = g.quad(JOINTS_0=joints, WEIGHTS_0=weights)
    prim["targets"] = [{"POSITION": g.floats([0, 0, 1] * 4, "VEC3"),
                        "NORMAL": g.floats([0.5, 0, 0] * 4, "VEC3")}]
    g.doc["meshes"][0]["weights"] = [0.25]
    identity = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
    ibm = g.accessor(g.view(struct.pack("<32f", *(identity + identity[:12] + [0, -1, 0, 1]))),
                     FLOAT, "MAT4", 2)
    g.doc["skins"] = [{"joints": [1, 2], "inverseBindMatrices": ibm, "skeleton": 1}]
    g.doc["nodes"] = [{"mesh": 0, "skin": 0}, {"children": [2]}, {"translation": [0, 1, 0]}]
    g.doc["scenes"] = [{"nodes": [0, 1]}]
    times = g.floats([0, 1], "SCALAR", min=[0], max=[1])
    g.doc["animations"] = [{"samplers": [
        {"input": times, "output": g.floats([0, 0, 0, 1, 0, 0, 0.7071068, 0.7071068], "VEC4")},
        {"input": times, "output": g.floats([0, 0, 0, 1, 1, 0], "SCALAR"), "interpolation": "CUBICSPLINE"}],
        "channels": [{"sampler": 0, "target": {"node": 2, "path": "rotation"}},
                     {"sampler": 1, "target": {"node": 0, "path": "weights"}}]}]
    write("gltf", "skin_morph.gltf", g.embedded())

    # Features afr skips with a warning or refuses: points, vertex colors, unknown required
    # extensions, no scenes (and a skinned node whose mesh has no joints).
    g = Gltf()
    prim = g.quad(COLOR_0=g.floats([1, 0, 0, 1] * 4, "VEC4"))
    prim["targets"] = [{"POSITION": g.floats([0, 0, 1] * 4, "VEC3")}]
    g.doc["meshes"][0]["weights"] = [0.5]
    g.doc["meshes"][0]["primitives"].append({"attributes": {"POSITION": 0}, "mode": 0})
    g.doc["skins"] = [{"joints": [0]}]
    g.doc["nodes"][0]["skin"] = 0
    g.doc["extensionsUsed"] = ["EXT_unknown", "KHR_texture_transform"]
    g.doc["extensionsRequired"] = ["EXT_unknown"]
    del g.doc["scenes"]
    del g.doc["scene"]
    write("gltf", "unsupported.gltf", g.embedded())


    # Compressed geometry and instances: EXT_meshopt_compression (a placeholder buffer without a
    # uri; positions, octahedral normals and triangles as meshoptimizer 0.18's encoders wrote the
    # unit quad), KHR_draco_mesh_compression (the quad as libdraco's encoder wrote it) and
    # EXT_mesh_gpu_instancing (three instances of the quad).
    g = Gltf()
    compressed = [("POSITIONS", 12, "ATTRIBUTES", None, FLOAT, "VEC3", False, 4),
                  ("NORMALS", 4, "ATTRIBUTES", "OCTAHEDRAL", I8, "VEC3", True, 4),
                  ("TRIANGLES", 2, "TRIANGLES", None, U16, "SCALAR", False, 6)]
    placeholder = 0
    accessors = []
    for name, stride, mode, filt, ctype, kind, normalized, count in compressed:
        data = bytes.fromhex(MESHOPT_STREAMS[name])
        while len(g.bin) % 4:
            g.bin.append(0)
        ext = {"buffer": 0, "byteOffset": len(g.bin), "byteLength": len(data), "byteStride": stride,
               "count": count, "mode": mode}
        if filt:
            ext["filter"] = filt
        g.bin += data
        view = {"buffer": 1, "byteOffset": placeholder, "byteLength": stride * count,
                "extensions": {"EXT_meshopt_compression": ext}}
        if mode == "ATTRIBUTES":
            view["byteStride"] = stride
        placeholder += (stride * count + 3) // 4 * 4
        g.doc.setdefault("bufferViews", []).append(view)
        extra = {"normalized": True} if normalized else {}
        accessors.append(g.accessor(len(g.doc["bufferViews"]) - 1, ctype, kind, count, **extra))
    g.doc["meshes"] = [{"primitives": [{"attributes": {"POSITION": accessors[0], "NORMAL": accessors[1]},
                                        "indices": accessors[2]}]}]
    g.doc["nodes"] = [{"mesh": 0}]
    g.doc["scenes"] = [{"nodes": [0]}]
    g.doc["extensionsUsed"] = ["EXT_meshopt_compression", "KHR_mesh_quantization"]
    g.doc["extensionsRequired"] = ["EXT_meshopt_compression", "KHR_mesh_quantization"]
    doc = json.loads(g.embedded())
    doc["buffers"].append({"byteLength": placeholder,
                           "extensions": {"EXT_meshopt_compression": {"fallback": True}}})
    write("gltf", "meshopt.gltf", json.dumps(doc, separators=(",", ":")))

    g = Gltf()
    draco = g.view(bytes.fromhex(DRACO_QUAD))
    positions = g.accessor(None, FLOAT, "VEC3", 4, min=[0, 0, 0], max=[1, 1, 0])
    indices = g.accessor(None, U16, "SCALAR", 6)
    g.doc["meshes"] = [{"primitives": [{
        "attributes": {"POSITION": positions}, "indices": indices,
        "extensions": {"KHR_draco_mesh_compression": {"bufferView": draco,
                                                      "attributes": {"POSITION": 0}}}}]}]
    g.doc["nodes"] = [{"mesh": 0, "extensions": {"EXT_mesh_gpu_instancing": {"attributes": {
        "TRANSLATION": g.floats([0, 0, 0, 2, 0, 0, 0, 2, 0], "VEC3"),
        "ROTATION": g.accessor(g.view(struct.pack("<12h", 0, 0, 0, 32767, 0, 0, 32767, 0, 0, 0, 0, 32767)),
                               I16, "VEC4", 3, normalized=True),
        "SCALE": g.floats([1, 1, 1, 2, 2, 2, 1, 1, 1], "VEC3")}}}}]
    g.doc["scenes"] = [{"nodes": [0]}]
    g.doc["extensionsUsed"] = ["KHR_draco_mesh_compression", "EXT_mesh_gpu_instancing"]
    g.doc["extensionsRequired"] = ["KHR_draco_mesh_compression", "EXT_mesh_gpu_instancing"]
    write("gltf", "draco_instanced.glb", g.glb())

    # The extensions read from the JSON beside tinygltf: KHR_animation_pointer channels (a node's
    # translation and weights, a material's emissive factor), KHR_node_visibility,
    # KHR_materials_dispersion in a volume, emissive strength and unlit; asset minVersion.
    g = Gltf()
    prim = g.quad()
    prim["targets"] = [{"POSITION": g.floats([0, 0, 1] * 4, "VEC3")}]
    prim["material"] = 0
    g.doc["asset"] = {"version": "2.1", "minVersion": "2.0"}
    g.doc["materials"] = [
        {"extensions": {"KHR_materials_transmission": {"transmissionFactor": 1},
                        "KHR_materials_volume": {"thicknessFactor": 0.5},
                        "KHR_materials_dispersion": {"dispersion": 2.0},
                        "KHR_materials_emissive_strength": {"emissiveStrength": 4}},
         "emissiveFactor": [1, 0.5, 0]},
        {"extensions": {"KHR_materials_unlit": {}}}]
    g.doc["nodes"] = [{"mesh": 0}, {"children": [0], "extensions": {"KHR_node_visibility": {"visible": True}}},
                      {"mesh": 0, "extensions": {"KHR_node_visibility": {"visible": False}}}]
    g.doc["scenes"] = [{"nodes": [1, 2]}]
    times = g.floats([0, 1], "SCALAR", min=[0], max=[1])
    pointer = lambda path: {"sampler": 0, "target": {"path": "pointer", "extensions": {
        "KHR_animation_pointer": {"pointer": path}}}}
    g.doc["animations"] = [{"samplers": [
        {"input": times, "output": g.floats([0, 0, 0, 1, 0, 0], "VEC3")},
        {"input": times, "output": g.floats([0, 1], "SCALAR")},
        {"input": times, "output": g.floats([1, 1, 1, 0, 0, 0], "VEC3")}],
        "channels": [pointer("/nodes/1/translation"),
                     dict(pointer("/nodes/0/weights"), sampler=1),
                     dict(pointer("/materials/0/emissiveFactor"), sampler=2)]}]
    g.doc["extensionsUsed"] = ["KHR_animation_pointer", "KHR_node_visibility", "KHR_materials_transmission",
                               "KHR_materials_volume", "KHR_materials_dispersion",
                               "KHR_materials_emissive_strength", "KHR_materials_unlit"]
    write("gltf", "pointer_visibility_dispersion.gltf", g.embedded())

    # KHR_animation_pointer channels that reach further: a texture slot's KHR_texture_transform
    # (offset, rotation, scale), a node's KHR_node_visibility (a parent with a child), the
    # material extensions' factors, a light's colour and a camera's field of view; CUBICSPLINE
    # and STEP samplers among them.
    g = Gltf()
    n = g.floats([0, 0, 1] * 4, "VEC3")
    t = g.floats([0, 0, 1, 0, 1, 1, 0, 1], "VEC2")
    g.quad(NORMAL=n, TEXCOORD_0=t)["material"] = 0
    g.doc["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(png(2, 1, [255, 0, 0, 0, 0, 255])).decode()}]
    g.doc["textures"] = [{"source": 0}]
    transformed = {"index": 0, "extensions": {"KHR_texture_transform": {"offset": [0, 0], "rotation": 0,
                                                                         "scale": [1, 1]}}}
    g.doc["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": transformed},
                           "extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 0.5,
                                                                      "clearcoatTexture": transformed},
                                          "KHR_materials_sheen": {"sheenColorFactor": [1, 1, 1]},
                                          "KHR_materials_iridescence": {"iridescenceFactor": 1}}}]
    g.doc["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}]
    g.doc["extensions"] = {"KHR_lights_punctual": {"lights": [{"type": "point", "color": [1, 1, 1],
                                                               "intensity": 5}]}}
    g.doc["nodes"] = [{"mesh": 0, "children": [1]}, {"mesh": 0, "translation": [0, 0, 1]},
                      {"camera": 0, "translation": [0, 0, 4]},
                      {"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [0, 1, 2]}]
    g.doc["scenes"] = [{"nodes": [0, 2, 3]}]
    times = g.floats([0, 1, 2], "SCALAR", min=[0], max=[2])
    channel = lambda path, sampler: {"sampler": sampler, "target": {"path": "pointer", "extensions": {
        "KHR_animation_pointer": {"pointer": path}}}}
    g.doc["animations"] = [{"samplers": [
        {"input": times, "output": g.floats([0, 0, 0.5, 0, 1, 0.25], "VEC2")},
        {"input": times, "output": g.floats([0, 1, 0, 0, 1, 0, 0, 1, 0], "SCALAR"),
         "interpolation": "CUBICSPLINE"},
        {"input": times, "output": g.floats([1, 0, 1], "SCALAR"), "interpolation": "STEP"},
        {"input": times, "output": g.floats([0.2, 0.9, 0.4], "SCALAR")},
        {"input": times, "output": g.floats([1, 0, 0, 0, 1, 0, 0, 0, 1], "VEC3")},
        {"input": times, "output": g.floats([1.2, 1.8, 1.3], "SCALAR")}],
        "channels": [
            channel("/materials/0/pbrMetallicRoughness/baseColorTexture/extensions/KHR_texture_transform/offset", 0),
            channel("/materials/0/pbrMetallicRoughness/baseColorTexture/extensions/KHR_texture_transform/rotation", 1),
            channel("/materials/0/extensions/KHR_materials_clearcoat/clearcoatTexture/extensions/"
                    "KHR_texture_transform/scale", 0),
            channel("/nodes/0/extensions/KHR_node_visibility/visible", 2),
            channel("/materials/0/extensions/KHR_materials_clearcoat/clearcoatFactor", 3),
            channel("/materials/0/extensions/KHR_materials_sheen/sheenColorFactor", 4),
            channel("/materials/0/extensions/KHR_materials_iridescence/iridescenceIor", 5),
            channel("/extensions/KHR_lights_punctual/lights/0/color", 4),
            channel("/cameras/0/perspective/yfov", 3)]}]
    g.doc["extensionsUsed"] = ["KHR_animation_pointer", "KHR_node_visibility", "KHR_texture_transform",
                               "KHR_materials_clearcoat", "KHR_materials_sheen", "KHR_materials_iridescence",
                               "KHR_lights_punctual"]
    write("gltf", "pointer_texture_transform.gltf", g.embedded())

    # KHR_materials_diffuse_transmission: a double-sided quad lit from behind, its strength and
    # color textures (one through KHR_texture_transform on TEXCOORD_1), both factors and the
    # strength texture's transform driven by KHR_animation_pointer.
    g = Gltf()
    n = g.floats([0, 0, 1] * 4, "VEC3")
    t = g.floats([0, 0, 1, 0, 1, 1, 0, 1], "VEC2")
    g.quad(NORMAL=n, TEXCOORD_0=t, TEXCOORD_1=t)["material"] = 0
    g.doc["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(png(2, 1, [255, 128, 0, 0, 64, 255])).decode()}]
    g.doc["textures"] = [{"source": 0}]
    moved = {"index": 0, "texCoord": 1, "extensions": {"KHR_texture_transform": {"rotation": 0.5}}}
    g.doc["materials"] = [{"doubleSided": True, "pbrMetallicRoughness": {"metallicFactor": 0},
                          "extensions": {"KHR_materials_diffuse_transmission": {
        "diffuseTransmissionFactor": 0.5, "diffuseTransmissionTexture": moved,
        "diffuseTransmissionColorFactor": [1, 0.8, 0.6], "diffuseTransmissionColorTexture": {"index": 0}}}}]
    g.doc["extensions"] = {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 8}]}}
    g.doc["nodes"] = [{"mesh": 0}, {"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [0, 0, -2]}]
    g.doc["scenes"] = [{"nodes": [0, 1]}]
    times = g.floats([0, 1], "SCALAR", min=[0], max=[1])
    channel = lambda path, sampler: {"sampler": sampler, "target": {"path": "pointer", "extensions": {
        "KHR_animation_pointer": {"pointer": path}}}}
    dt = "/materials/0/extensions/KHR_materials_diffuse_transmission/"
    g.doc["animations"] = [{"samplers": [
        {"input": times, "output": g.floats([0, 1], "SCALAR")},
        {"input": times, "output": g.floats([1, 1, 1, 0.2, 0.4, 0.9], "VEC3")}],
        "channels": [channel(dt + "diffuseTransmissionFactor", 0),
                     channel(dt + "diffuseTransmissionColorFactor", 1),
                     channel(dt + "diffuseTransmissionTexture/extensions/KHR_texture_transform/rotation", 0)]}]
    g.doc["extensionsUsed"] = ["KHR_animation_pointer", "KHR_materials_diffuse_transmission",
                               "KHR_texture_transform", "KHR_lights_punctual"]
    write("gltf", "diffuse_transmission.gltf", g.embedded())

    # A .glb whose BIN chunk is not padded to 4 bytes (read as if padded, with a warning).
    g = Gltf()
    g.quad()
    text = json.dumps(dict(g.doc, buffers=[{"byteLength": len(g.bin) + 2}]), separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    data = bytes(g.bin) + b"\0\0"
    total = 12 + 8 + len(text) + 8 + len(data)
    write("gltf", "unpadded.glb", b"glTF" + struct.pack("<II", 2, total) + struct.pack("<I", len(text)) +
          b"JSON" + text + struct.pack("<I", len(data)) + b"BIN\0" + data)


# meshoptimizer 0.18's meshopt_encodeVertexBuffer (positions: the unit quad as floats; normals:
# meshopt_encodeFilterOct at 8 bits of (0, 0, 1), (0.6, 0, 0.8), (0, -0.6, 0.8), (0, 0, 1)) and
# meshopt_encodeIndexBuffer (0 1 2 0 2 3): constants, so that the seeds need no encoder here.
MESHOPT_STREAMS = {
    "POSITIONS": "a000000133000000ffff01330000007e7d0000010c000000ff010c0000007e0000000000000000000000"
                 "00000000000000000000000000000000000000000000000000",
    "NORMALS": "a0013c0000006c6b010f0000006b6c000000000000000000000000000000000000000000000000000000"
               "00000000007f00",
    "TRIANGLES": "e0f000007687566778a9866589689801690000",
}
# libdraco 1.5's Encoder().EncodeMeshToBuffer of the unit quad's two triangles (positions only,
# attribute id 0, no quantization).
DRACO_QUAD = ("445241434f02020101000000040200020000011fff011101ff0000010009030000000000000000000000"
              "000000000000803f0000803f00000000000000000000803f000000000000803f0000000000000000")


# ---- Camera paths ----------------------------------------------------------------------------


def camera_path_seeds():
    paths = os.path.join(ROOT, "bench", "paths")
    with open(os.path.join(paths, "toycar.path"), "rb") as f:
        toycar = f.read()
    write("camera_path", "toycar.path", toycar)
    with open(os.path.join(paths, "interactive.path"), "rb") as f:
        lines = f.read().split(b"\n")
    head = b"\n".join(lines[:40]) + b"\n"
    write("camera_path", "interactive_head.path", head)
    write("camera_path", "interactive_crlf.path", head[:1200].rsplit(b"\n", 1)[0].replace(b"\n", b"\r\n"))
    write("camera_path", "tabs_blank_lines.path",
          b"# afr camera path v1\n\n0\t1 2 3\t0 0 0 1\t0.8\n# a comment\n   \n"
          b"1.5 1e-3 -2.5E2 +3 0.5 0.5 0.5 0.5 3.1\n2 0 0 0 0 0 0 2 1e-9\n")


def main():
    shared = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "..", "shared")
    aff_seeds(shared)
    gltf_seeds()
    camera_path_seeds()


if __name__ == "__main__":
    main()
