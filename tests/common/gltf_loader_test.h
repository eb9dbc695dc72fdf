// What the glTF loader's tests share: a builder of glTF documents with one binary buffer,
// written as .gltf or .glb, and the GltfLoaderTest fixture (a scratch folder per test).
#pragma once

#include <afr/common/gltf_loader.h>

#include <afr/common/error.h>
#include <afr/common/image.h>

#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/mesh/triangle_soup_mesh_builder.h>
#include <meshoptimizer.h>

#include <gtest/gtest.h>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "support/base64.h"
#include "support/files.h"
#include "support/log_capture.h"
#include "support/srgb.h"
#include "support/webp.h"

namespace afr::gltf_test {

namespace fs = std::filesystem;
using json = nlohmann::json;

inline constexpr int kByte = 5120;
inline constexpr int kUnsignedByte = 5121;
inline constexpr int kShort = 5122;
inline constexpr int kUnsignedShort = 5123;
inline constexpr int kUnsignedInt = 5125;
inline constexpr int kFloat = 5126;

using afr::testing::read_bytes;

inline void write_bytes(const fs::path& path, const void* data, size_t size) {
  std::ofstream out(path, std::ios::binary);
  out.write(static_cast<const char*>(data), std::streamsize(size));
}

using afr::testing::write_text;

// A glTF document and its one binary buffer, written as .gltf (embedded or external buffer)
// or as .glb.
class GltfBuilder {
 public:
  GltfBuilder() { doc_["asset"] = {{"version", "2.0"}}; }

  json& doc() { return doc_; }
  std::vector<uint8_t>& bin() { return bin_; }
  // Buffers written after the one binary buffer (buffer 0), as they are.
  json& more_buffers() { return more_buffers_; }

  // Appends `size` bytes as a new buffer view (4-byte aligned); returns its index.
  int add_view(const void* data, size_t size, size_t stride = 0) {
    while (bin_.size() % 4 != 0) bin_.push_back(0);
    json view = {{"buffer", 0}, {"byteOffset", bin_.size()}, {"byteLength", size}};
    if (stride != 0) view["byteStride"] = stride;
    const auto* bytes = static_cast<const uint8_t*>(data);
    bin_.insert(bin_.end(), bytes, bytes + size);
    doc_["bufferViews"].push_back(view);
    return int(doc_["bufferViews"].size()) - 1;
  }
  template <typename T>
  int add_view(const std::vector<T>& values, size_t stride = 0) {
    return add_view(values.data(), values.size() * sizeof(T), stride);
  }

  int add_accessor(int view, int component_type, const std::string& type, size_t count,
                   size_t offset = 0, bool normalized = false) {
    json accessor = {{"componentType", component_type}, {"type", type}, {"count", count}};
    if (view >= 0) accessor["bufferView"] = view;
    if (offset != 0) accessor["byteOffset"] = offset;
    if (normalized) accessor["normalized"] = true;
    doc_["accessors"].push_back(accessor);
    return int(doc_["accessors"].size()) - 1;
  }

  // A float accessor over its own buffer view, `width` components per element.
  int add_floats(const std::vector<float>& values, int width) {
    static const char* kTypes[] = {"", "SCALAR", "VEC2", "VEC3", "VEC4"};
    return add_accessor(add_view(values), kFloat, kTypes[width], values.size() / size_t(width));
  }
  int add_indices16(const std::vector<uint16_t>& indices) {
    return add_accessor(add_view(indices), kUnsignedShort, "SCALAR", indices.size());
  }

  void write_embedded(const fs::path& path) {
    json doc = doc_;
    doc["buffers"] =
        json::array({{{"byteLength", bin_.size()},
                      {"uri", "data:application/octet-stream;base64," + testing::base64(bin_)}}});
    for (const json& more : more_buffers_) doc["buffers"].push_back(more);
    write_text(path, doc.dump(2));
  }

  void write_external(const fs::path& path, const std::string& bin_name) {
    json doc = doc_;
    doc["buffers"] = json::array({{{"byteLength", bin_.size()}, {"uri", bin_name}}});
    for (const json& more : more_buffers_) doc["buffers"].push_back(more);
    write_text(path, doc.dump(2));
    write_bytes(path.parent_path() / bin_name, bin_.data(), bin_.size());
  }

  void write_glb(const fs::path& path) {
    json doc = doc_;
    doc["buffers"] = json::array({{{"byteLength", bin_.size()}}});
    for (const json& more : more_buffers_) doc["buffers"].push_back(more);
    std::string text = doc.dump();
    while (text.size() % 4 != 0) text += ' ';
    std::vector<uint8_t> bin = bin_;
    while (bin.size() % 4 != 0) bin.push_back(0);
    std::vector<uint8_t> glb;
    auto u32 = [&](uint32_t v) {
      for (int i = 0; i < 4; ++i) glb.push_back(uint8_t(v >> (8 * i)));
    };
    glb.insert(glb.end(), {'g', 'l', 'T', 'F'});
    u32(2);
    u32(uint32_t(12 + 8 + text.size() + 8 + bin.size()));
    u32(uint32_t(text.size()));
    u32(0x4E4F534A);  // JSON
    glb.insert(glb.end(), text.begin(), text.end());
    u32(uint32_t(bin.size()));
    u32(0x004E4942);  // BIN
    glb.insert(glb.end(), bin.begin(), bin.end());
    write_bytes(path, glb.data(), glb.size());
  }

 private:
  json doc_;
  std::vector<uint8_t> bin_;
  json more_buffers_ = json::array();
};

// An animation channel whose sampler drives the property a KHR_animation_pointer names.
inline json pointer_channel(int sampler, const std::string& pointer) {
  return json{
      {"sampler", sampler},
      {"target",
       {{"path", "pointer"}, {"extensions", {{"KHR_animation_pointer", {{"pointer", pointer}}}}}}}};
}

// The unit quad in the z = 0 plane, counter-clockwise seen from +z, as mesh 0 on node 0 of
// scene 0. Returns the POSITION accessor.
inline int add_quad(GltfBuilder* b) {
  const int positions = b->add_floats({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, 3);
  const int indices = b->add_indices16({0, 1, 2, 0, 2, 3});
  b->doc()["meshes"].push_back(
      {{"name", "quad"},
       {"primitives",
        json::array({{{"attributes", {{"POSITION", positions}}}, {"indices", indices}}})}});
  b->doc()["nodes"].push_back({{"mesh", 0}});
  b->doc()["scenes"] = json::array({{{"nodes", {0}}}});
  b->doc()["scene"] = 0;
  return positions;
}

using afr::testing::reference_srgb_to_linear;

inline size_t count_containing(const std::vector<std::string>& lines, const std::string& part) {
  size_t n = 0;
  for (const std::string& line : lines) n += line.find(part) != std::string::npos ? 1 : 0;
  return n;
}

class GltfLoaderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() /
            ("afr_gltf_test_" + std::to_string(getpid()) + "_" + info->name());
    fs::remove_all(root_);
    dir_ = root_ / "scenes";
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(root_); }

  // Loading `path` must fail with a message that names the file and contains `problem`.
  void expect_error(const fs::path& path, const std::string& problem) {
    try {
      load_gltf(path);
      ADD_FAILURE() << path << " loaded, expected an error about " << problem;
    } catch (const Error& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find(path.filename().string()), std::string::npos) << message;
      EXPECT_NE(message.find(problem), std::string::npos) << message;
    }
  }

  fs::path root_;  // removed afterwards
  fs::path dir_;   // where the scenes are written, one level below root_
};

}  // namespace afr::gltf_test
