// Small glTF files with deforming meshes, made by the tests, and the positions their vertices
// must take, written out in closed form from the files' own numbers (not through afr's
// deformation code): a strip skinned to two joints, one bending about X, and a quad with two
// morph targets driven by a weights channel in each interpolation. For the loader's, the
// scene's and the tracer's tests.
#pragma once

#include <afr/common/animation.h>
#include <afr/common/math.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "support/gltf_content.h"

namespace afr::testing {

// ---- The skinned strip ----
//
// Ten vertices in rows y = 0, 0.5, 1, 1.5, 2 at x = 0.5 and 1.5 (z = 0), normals +Z. Joint 0
// (node 1) is the root, at (1, 0, 0) in the bind pose, and slides along +Z: translation
// (1, 0, t) for t in [0, 2]. Joint 1 (node 2), its child at (0, 1, 0), turns about X by
// 90 degrees a second (LINEAR, keys at 0, 1 and 2 s). A vertex at height y takes joint 1 with
// weight clamp(y - 0.5, 0, 1) and joint 0 with the rest. The mesh node (node 0) has a
// translation of (5, 0, 0), which glTF says a skinned mesh ignores.
struct SkinnedStrip {
  using json = GltfContent::json;
  static constexpr int kMeshNode = 0;
  static constexpr double kEnd = 2.0;  // seconds

  static std::vector<glm::vec3> bind_positions() {
    std::vector<glm::vec3> p;
    for (int row = 0; row < 5; ++row) {
      for (float x : {0.5f, 1.5f}) p.push_back({x, 0.5f * float(row), 0.0f});
    }
    return p;
  }
  static double arm_weight(const glm::vec3& bind) {
    return std::clamp(double(bind.y) - 0.5, 0.0, 1.0);
  }
  static double angle(double t) { return std::clamp(t, 0.0, kEnd) * M_PI / 2.0; }
  static double slide(double t) { return std::clamp(t, 0.0, kEnd); }

  // Where a vertex of the bind pose is at time t: joint 0 moves it by (0, 0, slide), joint 1
  // also turns it about the line through (1, 1, 0) along X.
  static glm::dvec3 position(const glm::vec3& bind, double t) {
    const glm::dvec3 p(bind);
    const glm::dvec3 lift(0.0, 0.0, slide(t));
    const glm::dvec3 c(1.0, 1.0, 0.0);
    const double a = angle(t);
    const glm::dvec3 d = p - c;
    const glm::dvec3 turned(d.x, d.y * std::cos(a) - d.z * std::sin(a),
                            d.y * std::sin(a) + d.z * std::cos(a));
    const double w1 = arm_weight(bind);
    return (1.0 - w1) * (p + lift) + w1 * (c + lift + turned);
  }

