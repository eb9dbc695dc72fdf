// Skins and morph targets (issue 18), from glTF files made here through the loader to
// Scene::deform: vertex positions and normals at times between keys against the closed forms
// of tests/support/deforming_content.h, weights channels in each interpolation, what moves
// and what only deforms, bounds and the default camera over a deforming animation, and a clear
// error for each way a file can get skins or morph targets wrong.
#include <afr/common/error.h>
#include <afr/common/gltf_loader.h>
#include <afr/common/image.h>

#include "support/png.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "support/deforming_content.h"
#include "support/gltf_content.h"

namespace afr {
namespace {

using json = nlohmann::json;
using testing::GltfContent;
using testing::MorphedQuad;
using testing::SkinnedStrip;
using testing::TempFolder;

Scene load(const GltfContent& g, const TempFolder& dir, GltfLoadReport* report = nullptr) {
  g.write(dir / "scene.gltf");
  return load_gltf(dir / "scene.gltf", report);
}

// Positions and normals of primitive 0 of node `node` at time t.
struct Deformed {
  std::vector<glm::vec3> positions, normals;
};
Deformed deform_at(const Scene& scene, int node, double t) {
  const size_t count =
      scene.meshes[size_t(scene.nodes[size_t(node)].mesh)].primitives[0].positions.size();
  Deformed d;
  d.positions.resize(count);
  d.normals.resize(count);
  scene.deform(node, 0, scene.evaluate(t), d.positions.data(), d.normals.data());
  return d;
}

void expect_near(const glm::vec3& got, const glm::dvec3& want, double tolerance,
                 const std::string& what) {
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], want[c], tolerance) << what << ", axis " << c;
}

// ---- Skins ----

TEST(DeformationTest, SkinnedVerticesFollowTheirJointsAndIgnoreTheMeshNode) {
  TempFolder dir;
  GltfLoadReport report;
  const Scene scene = load(SkinnedStrip::make(), dir, &report);
  EXPECT_TRUE(report.warnings.empty());
  ASSERT_EQ(scene.skins.size(), 1u);
  EXPECT_EQ(scene.skins[0].joints, (std::vector<int>{1, 2}));
  const std::vector<glm::vec3> bind = SkinnedStrip::bind_positions();
  for (double t : {0.0, 0.25, 0.5, 1.0, 1.3, 2.0, 3.0}) {
    const Deformed d = deform_at(scene, SkinnedStrip::kMeshNode, t);
    for (size_t v = 0; v < bind.size(); ++v) {
      const std::string what = "t = " + std::to_string(t) + ", vertex " + std::to_string(v);
      expect_near(d.positions[v], SkinnedStrip::position(bind[v], t), 1e-5, what);
      // The normal: +Z under the linear part of the blended joint matrix, by its inverse
      // transpose (glm::inverse here; the loader's code takes cofactors).
      const double w1 = SkinnedStrip::arm_weight(bind[v]);
      const double a = SkinnedStrip::angle(t);
      const glm::dmat3 turn(glm::dvec3(1, 0, 0), glm::dvec3(0, std::cos(a), std::sin(a)),
                            glm::dvec3(0, -std::sin(a), std::cos(a)));
      const glm::dmat3 blend = (1.0 - w1) * glm::dmat3(1.0) + w1 * turn;
      if (std::abs(glm::determinant(blend)) < 1e-6) {
        // Half way between two joints turned apart by 180 degrees the blend is flat: no
        // normal. The deformation says so with a zero normal.
        EXPECT_EQ(d.normals[v], glm::vec3(0.0f)) << what;
        continue;
      }
      const glm::dvec3 n =
          glm::normalize(glm::transpose(glm::inverse(blend)) * glm::dvec3(0.0, 0.0, 1.0));
      expect_near(d.normals[v], n, 1e-5, what + " normal");
    }
  }
}

