// The glTF loader's tests of accessors: strides, sparse data, bounds, Draco and meshopt.
#include "gltf_loader_test.h"

namespace afr {
namespace {

using namespace gltf_test;

TEST_F(GltfLoaderTest, InterleavedStridedAndSparseAccessorsAreRead) {
  GltfBuilder b;
  // Position and normal of three vertices interleaved in one view of stride 24.
  const std::vector<float> interleaved = {0, 0, 0, 0, 0, 1, 2, 0, 0, 0, 0, 1, 0, 2, 0, 0, 0, 1};
  const int view = b.add_view(interleaved, 24);
  const int positions = b.add_accessor(view, kFloat, "VEC3", 3, 0);
  const int normals = b.add_accessor(view, kFloat, "VEC3", 3, 12);
  // Sparse: vertex 1 moves to (5, 6, 7).
  const std::vector<uint16_t> sparse_index = {1};
  const std::vector<float> sparse_value = {5, 6, 7};
  b.doc()["accessors"][positions]["sparse"] = {
      {"count", 1},
      {"indices", {{"bufferView", b.add_view(sparse_index)}, {"componentType", kUnsignedShort}}},
      {"values", {{"bufferView", b.add_view(sparse_value)}}}};
  // UVs with no buffer view at all (zeros) and one sparse value.
  const int uvs = b.add_accessor(-1, kFloat, "VEC2", 3);
  const std::vector<uint8_t> uv_index = {2};
  const std::vector<float> uv_value = {0.5f, 0.25f};
  b.doc()["accessors"][uvs]["sparse"] = {
      {"count", 1},
      {"indices", {{"bufferView", b.add_view(uv_index)}, {"componentType", kUnsignedByte}}},
      {"values", {{"bufferView", b.add_view(uv_value)}}}};
  b.doc()["meshes"].push_back(
      {{"primitives",
        json::array({{{"attributes",
                       {{"POSITION", positions}, {"NORMAL", normals}, {"TEXCOORD_0", uvs}}}}})}});
  b.doc()["nodes"].push_back({{"mesh", 0}});
  b.doc()["scenes"] = json::array({{{"nodes", {0}}}});
  const fs::path path = dir_ / "interleaved.gltf";
  b.write_embedded(path);

  const Scene scene = load_gltf(path);
  const Primitive& p = scene.meshes.at(0).primitives.at(0);
  EXPECT_EQ(p.positions, (std::vector<glm::vec3>{{0, 0, 0}, {5, 6, 7}, {0, 2, 0}}));
  EXPECT_EQ(p.normals, (std::vector<glm::vec3>(3, glm::vec3(0, 0, 1))));
  EXPECT_EQ(p.uvs, (std::vector<glm::vec2>{{0, 0}, {0, 0}, {0.5f, 0.25f}}));
  EXPECT_EQ(p.indices, (std::vector<uint32_t>{0, 1, 2}));
}

// KHR_draco_mesh_compression: a primitive's indices and the attributes the extension names are
// decoded from its Draco data (here a quad of two triangles with texture coordinates, encoded
// by libdraco without quantization, so exactly), also where the file requires the extension;
// the triangles and each corner's coordinates come out as they went in, whatever order the
// encoder gave the points. Broken Draco data fails naming the primitive.
TEST_F(GltfLoaderTest, DracoCompressedPrimitivesAreDecoded) {
  const std::vector<glm::vec3> corners = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  const std::vector<glm::vec2> corner_uvs = {{0, 1}, {1, 1}, {1, 0}, {0, 0}};
  const int triangles[2][3] = {{0, 1, 2}, {0, 2, 3}};
  draco::TriangleSoupMeshBuilder builder;
  builder.Start(2);
  const int position =
      builder.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
  const int uv = builder.AddAttribute(draco::GeometryAttribute::TEX_COORD, 2, draco::DT_FLOAT32);
  for (uint32_t f = 0; f < 2; ++f) {
    const int* t = triangles[f];
    builder.SetAttributeValuesForFace(position, draco::FaceIndex(f), &corners[size_t(t[0])],
                                      &corners[size_t(t[1])], &corners[size_t(t[2])]);
    builder.SetAttributeValuesForFace(uv, draco::FaceIndex(f), &corner_uvs[size_t(t[0])],
                                      &corner_uvs[size_t(t[1])], &corner_uvs[size_t(t[2])]);
  }
  const std::unique_ptr<draco::Mesh> mesh = builder.Finalize();
  ASSERT_TRUE(mesh);
  draco::EncoderBuffer encoded;
  ASSERT_TRUE(draco::Encoder().EncodeMeshToBuffer(*mesh, &encoded).ok());
  const std::vector<uint8_t> bytes(encoded.data(), encoded.data() + encoded.size());
  // The accessors' counts are the points and triangles the data holds.
  draco::DecoderBuffer peek;
  peek.Init(encoded.data(), encoded.size());
  const size_t points = draco::Decoder().DecodeMeshFromBuffer(&peek).value()->num_points();

  GltfBuilder b;
  const int view = b.add_view(bytes);
  auto accessor = [&](int component, const char* type, size_t count) {
    b.doc()["accessors"].push_back(
        {{"componentType", component}, {"type", type}, {"count", count}});
    return int(b.doc()["accessors"].size()) - 1;
  };
  const int positions = accessor(5126, "VEC3", points);
  const int uvs = accessor(5126, "VEC2", points);
  const int indices = accessor(5123, "SCALAR", 6);
  b.doc()["meshes"] = json::array(
      {{{"primitives",
         json::array({{{"attributes", {{"POSITION", positions}, {"TEXCOORD_0", uvs}}},
                       {"indices", indices},
                       {"extensions",
                        {{"KHR_draco_mesh_compression",
                          {{"bufferView", view},
                           {"attributes",
                            {{"POSITION", mesh->attribute(position)->unique_id()},
                             {"TEXCOORD_0", mesh->attribute(uv)->unique_id()}}}}}}}}})}}});
  b.doc()["nodes"] = json::array({{{"mesh", 0}}});
  b.doc()["scenes"] = json::array({{{"nodes", {0}}}});
  b.doc()["extensionsUsed"] = {"KHR_draco_mesh_compression"};
  b.doc()["extensionsRequired"] = {"KHR_draco_mesh_compression"};
  b.write_embedded(dir_ / "draco.gltf");
  b.write_glb(dir_ / "draco.glb");
  for (const char* file : {"draco.gltf", "draco.glb"}) {
    SCOPED_TRACE(file);
    GltfLoadReport report;
    const Scene scene = load_gltf(dir_ / file, &report);
    EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
    const Primitive& p = scene.meshes.at(0).primitives.at(0);
    ASSERT_EQ(p.positions.size(), points);
    ASSERT_EQ(p.uvs.size(), points);
    ASSERT_EQ(p.indices.size(), 6u);
    // The triangles (each turned to start at its least corner, so that only the winding counts)
    // and each point's coordinates.
    using Triangle = std::array<glm::vec3, 3>;
    const auto less = [](const glm::vec3& a, const glm::vec3& c) {
      return std::lexicographical_compare(&a.x, &a.x + 3, &c.x, &c.x + 3);
    };
    const auto canonical = [&](Triangle t) {
      std::rotate(t.begin(), std::min_element(t.begin(), t.end(), less), t.end());
      return t;
    };
    const auto order = [&](const Triangle& a, const Triangle& c) {
      return std::lexicographical_compare(a.begin(), a.end(), c.begin(), c.end(), less);
    };
    std::vector<Triangle> got, want;
    for (size_t t = 0; t < 2; ++t) {
      Triangle g, w;
      for (size_t k = 0; k < 3; ++k) {
        g[k] = p.positions[p.indices[3 * t + k]];
        w[k] = corners[size_t(triangles[t][k])];
      }
      got.push_back(canonical(g));
      want.push_back(canonical(w));
    }
    std::sort(got.begin(), got.end(), order);
    std::sort(want.begin(), want.end(), order);
    EXPECT_EQ(got, want);
    for (size_t i = 0; i < points; ++i) {
      const size_t corner =
          size_t(std::find(corners.begin(), corners.end(), p.positions[i]) - corners.begin());
      ASSERT_LT(corner, corners.size()) << "point " << i;
      EXPECT_EQ(p.uvs[i], corner_uvs[corner]) << "point " << i;
    }
  }

  // The same file with its Draco data cut short.
  GltfBuilder cut = b;
  std::vector<uint8_t> half(bytes.begin(), bytes.begin() + bytes.size() / 2);
  cut.doc()["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]
           ["bufferView"] = cut.add_view(half);
  cut.write_embedded(dir_ / "cut.gltf");
  expect_error(dir_ / "cut.gltf", "mesh 0 primitive 0 KHR_draco_mesh_compression: cannot decode");

  // Draco data whose attribute is of a type no glTF component type matches (a bool, which
  // libdraco would read byte by byte whatever the byte: found by afr_fuzz_gltf).
  draco::TriangleSoupMeshBuilder flags;
  flags.Start(2);
  const int flag_position =
      flags.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
  const int flag = flags.AddAttribute(draco::GeometryAttribute::GENERIC, 1, draco::DT_BOOL);
  const bool on[3] = {true, false, true};
  for (uint32_t f = 0; f < 2; ++f) {
    const int* t = triangles[f];
    flags.SetAttributeValuesForFace(flag_position, draco::FaceIndex(f), &corners[size_t(t[0])],
                                    &corners[size_t(t[1])], &corners[size_t(t[2])]);
    flags.SetAttributeValuesForFace(flag, draco::FaceIndex(f), &on[0], &on[1], &on[2]);
  }
  const std::unique_ptr<draco::Mesh> flagged = flags.Finalize();
  ASSERT_TRUE(flagged);
  draco::EncoderBuffer flagged_encoded;
  ASSERT_TRUE(draco::Encoder().EncodeMeshToBuffer(*flagged, &flagged_encoded).ok());
  GltfBuilder typed = b;
  typed.doc()["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"] = {
      {"bufferView", typed.add_view(std::vector<uint8_t>(
                         flagged_encoded.data(), flagged_encoded.data() + flagged_encoded.size()))},
      {"attributes",
       {{"POSITION", flagged->attribute(flag_position)->unique_id()},
        {"TEXCOORD_0", flagged->attribute(flag)->unique_id()}}}};
  draco::DecoderBuffer flagged_peek;
  flagged_peek.Init(flagged_encoded.data(), flagged_encoded.size());
  const size_t flagged_points =
      draco::Decoder().DecodeMeshFromBuffer(&flagged_peek).value()->num_points();
  typed.doc()["accessors"][positions]["count"] = flagged_points;
  typed.doc()["accessors"][uvs]["count"] = flagged_points;
  typed.write_embedded(dir_ / "typed.gltf");
  expect_error(dir_ / "typed.gltf",
               "mesh 0 primitive 0 KHR_draco_mesh_compression: its attribute TEXCOORD_0 has Draco "
               "data type 11, which no glTF component type matches");
}

// EXT_ and KHR_meshopt_compression: buffer views compressed with meshoptimizer's encoders (the
// three modes, and the three filters afr's meshoptimizer decodes, under vertex data, indices and
// an animation) read as the data they stand for, whether the placeholder buffer has no uri
// (.gltf, .glb) or is a fallback whose file is missing (never read). Broken data, what the
// extension forbids and what afr cannot decode fail naming the buffer view.
TEST_F(GltfLoaderTest, MeshoptCompressedBufferViewsAreDecoded) {
  GltfBuilder b;
  size_t placeholder = 0;  // the bytes of buffer 1, which holds nothing
  // A buffer view over buffer 1 standing for `count` elements of `stride` bytes, `encoded` in
  // buffer 0; returns its index.
  const auto add = [&](const std::vector<uint8_t>& encoded, size_t count, size_t stride,
                       const char* mode, const char* filter, bool view_stride) {
    while (b.bin().size() % 4 != 0) b.bin().push_back(0);
    json ext = {{"buffer", 0},
                {"byteOffset", b.bin().size()},
                {"byteLength", encoded.size()},
                {"byteStride", stride},
                {"count", count},
                {"mode", mode}};
    if (filter != nullptr) ext["filter"] = filter;
    b.bin().insert(b.bin().end(), encoded.begin(), encoded.end());
    json view = {{"buffer", 1},
                 {"byteOffset", placeholder},
                 {"byteLength", count * stride},
                 {"extensions", {{"EXT_meshopt_compression", ext}}}};
    if (view_stride) view["byteStride"] = stride;
    placeholder += (count * stride + 3) / 4 * 4;
    b.doc()["bufferViews"].push_back(view);
    return int(b.doc()["bufferViews"].size()) - 1;
  };
  const auto attributes = [](const void* data, size_t count, size_t stride) {
    std::vector<uint8_t> out(meshopt_encodeVertexBufferBound(count, stride));
    out.resize(meshopt_encodeVertexBuffer(out.data(), out.size(), data, count, stride));
    return out;
  };
  const std::vector<float> positions = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  const int p =
      b.add_accessor(add(attributes(positions.data(), 4, 12), 4, 12, "ATTRIBUTES", nullptr, true),
                     kFloat, "VEC3", 4);
  // Normals as normalized bytes (KHR_mesh_quantization), octahedral.
  const std::vector<glm::vec3> normals = {{0, 0, 1}, {0.6f, 0, 0.8f}, {0, -0.6f, 0.8f}, {0, 0, 1}};
  std::vector<float> normal_in;
  for (const glm::vec3& v : normals) normal_in.insert(normal_in.end(), {v.x, v.y, v.z, 0.0f});
  std::vector<int8_t> octahedral(16);
  meshopt_encodeFilterOct(octahedral.data(), 4, 4, 8, normal_in.data());
  const int n = b.add_accessor(
      add(attributes(octahedral.data(), 4, 4), 4, 4, "ATTRIBUTES", "OCTAHEDRAL", true), kByte,
      "VEC3", 4, 0, /*normalized=*/true);
  // Mesh 0's indices as triangles, mesh 1's as a sequence.
  const std::vector<uint32_t> triangles = {0, 1, 2, 0, 2, 3};
  std::vector<uint8_t> encoded(meshopt_encodeIndexBufferBound(6, 4));
  encoded.resize(meshopt_encodeIndexBuffer(encoded.data(), encoded.size(), triangles.data(), 6));
  const int i0 =
      b.add_accessor(add(encoded, 6, 2, "TRIANGLES", nullptr, false), kUnsignedShort, "SCALAR", 6);
  encoded.assign(meshopt_encodeIndexSequenceBound(6, 4), 0);
  encoded.resize(meshopt_encodeIndexSequence(encoded.data(), encoded.size(), triangles.data(), 6));
  const int i1 =
      b.add_accessor(add(encoded, 6, 4, "INDICES", nullptr, false), kUnsignedInt, "SCALAR", 6);
  // An animation: key times through the exponential filter (24 bits of mantissa: exact), the
  // rotations as normalized shorts through the quaternion filter.
  const std::vector<float> times = {0.0f, 0.5f, 1.25f};
  std::vector<uint32_t> exponential(3);
  meshopt_encodeFilterExp(exponential.data(), 3, 4, 24, times.data());
  const int t = b.add_accessor(
      add(attributes(exponential.data(), 3, 4), 3, 4, "ATTRIBUTES", "EXPONENTIAL", false), kFloat,
      "SCALAR", 3);
  const float h = std::sqrt(0.5f);
  const std::vector<glm::vec4> rotations = {{0, 0, 0, 1}, {0, 0, h, h}, {0, 1, 0, 0}};
  std::vector<int16_t> quaternion(12);
  meshopt_encodeFilterQuat(quaternion.data(), 3, 8, 16, &rotations[0].x);
  const int r = b.add_accessor(
      add(attributes(quaternion.data(), 3, 8), 3, 8, "ATTRIBUTES", "QUATERNION", false), kShort,
      "VEC4", 3, 0, /*normalized=*/true);

  b.doc()["meshes"] = json::array(
      {{{"primitives",
         json::array({{{"attributes", {{"POSITION", p}, {"NORMAL", n}}}, {"indices", i0}}})}},
       {{"primitives", json::array({{{"attributes", {{"POSITION", p}}}, {"indices", i1}}})}}});
  b.doc()["nodes"] = json::array({{{"mesh", 0}}, {{"mesh", 1}}});
  b.doc()["scenes"] = json::array({{{"nodes", {0, 1}}}});
  b.doc()["animations"] = json::array(
      {{{"channels", {{{"sampler", 0}, {"target", {{"node", 1}, {"path", "rotation"}}}}}},
        {"samplers", {{{"input", t}, {"output", r}}}}}});
  b.doc()["extensionsUsed"] = {"EXT_meshopt_compression", "KHR_mesh_quantization"};
  b.doc()["extensionsRequired"] = {"EXT_meshopt_compression", "KHR_mesh_quantization"};
  b.more_buffers() = json::array({{{"byteLength", placeholder}}});
  b.write_embedded(dir_ / "meshopt.gltf");
  b.write_glb(dir_ / "meshopt.glb");
  GltfBuilder with_fallback = b;
  with_fallback.more_buffers()[0]["uri"] = "missing.bin";
  with_fallback.more_buffers()[0]["extensions"]["EXT_meshopt_compression"]["fallback"] = true;
  with_fallback.write_embedded(dir_ / "fallback.gltf");
  // The same under the KHR extension's name.
  const auto as_khr = [&](const fs::path& from, const fs::path& to) {
    std::ifstream in(from);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    for (size_t at; (at = text.find("EXT_meshopt_compression")) != std::string::npos;) {
      text.replace(at, 3, "KHR");
    }
    write_text(to, text);
  };
  as_khr(dir_ / "meshopt.gltf", dir_ / "khr.gltf");

  // A triangle turned to start at its least index (the codec may turn triangles).
  const auto canonical = [](const std::vector<uint32_t>& indices) {
    std::vector<uint32_t> out = indices;
    for (size_t k = 0; k + 3 <= out.size(); k += 3) {
      std::rotate(out.begin() + ptrdiff_t(k),
                  std::min_element(out.begin() + ptrdiff_t(k), out.begin() + ptrdiff_t(k + 3)),
                  out.begin() + ptrdiff_t(k + 3));
    }
    return out;
  };
  for (const char* file : {"meshopt.gltf", "meshopt.glb", "fallback.gltf", "khr.gltf"}) {
    SCOPED_TRACE(file);
    GltfLoadReport report;
    const Scene scene = load_gltf(dir_ / file, &report);
    EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
    ASSERT_EQ(scene.meshes.size(), 2u);
    const Primitive& a = scene.meshes[0].primitives.at(0);
    ASSERT_EQ(a.positions.size(), 4u);
    for (size_t v = 0; v < 4; ++v) {
      EXPECT_EQ(a.positions[v],
                glm::vec3(positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]))
          << "vertex " << v;
      ASSERT_EQ(a.normals.size(), 4u);
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(a.normals[v][c], normals[v][c], 0.02) << v;
    }
    EXPECT_EQ(canonical(a.indices), triangles);
    EXPECT_EQ(scene.meshes[1].primitives.at(0).indices, triangles);  // a sequence keeps its order
    ASSERT_EQ(scene.channels.size(), 1u);
    EXPECT_EQ(scene.channels[0].times, (std::vector<double>{0.0, 0.5, 1.25}));
    ASSERT_EQ(scene.channels[0].values.size(), 3u);
    for (size_t k = 0; k < 3; ++k) {
      for (int c = 0; c < 4; ++c) {
        EXPECT_NEAR(scene.channels[0].values[k][c], rotations[k][c], 1e-4) << "key " << k;
      }
    }
  }

  // What fails, each naming the buffer view.
  const auto broken = [&](const char* name, const std::function<void(GltfBuilder*)>& change,
                          const std::string& problem, bool khr = false) {
    SCOPED_TRACE(name);
    GltfBuilder c = b;
    change(&c);
    const fs::path path = dir_ / (std::string(name) + ".gltf");
    c.write_embedded(path);
    if (khr) as_khr(path, path);
    expect_error(path, problem);
  };
  const auto ext = [](GltfBuilder* c, int view) -> json& {
    return c->doc()["bufferViews"][size_t(view)]["extensions"]["EXT_meshopt_compression"];
  };
  broken(
      "cut", [&](GltfBuilder* c) { ext(c, 0)["byteLength"] = 10; },
      "buffer view 0 EXT_meshopt_compression: cannot decode its ATTRIBUTES data");
  broken(
      "length", [&](GltfBuilder* c) { c->doc()["bufferViews"][0]["byteLength"] = 40; },
      "buffer view 0 EXT_meshopt_compression: count x byteStride is 4 x 12 = 48 bytes, but the "
      "buffer view's byteLength is 40");
  broken(
      "filter", [&](GltfBuilder* c) { ext(c, 0)["filter"] = "QUATERNION"; },
      "buffer view 0 EXT_meshopt_compression: the QUATERNION filter does not take a byteStride "
      "of 12");
  broken(
      "mode", [&](GltfBuilder* c) { ext(c, 2)["mode"] = "STRIPS"; },
      "buffer view 2 EXT_meshopt_compression has mode \"STRIPS\"");
  broken(
      "source", [&](GltfBuilder* c) { ext(c, 0)["buffer"] = 1; },
      "buffer view 0 EXT_meshopt_compression reads its compressed data from buffer 1, which "
      "holds no data");
  broken(
      "plain",
      [&](GltfBuilder* c) {
        c->doc()["bufferViews"][0].erase("extensions");
        c->doc()["bufferViews"][0].erase("byteStride");
      },
      "buffer view 0 (accessor 0 (mesh 0 primitive 0 POSITION)) is not compressed but reads "
      "buffer 1, which holds no data");
  broken(
      "version1", [&](GltfBuilder* c) { c->bin()[ext(c, 0)["byteOffset"].get<size_t>()] = 0xa1; },
      "buffer view 0 KHR_meshopt_compression uses version 1 of the attribute codec, which afr's "
      "meshoptimizer",
      /*khr=*/true);
  broken(
      "color", [&](GltfBuilder* c) { ext(c, 1)["filter"] = "COLOR"; },
      "buffer view 1 KHR_meshopt_compression uses the COLOR filter, which afr's meshoptimizer",
      /*khr=*/true);
}

TEST_F(GltfLoaderTest, AccessorOutOfBoundsOfItsBufferViewFails) {
  GltfBuilder b;
  const int positions = add_quad(&b);
  b.doc()["accessors"][positions]["count"] = 5;
  const fs::path path = dir_ / "overrun.gltf";
  b.write_embedded(path);
  expect_error(path, "out of bounds");
}

TEST_F(GltfLoaderTest, BufferViewOutOfBoundsOfItsBufferFails) {
  GltfBuilder b;
  add_quad(&b);
  b.doc()["bufferViews"][1]["byteLength"] = 400;
  const fs::path path = dir_ / "long_view.gltf";
  b.write_embedded(path);
  expect_error(path, "out of bounds");
}

}  // namespace
}  // namespace afr