  // The glTF file: joints as unsigned bytes, weights as floats. Vertices of odd index list
  // their joints in the other order (slot 0 = joint 1), which must not matter.
  static GltfContent make(bool animated = true) {
    GltfContent g;
    const std::vector<glm::vec3> bind = bind_positions();
    std::vector<float> positions, normals;
    std::vector<uint8_t> joints;
    std::vector<float> weights;
    for (size_t v = 0; v < bind.size(); ++v) {
      positions.insert(positions.end(), {bind[v].x, bind[v].y, bind[v].z});
      normals.insert(normals.end(), {0.0f, 0.0f, 1.0f});
      const float w1 = float(arm_weight(bind[v]));
      if (v % 2 == 0) {
        joints.insert(joints.end(), {0, 1, 0, 0});
        weights.insert(weights.end(), {1.0f - w1, w1, 0.0f, 0.0f});
      } else {
        joints.insert(joints.end(), {1, 0, 0, 0});
        weights.insert(weights.end(), {w1, 1.0f - w1, 0.0f, 0.0f});
      }
    }
    std::vector<uint16_t> indices;
    for (uint16_t row = 0; row < 4; ++row) {
      const uint16_t a = uint16_t(2 * row);
      // Counter-clockwise seen from +Z.
      indices.insert(indices.end(),
                     {a, uint16_t(a + 1), uint16_t(a + 3), a, uint16_t(a + 3), uint16_t(a + 2)});
    }
    const json primitive = {{"attributes",
                             {{"POSITION", g.add_floats(positions, 3)},
                              {"NORMAL", g.add_floats(normals, 3)},
                              {"JOINTS_0", g.add_accessor(joints, 5121, "VEC4", bind.size())},
                              {"WEIGHTS_0", g.add_accessor(weights, 5126, "VEC4", bind.size())}}},
                            {"indices", g.add_indices(indices)}};
    g.doc()["meshes"].push_back({{"primitives", json::array({primitive})}});
    // Inverse bind matrices: the inverses of the joints' bind-pose world transforms,
    // translations by (-1, 0, 0) and (-1, -1, 0), column-major.
    const std::vector<float> ibm = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, -1, 0,  0, 1,
                                    1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, -1, -1, 0, 1};
    g.doc()["skins"] = json::array(
        {{{"joints", {1, 2}}, {"inverseBindMatrices", g.add_accessor(ibm, 5126, "MAT4", 2)}}});
    g.add_node({{"mesh", 0}, {"skin", 0}, {"translation", {5.0, 0.0, 0.0}}});
    g.add_node({{"translation", {1.0, 0.0, 0.0}}, {"children", {2}}});
    g.add_node({{"translation", {0.0, 1.0, 0.0}}});
    g.set_roots({0, 1});
    if (animated) {
      const float h = float(std::sqrt(0.5));
      const int times = g.add_floats({0.0f, 1.0f, 2.0f}, 1);
      const int turn = g.add_floats({0, 0, 0, 1, h, 0, 0, h, 1, 0, 0, 0}, 4);
      const int slide_times = g.add_floats({0.0f, 2.0f}, 1);
      const int slide_values = g.add_floats({1, 0, 0, 1, 0, 2}, 3);
      g.doc()["animations"] =
          json::array({{{"channels",
                         {{{"sampler", 0}, {"target", {{"node", 2}, {"path", "rotation"}}}},
                          {{"sampler", 1}, {"target", {{"node", 1}, {"path", "translation"}}}}}},
                        {"samplers",
                         {{{"input", times}, {"output", turn}},
                          {{"input", slide_times}, {"output", slide_values}}}}}});
    }
    return g;
  }
};

// ---- The morphed quad ----
//
// A unit quad in the XY plane facing +Z. Morph target 0 lifts it to z = 1 + x (and tilts its
// normals by (-1, 0, 0)); target 1 shifts it by (0.5, 0, 0). A weights channel with keys at
// 0, 1 and 3 s drives both. The mesh node scales by 2 and moves by (2, 0, 0).
struct MorphedQuad {
  using json = GltfContent::json;
  static constexpr int kMeshNode = 0;
  static constexpr double kKeys[3] = {0.0, 1.0, 3.0};