TEST(DeformationTest, AtTheBindPoseASkinIsTheMeshAsWritten) {
  // At 0 s the joints are where the inverse bind matrices undo them: every vertex is where
  // the file puts it, and the mesh node's translation of (5, 0, 0) is not applied.
  TempFolder dir;
  const Scene scene = load(SkinnedStrip::make(), dir);
  const Deformed d = deform_at(scene, SkinnedStrip::kMeshNode, 0.0);
  const std::vector<glm::vec3> bind = SkinnedStrip::bind_positions();
  for (size_t v = 0; v < bind.size(); ++v) {
    expect_near(d.positions[v], glm::dvec3(bind[v]), 1e-6, "vertex " + std::to_string(v));
  }
}

TEST(DeformationTest, WithoutInverseBindMatricesEachIsTheIdentity) {
  // Joints at the origin with identity inverse bind matrices: a vertex goes where its joints'
  // world transforms take its mesh position.
  TempFolder dir;
  GltfContent g = SkinnedStrip::make(false);
  g.doc()["skins"][0].erase("inverseBindMatrices");
  g.doc()["nodes"][1]["translation"] = {0.0, 0.0, 3.0};
  g.doc()["nodes"][2]["translation"] = {0.0, 0.0, 0.0};
  GltfLoadReport report;
  const Scene scene = load(g, dir, &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();  // glTF makes them optional
  const Deformed d = deform_at(scene, SkinnedStrip::kMeshNode, 0.0);
  const std::vector<glm::vec3> bind = SkinnedStrip::bind_positions();
  for (size_t v = 0; v < bind.size(); ++v) {
    expect_near(d.positions[v], glm::dvec3(bind[v]) + glm::dvec3(0, 0, 3), 1e-6,
                "vertex " + std::to_string(v));
  }
}

TEST(DeformationTest, QuantizedWeightsAreRenormalisedAndZeroWeightsFollowTheFirstJoint) {
  // WEIGHTS_0 as normalized unsigned bytes: 100 and 100 (not 127.5 and 127.5) mean half
  // each; a vertex of weights 0 follows the joint of its first slot, with one warning.
  TempFolder dir;
  GltfContent g = SkinnedStrip::make();
  std::vector<uint8_t> weights;
  for (int v = 0; v < 10; ++v) {
    if (v == 9) {
      weights.insert(weights.end(), {0, 0, 0, 0});
    } else {
      weights.insert(weights.end(), {100, 100, 0, 0});
    }
  }
  g.doc()["meshes"][0]["primitives"][0]["attributes"]["WEIGHTS_0"] =
      g.add_accessor(weights, 5121, "VEC4", 10, true);
  GltfLoadReport report;
  const Scene scene = load(g, dir, &report);
  const Primitive& p = scene.meshes[0].primitives[0];
  for (int v = 0; v < 9; ++v) {
    EXPECT_FLOAT_EQ(p.joint_weights[size_t(v)].x, 0.5f);
    EXPECT_FLOAT_EQ(p.joint_weights[size_t(v)].y, 0.5f);
  }
  EXPECT_EQ(p.joint_weights[9], glm::vec4(1.0f, 0.0f, 0.0f, 0.0f));
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find("sum to 0"), std::string::npos) << report.warnings[0];
  // Vertex 9 lists joint 1 first: at 1 s it is turned a quarter about (1, 1, 0) along X and
  // lifted by 1: (1.5, 2, 0) -> (1.5, 1, 1) + (0, 0, 1).
  const Deformed d = deform_at(scene, SkinnedStrip::kMeshNode, 1.0);
  expect_near(d.positions[9], glm::dvec3(1.5, 1.0, 2.0), 1e-5, "vertex 9");
}

