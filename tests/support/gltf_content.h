// Small glTF files as content users bring them (made by other tools than afr's): a document
// with one embedded buffer, built here from plain arrays, and a few ready-made pieces (an
// axis-aligned box, a node moved by a LINEAR animation). Header-only, for the loader's and the
// tracer's tests.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "support/base64.h"

namespace afr::testing {

class GltfContent {
 public:
  using json = nlohmann::json;

  GltfContent() { doc_["asset"] = {{"version", "2.0"}, {"generator", "afr tests"}}; }

  json& doc() { return doc_; }

  // A float accessor of `width` components per element over a buffer view of its own.
  int add_floats(const std::vector<float>& values, int width) {
    static const char* kTypes[] = {"", "SCALAR", "VEC2", "VEC3", "VEC4"};
    const int view = add_view(values.data(), values.size() * sizeof(float));
    doc_["accessors"].push_back({{"bufferView", view},
                                 {"componentType", 5126},
                                 {"type", kTypes[width]},
                                 {"count", values.size() / size_t(width)}});
    return int(doc_["accessors"].size()) - 1;
  }
  // An accessor of `count` elements of glTF `type` ("VEC4", "MAT4", ...) and `component_type`
  // (5121 unsigned byte, 5123 unsigned short, 5126 float, ...) over a buffer view of its own.
  template <typename T>
  int add_accessor(const std::vector<T>& values, int component_type, const char* type, size_t count,
                   bool normalized = false) {
    const int view = add_view(values.data(), values.size() * sizeof(T));
    json accessor = {
        {"bufferView", view}, {"componentType", component_type}, {"type", type}, {"count", count}};
    if (normalized) accessor["normalized"] = true;
    doc_["accessors"].push_back(accessor);
    return int(doc_["accessors"].size()) - 1;
  }
  int add_indices(const std::vector<uint16_t>& indices) {
    const int view = add_view(indices.data(), indices.size() * sizeof(uint16_t));
    doc_["accessors"].push_back({{"bufferView", view},
                                 {"componentType", 5123},
                                 {"type", "SCALAR"},
                                 {"count", indices.size()}});
    return int(doc_["accessors"].size()) - 1;
  }

  // A mesh of one primitive; returns the mesh index. `uvs` may be empty; no normals are
  // given (the loader makes them, as for much exported content).
  int add_mesh(const std::vector<float>& positions, const std::vector<uint16_t>& indices,
               int material = -1, const std::vector<float>& uvs = {}) {
    json primitive = {{"attributes", {{"POSITION", add_floats(positions, 3)}}},
                      {"indices", add_indices(indices)}};
    if (!uvs.empty()) primitive["attributes"]["TEXCOORD_0"] = add_floats(uvs, 2);
    if (material >= 0) primitive["material"] = material;
    doc_["meshes"].push_back({{"primitives", json::array({primitive})}});
    return int(doc_["meshes"].size()) - 1;
  }

  // An axis-aligned box of half size `h` around the origin, outward faces, 4 vertices per face.
  int add_box(float h, int material = -1) {
    std::vector<float> p;
    std::vector<uint16_t> idx;
    for (int axis = 0; axis < 3; ++axis) {
      for (float sign : {-1.0f, 1.0f}) {
        const int u = (axis + 1) % 3, v = (axis + 2) % 3;
        const uint16_t base = uint16_t(p.size() / 3);
        for (const auto& [a, b] :
             {std::pair{-1.0f, -1.0f}, {1.0f, -1.0f}, {1.0f, 1.0f}, {-1.0f, 1.0f}}) {
          float c[3];
          c[axis] = sign * h;
          c[u] = a * h;
          c[v] = b * h;
          p.insert(p.end(), {c[0], c[1], c[2]});
        }
        // cross(u, v) is +axis: counter-clockwise seen from outside for sign > 0.
        if (sign > 0.0f) {
          idx.insert(idx.end(), {base, uint16_t(base + 1), uint16_t(base + 2), base,
                                 uint16_t(base + 2), uint16_t(base + 3)});
        } else {
          idx.insert(idx.end(), {base, uint16_t(base + 2), uint16_t(base + 1), base,
                                 uint16_t(base + 3), uint16_t(base + 2)});
        }
      }
    }
    return add_mesh(p, idx, material);
  }

  int add_node(json node) {
    doc_["nodes"].push_back(std::move(node));
    return int(doc_["nodes"].size()) - 1;
  }
  // Scene 0 with these root nodes.
  void set_roots(const std::vector<int>& roots) {
    doc_["scenes"] = json::array({{{"nodes", roots}}});
    doc_["scene"] = 0;
  }
  // Moves `node` by LINEAR translation keys (`times` seconds, `values` 3 per key).
  void animate_translation(int node, const std::vector<float>& times,
                           const std::vector<float>& values) {
    const int input = add_floats(times, 1);
    const int output = add_floats(values, 3);
    doc_["animations"].push_back(
        {{"channels",
          json::array({{{"sampler", 0}, {"target", {{"node", node}, {"path", "translation"}}}}})},
         {"samplers", json::array({{{"input", input}, {"output", output}}})}});
  }

  // Writes the document with its buffer as a data: URI.
  void write(const std::filesystem::path& path) const {
    json doc = doc_;
    if (!bin_.empty()) {
      doc["buffers"] =
          json::array({{{"byteLength", bin_.size()},
                        {"uri", "data:application/octet-stream;base64," + base64(bin_)}}});
    }
    std::ofstream(path, std::ios::binary) << doc.dump(1);
  }

 private:
  int add_view(const void* data, size_t size) {
    while (bin_.size() % 4 != 0) bin_.push_back(0);
    doc_["bufferViews"].push_back(
        {{"buffer", 0}, {"byteOffset", bin_.size()}, {"byteLength", size}});
    const auto* bytes = static_cast<const uint8_t*>(data);
    bin_.insert(bin_.end(), bytes, bytes + size);
    return int(doc_["bufferViews"].size()) - 1;
  }

  json doc_;
  std::vector<uint8_t> bin_;
};

// A folder of its own for one test, removed afterwards.
class TempFolder {
 public:
  TempFolder() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    // A parameterised test's names hold '/' ("Each/Suite", "Name/0"): kept out of the folder's
    // name, so that it is one folder (which the destructor removes) rather than a nest.
    std::string name = std::string(info->test_suite_name()) + "_" + info->name();
    std::replace(name.begin(), name.end(), '/', '_');
    path_ = std::filesystem::temp_directory_path() /
            ("afr_content_" + std::to_string(getpid()) + "_" + name);
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempFolder() { std::filesystem::remove_all(path_); }
  TempFolder(const TempFolder&) = delete;
  TempFolder& operator=(const TempFolder&) = delete;

  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

}  // namespace afr::testing