  static std::vector<glm::vec3> base_positions() {
    return {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  }

  // The cubic polynomials the CUBICSPLINE keys are cut from (a Hermite spline whose tangents
  // are a cubic's derivatives reproduces that cubic exactly).
  static glm::dvec2 cubic(double t) {
    return {0.1 * t * t * t - 0.5 * t * t + t, 0.25 * t * t - 0.05 * t * t * t};
  }
  static glm::dvec2 cubic_derivative(double t) {
    return {0.3 * t * t - t + 1.0, 0.5 * t - 0.15 * t * t};
  }
  // Key values of the STEP and LINEAR channels.
  static glm::dvec2 key_value(int k) {
    static const glm::dvec2 kValues[3] = {{0.0, 0.0}, {1.0, 0.5}, {0.5, 1.0}};
    return kValues[k];
  }

  // The weights at time t, by the interpolation's definition written out.
  static glm::dvec2 weights(Interpolation interpolation, double t) {
    const double tc = std::clamp(t, kKeys[0], kKeys[2]);
    if (interpolation == Interpolation::kCubicSpline) return cubic(tc);
    const int k = tc >= kKeys[2] ? 2 : tc >= kKeys[1] ? 1 : 0;
    if (interpolation == Interpolation::kStep || k == 2) return key_value(k);
    const double s = (tc - kKeys[k]) / (kKeys[k + 1] - kKeys[k]);
    return (1.0 - s) * key_value(k) + s * key_value(k + 1);
  }

  // World position of base vertex `base` under weights w: morph, then scale 2 and move.
  static glm::dvec3 position(const glm::vec3& base, const glm::dvec2& w) {
    const glm::dvec3 local(base.x + 0.5 * w.y, base.y, w.x * (1.0 + base.x));
    return glm::dvec3(2.0, 0.0, 0.0) + 2.0 * local;
  }
  // The unit normal there (the scale is uniform, so it keeps directions).
  static glm::dvec3 normal(const glm::dvec2& w) {
    return glm::normalize(glm::dvec3(-w.x, 0.0, 1.0));
  }

  static GltfContent make(Interpolation interpolation, bool with_normals = true) {
    GltfContent g;
    std::vector<float> positions, normals, lift, lift_normals, shift;
    for (const glm::vec3& p : base_positions()) {
      positions.insert(positions.end(), {p.x, p.y, p.z});
      normals.insert(normals.end(), {0.0f, 0.0f, 1.0f});
      lift.insert(lift.end(), {0.0f, 0.0f, 1.0f + p.x});
      lift_normals.insert(lift_normals.end(), {-1.0f, 0.0f, 0.0f});
      shift.insert(shift.end(), {0.5f, 0.0f, 0.0f});
    }
    json attributes = {{"POSITION", g.add_floats(positions, 3)}};
    json target0 = {{"POSITION", g.add_floats(lift, 3)}};
    if (with_normals) {
      attributes["NORMAL"] = g.add_floats(normals, 3);
      target0["NORMAL"] = g.add_floats(lift_normals, 3);
    }
    const json primitive = {
        {"attributes", attributes},
        {"indices", g.add_indices({0, 1, 2, 0, 2, 3})},
        {"targets", json::array({target0, {{"POSITION", g.add_floats(shift, 3)}}})}};
    g.doc()["meshes"].push_back(
        {{"primitives", json::array({primitive})}, {"weights", {0.25, 0.25}}});
    g.add_node({{"mesh", 0}, {"translation", {2.0, 0.0, 0.0}}, {"scale", {2.0, 2.0, 2.0}}});
    g.set_roots({0});

    std::vector<float> values;
    for (int k = 0; k < 3; ++k) {
      if (interpolation == Interpolation::kCubicSpline) {
        const glm::dvec2 v = cubic(kKeys[k]), d = cubic_derivative(kKeys[k]);
        values.insert(values.end(),
                      {float(d.x), float(d.y), float(v.x), float(v.y), float(d.x), float(d.y)});
      } else {
        values.insert(values.end(), {float(key_value(k).x), float(key_value(k).y)});
      }
    }
    const char* name = interpolation == Interpolation::kStep     ? "STEP"
                       : interpolation == Interpolation::kLinear ? "LINEAR"
                                                                 : "CUBICSPLINE";
    const int input = g.add_floats({float(kKeys[0]), float(kKeys[1]), float(kKeys[2])}, 1);
    const int output = g.add_floats(values, 1);
    g.doc()["animations"] = json::array(
        {{{"channels", {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "weights"}}}}}},
          {"samplers", {{{"input", input}, {"output", output}, {"interpolation", name}}}}}});
    return g;
  }
};

}  // namespace afr::testing