TEST(DeformationTest, MoreThanFourInfluencesWarnAndTheFirstFourAreUsed) {
  TempFolder dir;
  GltfContent g = SkinnedStrip::make();
  json& attributes = g.doc()["meshes"][0]["primitives"][0]["attributes"];
  attributes["JOINTS_1"] = attributes["JOINTS_0"];
  attributes["WEIGHTS_1"] = attributes["WEIGHTS_0"];
  GltfLoadReport report;
  const Scene scene = load(g, dir, &report);
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find("JOINTS_1"), std::string::npos) << report.warnings[0];
  const Deformed d = deform_at(scene, SkinnedStrip::kMeshNode, 0.5);
  const std::vector<glm::vec3> bind = SkinnedStrip::bind_positions();
  for (size_t v = 0; v < bind.size(); ++v) {
    expect_near(d.positions[v], SkinnedStrip::position(bind[v], 0.5), 1e-5,
                "vertex " + std::to_string(v));
  }
}

TEST(DeformationTest, JointsOfMeshesNoSkinShowsAreNotKept) {
  // A mesh with JOINTS_0 and WEIGHTS_0 on a node without a skin is an ordinary mesh.
  TempFolder dir;
  GltfContent g = SkinnedStrip::make(false);
  g.doc()["nodes"][0].erase("skin");
  const Scene scene = load(g, dir);
  EXPECT_TRUE(scene.meshes[0].primitives[0].joints.empty());
  EXPECT_TRUE(scene.meshes[0].primitives[0].joint_weights.empty());
  EXPECT_FALSE(scene.node_deforms(SkinnedStrip::kMeshNode));
}

// ---- Morph targets ----

class MorphChannelTest : public ::testing::TestWithParam<Interpolation> {};

TEST_P(MorphChannelTest, PositionsAndNormalsFollowTheWeightsBetweenKeys) {
  const Interpolation interpolation = GetParam();
  TempFolder dir;
  const Scene scene = load(MorphedQuad::make(interpolation), dir);
  ASSERT_EQ(scene.channels.size(), 1u);
  EXPECT_EQ(scene.channels[0].path, AnimatedPath::kWeights);
  EXPECT_EQ(scene.channels[0].weight_count, 2u);
  const std::vector<glm::vec3> base = MorphedQuad::base_positions();
  for (double t : {-1.0, 0.0, 0.3, 0.5, 0.99, 1.0, 1.7, 2.5, 3.0, 4.0}) {
    const glm::dvec2 w = MorphedQuad::weights(interpolation, t);
    const SceneState state = scene.evaluate(t);
    const std::span<const float> got = scene.morph_weights(state, MorphedQuad::kMeshNode);
    ASSERT_EQ(got.size(), 2u);
    EXPECT_NEAR(got[0], w.x, 1e-6) << "t = " << t;
    EXPECT_NEAR(got[1], w.y, 1e-6) << "t = " << t;
    const Deformed d = deform_at(scene, MorphedQuad::kMeshNode, t);
    for (size_t v = 0; v < base.size(); ++v) {
      const std::string what = "t = " + std::to_string(t) + ", vertex " + std::to_string(v);
      expect_near(d.positions[v], MorphedQuad::position(base[v], w), 1e-5, what);
      expect_near(d.normals[v], MorphedQuad::normal(w), 1e-5, what + " normal");
    }
  }
}

INSTANTIATE_TEST_SUITE_P(EachInterpolation, MorphChannelTest,
                         ::testing::Values(Interpolation::kStep, Interpolation::kLinear,
                                           Interpolation::kCubicSpline),
                         [](const ::testing::TestParamInfo<Interpolation>& info) {
                           return std::string(to_string(info.param));
                         });

TEST(DeformationTest, GeneratedNormalsOfAMorphedShapeComeFromItsOwnPositions) {
  // Without NORMAL the loader makes normals of the flat quad (+Z); the lifted quad's are
  // those of the plane z = w0 (1 + x).
  TempFolder dir;
  const Scene scene = load(MorphedQuad::make(Interpolation::kLinear, false), dir);
  for (double t : {0.0, 0.5, 2.0}) {
    const Deformed d = deform_at(scene, MorphedQuad::kMeshNode, t);
    const glm::dvec3 n = MorphedQuad::normal(MorphedQuad::weights(Interpolation::kLinear, t));
    for (size_t v = 0; v < d.normals.size(); ++v) {
      expect_near(d.normals[v], n, 1e-5,
                  "t = " + std::to_string(t) + ", vertex " + std::to_string(v));
    }
  }
}

