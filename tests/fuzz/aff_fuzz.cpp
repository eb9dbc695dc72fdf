// libFuzzer target for the AFF parser and the glTF conversion (tools/aff2gltf): parses the
// input as the root file of a scene and builds its glTF model in memory (no files written).
// Bad input must end in afr::Error; anything else (a crash, undefined behaviour, a failed
// AFR_CHECK, a runaway allocation or a hang) is a bug the fuzzer reports.
#include "aff_parser.h"
#include "aff_to_gltf.h"

#include <afr/common/check.h>
#include <afr/common/error.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

namespace {

// A folder laid out like BART's, with an include (part.aff) and texture files (never
// read: the conversion in memory only names them) that the seeds use; other names are not
// found, unless given as an absolute path.
const std::filesystem::path& root_dir() {
  static const std::filesystem::path dir = [] {
    const auto top = std::filesystem::temp_directory_path() / "afr_fuzz_aff";
    std::filesystem::create_directories(top / "aff");
    std::filesystem::create_directories(top / "TextureFiles");
    std::ofstream(top / "aff" / "part.aff") << "fm 0.3 0.3 0.3  0.9 0.9 0.9  0 0 0  0 0 0\n"
                                               "m vertices 3 0 0 0 1 0 0 0 1 0 triangles 1 0 1 2\n";
    for (const char* texture : {"checker.ppm", "gray.ppm", "floor.ppm", "garden.ppm"}) {
      std::ofstream(top / "TextureFiles" / texture) << "P3 1 1 255 1 2 3\n";
    }
    return top / "aff";
  }();
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    // The coarsest tessellation: the same code with far fewer triangles per sphere or cone.
    afr::aff::ParseOptions options;
    options.tessellation = {.sphere_slices = 3, .sphere_stacks = 2, .cone_slices = 3};
    const afr::aff::Scene scene = afr::aff::parse_aff_text(text, "fuzz.aff", root_dir(), options);
    const afr::aff::GltfScene gltf = afr::aff::build_gltf(scene);
    // Every accessor lies inside the one buffer.
    const tinygltf::Model& m = gltf.model;
    for (const tinygltf::BufferView& v : m.bufferViews) {
      AFR_CHECK(v.buffer == 0 && v.byteOffset + v.byteLength <= m.buffers[0].data.size());
    }
    for (const tinygltf::Accessor& a : m.accessors) {
      AFR_CHECK(a.bufferView >= 0 && size_t(a.bufferView) < m.bufferViews.size());
    }
  } catch (const afr::Error&) {
    // Rejected with a message: what bad input should get.
  }
  return 0;
}
