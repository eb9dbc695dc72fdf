// libFuzzer target for the glTF loading path (gltf_loader.h): the input is the bytes of a
// .gltf or .glb file, loaded from memory with the same checks as a file. The scene's folder is
// an empty one, so external buffers and images are not found. Bad input must end in
// afr::Error; anything else (a crash, undefined behaviour, a failed AFR_CHECK, a runaway
// allocation or a hang) is a bug the fuzzer reports.
#include <afr/common/error.h>
#include <afr/common/gltf_loader.h>

#include <spdlog/spdlog.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>

namespace {

const std::filesystem::path& scene_path() {
  static const std::filesystem::path path = [] {
    const auto dir = std::filesystem::temp_directory_path() / "afr_fuzz_gltf" / "scene";
    std::filesystem::create_directories(dir);
    return dir / "fuzz.gltf";
  }();
  return path;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);  // unsupported features warn once per input
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    (void)afr::load_gltf_bytes(std::span<const uint8_t>(data, size), scene_path());
  } catch (const afr::Error&) {
    // Rejected with a message: what bad input should get.
  }
  return 0;
}