TEST(DeformationTest, NodeWeightsOverrideTheMeshWeights) {
  TempFolder dir;
  GltfContent g = MorphedQuad::make(Interpolation::kLinear);
  g.doc().erase("animations");
  const Scene mesh_weights = load(g, dir);
  g.doc()["nodes"][0]["weights"] = {0.5, 1.0};
  const Scene node_weights = load(g, dir);
  const std::vector<glm::vec3> base = MorphedQuad::base_positions();
  const Deformed a = deform_at(mesh_weights, 0, 0.0);
  const Deformed b = deform_at(node_weights, 0, 0.0);
  for (size_t v = 0; v < base.size(); ++v) {
    expect_near(a.positions[v], MorphedQuad::position(base[v], {0.25, 0.25}), 1e-6, "mesh");
    expect_near(b.positions[v], MorphedQuad::position(base[v], {0.5, 1.0}), 1e-6, "node");
  }
  // Deformed, but never moving: no velocities needed.
  EXPECT_TRUE(node_weights.node_deforms(0));
  EXPECT_FALSE(node_weights.node_geometry_moves(0));
  EXPECT_FALSE(node_weights.has_moving_geometry());
}

// ---- What moves ----

TEST(DeformationTest, DeformingMeshesAreMovingGeometryAndStaticPosesAreNot) {
  TempFolder dir;
  const Scene skinned = load(SkinnedStrip::make(), dir);
  EXPECT_TRUE(skinned.node_deforms(0));
  EXPECT_TRUE(skinned.node_geometry_moves(0));
  EXPECT_TRUE(skinned.has_moving_geometry());
  EXPECT_FALSE(skinned.node_moves(0));  // its own transform is not animated

  const Scene posed = load(SkinnedStrip::make(false), dir);
  EXPECT_TRUE(posed.node_deforms(0));
  EXPECT_FALSE(posed.node_geometry_moves(0));
  EXPECT_FALSE(posed.has_moving_geometry());

  // A skinned mesh whose own node moves but whose joints do not stays still (glTF ignores the
  // node's transform).
  GltfContent g = SkinnedStrip::make(false);
  g.animate_translation(0, {0.0f, 1.0f}, {0, 0, 0, 3, 0, 0});
  const Scene moved_node = load(g, dir);
  EXPECT_TRUE(moved_node.node_moves(0));
  EXPECT_FALSE(moved_node.node_geometry_moves(0));
  EXPECT_FALSE(moved_node.has_moving_geometry());

  const Scene morphed = load(MorphedQuad::make(Interpolation::kStep), dir);
  EXPECT_TRUE(morphed.has_moving_geometry());
  EXPECT_FALSE(morphed.node_moves(0));
  EXPECT_DOUBLE_EQ(morphed.duration(), 3.0);
}

TEST(DeformationTest, BoundsAndTheDefaultCameraCoverTheDeformedGeometry) {
  TempFolder dir;
  const Scene scene = load(SkinnedStrip::make(), dir);
  const std::vector<glm::vec3> bind = SkinnedStrip::bind_positions();
  const Camera camera = scene.camera_at(scene.evaluate(0.0));
  for (double t : {0.0, 1.0, 2.0}) {
    glm::dvec3 lo, hi;
    scene.bounds(scene.evaluate(t), &lo, &hi);
    glm::dvec3 want_lo(1e9), want_hi(-1e9);
    for (const glm::vec3& b : bind) {
      const glm::dvec3 p = SkinnedStrip::position(b, t);
      want_lo = glm::min(want_lo, p);
      want_hi = glm::max(want_hi, p);
      // At every key time, every vertex is in the default camera's view.
      glm::dvec2 pixel;
      ASSERT_TRUE(camera.project(p, 100, 100, &pixel, nullptr)) << "t = " << t;
      EXPECT_GE(pixel.x, 0.0);
      EXPECT_LE(pixel.x, 100.0);
      EXPECT_GE(pixel.y, 0.0);
      EXPECT_LE(pixel.y, 100.0);
    }
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(lo[c], want_lo[c], 1e-5) << "t = " << t;
      EXPECT_NEAR(hi[c], want_hi[c], 1e-5) << "t = " << t;
    }
  }
}

// ---- Errors ----

void expect_load_error(const GltfContent& g, const std::string& part) {
  TempFolder dir;
  g.write(dir / "bad.gltf");
  try {
    load_gltf(dir / "bad.gltf");
    ADD_FAILURE() << "loaded; expected an error containing '" << part << "'";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(part), std::string::npos) << message;
    EXPECT_NE(message.find("bad.gltf"), std::string::npos) << message;
  }
}

TEST(DeformationTest, BadSkinsAreErrorsNamingTheProblem) {
  {
    GltfContent g = SkinnedStrip::make();
    std::vector<uint8_t> joints(40, 0);
    joints[4 * 3 + 1] = 2;  // vertex 3 names joint 2 of 2
    g.doc()["meshes"][0]["primitives"][0]["attributes"]["JOINTS_0"] =
        g.add_accessor(joints, 5121, "VEC4", 10);
    expect_load_error(g, "vertex 3 of primitive 0 of mesh 0 names joint 2, but skin 0 has 2");
  }
  {  // tinygltf refuses it without a reason; the loader finds the property missing
    GltfContent g = SkinnedStrip::make();
    g.doc()["skins"][0].erase("joints");
    expect_load_error(g, "invalid glTF: skin 0 has no \"joints\", which glTF requires");
  }
  {
    GltfContent g = SkinnedStrip::make();
    g.doc()["meshes"][0]["primitives"][0]["attributes"]["JOINTS_0"] =
        g.add_accessor(std::vector<float>(40, 0.0f), 5126, "VEC4", 10);
    expect_load_error(g, "not unsigned bytes or shorts as joints must be");
  }
  {
    GltfContent g = SkinnedStrip::make();
    g.doc()["meshes"][0]["primitives"][0]["attributes"]["WEIGHTS_0"] =
        g.add_accessor(std::vector<float>(36, 0.25f), 5126, "VEC4", 9);
    expect_load_error(g, "9 WEIGHTS_0 values for 10 positions");
  }
  {
    GltfContent g = SkinnedStrip::make();
    g.doc()["meshes"][0]["primitives"][0]["attributes"]["WEIGHTS_0"] =
        g.add_accessor(std::vector<uint16_t>(40, 1), 5123, "VEC4", 10);
    expect_load_error(g, "weights are floats or normalized unsigned bytes or shorts");
  }
  {
    GltfContent g = SkinnedStrip::make();
    g.doc()["meshes"][0]["primitives"][0]["attributes"].erase("WEIGHTS_0");
    expect_load_error(g, "has JOINTS_0 but no WEIGHTS_0");
  }
  {
    GltfContent g = SkinnedStrip::make();
    g.doc()["skins"][0]["joints"] = {1, 2, 7};
    expect_load_error(g, "skin 0 has joint node 7, but there are 3 nodes");
  }
  {
    GltfContent g = SkinnedStrip::make();
    g.doc()["skins"][0]["joints"] = {1, 2, 0};
    expect_load_error(g, "skin 0 has 2 inverse bind matrices for 3 joints");
  }
  {
    GltfContent g = SkinnedStrip::make();
    g.doc()["nodes"][0]["skin"] = 1;
    expect_load_error(g, "node 0 refers to skin 1, but there are 1");
  }
  {
    GltfContent g = SkinnedStrip::make();
    g.doc()["nodes"][1]["skin"] = 0;
    expect_load_error(g, "node 1 has skin 0 but no mesh");
  }
  {
    // A skinned node whose mesh has no joints.
    GltfContent g = SkinnedStrip::make();
    g.doc()["meshes"][0]["primitives"][0]["attributes"].erase("JOINTS_0");
    g.doc()["meshes"][0]["primitives"][0]["attributes"].erase("WEIGHTS_0");
    expect_load_error(g, "primitive 0 of its mesh 0 has no joints");
  }
}

TEST(DeformationTest, AFileCannotAskForAnEndlessDeformation) {
  // One skinned mesh of 2^21 vertices (accessors without buffer views: all zeros, a few bytes
  // of JSON) shown by 9 nodes: 9 x 2^21 vertex updates at every time, beyond the 2^24 afr
  // accepts. With 7 nodes it loads.
  auto file = [](int nodes) {
    GltfContent g;
    const size_t count = size_t(1) << 21;
    auto& accessors = g.doc()["accessors"];
    accessors.push_back({{"componentType", 5126}, {"type", "VEC3"}, {"count", count}});
    accessors.push_back({{"componentType", 5121}, {"type", "VEC4"}, {"count", count}});
    accessors.push_back({{"componentType", 5126}, {"type", "VEC4"}, {"count", count}});
    const json primitive = {{"attributes", {{"POSITION", 0}, {"JOINTS_0", 1}, {"WEIGHTS_0", 2}}},
                            {"indices", g.add_indices({0, 1, 2})}};
    g.doc()["meshes"].push_back({{"primitives", json::array({primitive})}});
    g.doc()["skins"] = json::array({{{"joints", {0}}}});
    std::vector<int> roots = {g.add_node(json::object())};
    for (int k = 0; k < nodes; ++k) roots.push_back(g.add_node({{"mesh", 0}, {"skin", 0}}));
    g.set_roots(roots);
    return g;
  };
  expect_load_error(file(9), "more than afr accepts (16777216)");
  TempFolder dir;
  EXPECT_TRUE(load(file(7), dir).node_deforms(1));
}

// Tangents deform with their primitive (a normal texture's frame, docs/scene-model.md "Normal
// textures"): the targets' TANGENT displacements are added times their weights, then the node's
// linear part moves x, y, z, and a mirroring one turns w. Without a normal texture neither the
// tangents nor their displacements are kept, and nothing warns.
TEST(DeformationTest, TangentsDeformWithTheirPrimitive) {
  TempFolder dir;
  testing::write_png(DecodedImage{1, 1, 3, {128, 128, 255}}, dir / "flat.png");
  GltfContent g;
  g.doc()["images"] = json::array({{{"uri", "flat.png"}}});
  g.doc()["textures"] = json::array({{{"source", 0}}});
  g.doc()["materials"] = json::array({{{"normalTexture", {{"index", 0}}}}});
  const int mesh = g.add_mesh({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, {0, 1, 2, 0, 2, 3}, 0,
                              {0, 1, 1, 1, 1, 0, 0, 0});
  json& primitive = g.doc()["meshes"][mesh]["primitives"][0];
  primitive["attributes"]["TANGENT"] =
      g.add_floats({1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1}, 4);
  primitive["targets"] =
      json::array({{{"POSITION", g.add_floats(std::vector<float>(12, 0.0f), 3)},
                    {"TANGENT", g.add_floats({-1, 1, 0, -1, 1, 0, -1, 1, 0, -1, 1, 0}, 3)}}});
  g.doc()["meshes"][mesh]["weights"] = {0.5};
  // Mirrored in x, then turned a quarter round z: +x goes to -x, then to -y; +y to -x.
  g.set_roots({g.add_node({{"mesh", mesh},
                           {"scale", {-1.0, 1.0, 1.0}},
                           {"rotation", {0.0, 0.0, std::sqrt(0.5), std::sqrt(0.5)}}})});
  GltfLoadReport report;
  const Scene scene = load(g, dir, &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  const Primitive& p = scene.meshes[0].primitives[0];
  ASSERT_EQ(p.targets.size(), 1u);
  ASSERT_EQ(p.targets[0].tangents.size(), 4u);
  std::vector<glm::vec3> positions(4), normals(4);
  std::vector<glm::vec4> tangents(4);
  scene.deform(0, 0, scene.evaluate(0.0), positions.data(), normals.data(), tangents.data());
  // (1, 0, 0) + 0.5 (-1, 1, 0) = (0.5, 0.5, 0); mirrored (-0.5, 0.5, 0); turned (-0.5, -0.5, 0).
  for (const glm::vec4& t : tangents) {
    expect_near(glm::vec3(t), glm::dvec3(-0.5, -0.5, 0.0), 1e-6, "tangent");
    EXPECT_EQ(t.w, -1.0f);
  }
  // A null output, or a primitive without tangents, leaves the rest as it was.
  scene.deform(0, 0, scene.evaluate(0.0), positions.data(), normals.data(), nullptr);

  g.doc()["materials"] = json::array({json::object()});
  const Scene plain = load(g, dir, &report);
  EXPECT_TRUE(plain.meshes[0].primitives[0].tangents.empty());
  EXPECT_TRUE(plain.meshes[0].primitives[0].targets[0].tangents.empty());
  tangents.assign(4, glm::vec4(7.0f));
  plain.deform(0, 0, plain.evaluate(0.0), positions.data(), normals.data(), tangents.data());
  EXPECT_EQ(tangents[0], glm::vec4(7.0f));
}

TEST(DeformationTest, BadMorphTargetsAreErrorsNamingTheProblem) {
  {
    GltfContent g = MorphedQuad::make(Interpolation::kLinear);
    g.doc()["meshes"][0]["weights"] = {0.5, 0.5, 0.5};
    expect_load_error(g, "mesh 0 has 3 morph weights for 2 morph targets");
  }
  {
    GltfContent g = MorphedQuad::make(Interpolation::kLinear);
    g.doc()["nodes"][0]["weights"] = {0.5};
    expect_load_error(g, "node 0 has 1 morph weights, but its mesh has 2 morph targets");
  }
  {
    GltfContent g = MorphedQuad::make(Interpolation::kLinear);
    g.doc()["meshes"][0]["primitives"][0]["targets"][1]["POSITION"] =
        g.add_floats({0, 0, 0, 0, 0, 0, 0, 0, 0}, 3);
    expect_load_error(g, "morph target 1 has 3 POSITION values for 4 positions");
  }
  {
    // The channel's output has 2 weights per key, but the mesh has 3 targets.
    GltfContent g = MorphedQuad::make(Interpolation::kLinear);
    json& targets = g.doc()["meshes"][0]["primitives"][0]["targets"];
    targets.push_back(targets[1]);
    g.doc()["meshes"][0]["weights"] = {0.0, 0.0, 0.0};
    expect_load_error(g, "3 keyframe times and 6 weights (3 per key expected: 3 morph targets)");
  }
  {
    GltfContent g = MorphedQuad::make(Interpolation::kCubicSpline);
    g.doc()["animations"][0]["samplers"][0]["output"] = g.add_floats(std::vector<float>(6), 1);
    expect_load_error(g,
                      "(6 per key expected: 2 morph targets times in-tangent, value, "
                      "out-tangent)");
  }
  {
    // Weights animated on a mesh without targets.
    GltfContent g = SkinnedStrip::make(false);
    const int input = g.add_floats({0.0f, 1.0f}, 1);
    const int output = g.add_floats({0.0f, 1.0f}, 1);
    g.doc()["animations"] = json::array(
        {{{"channels", {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "weights"}}}}}},
          {"samplers", {{{"input", input}, {"output", output}}}}}});
    expect_load_error(g,
                      "animates the morph weights of node 0, which has a mesh without morph "
                      "targets");
  }
  {
    GltfContent g = MorphedQuad::make(Interpolation::kLinear);
    json primitive = g.doc()["meshes"][0]["primitives"][0];
    primitive.erase("targets");
    g.doc()["meshes"][0]["primitives"].push_back(primitive);
    expect_load_error(g, "mesh 0 primitive 1 has 0 morph targets, but primitive 0 has 2");
  }
}

}  // namespace
}  // namespace afr
