// libFuzzer target for the glTF loading path (gltf_loader.h): the input is the bytes of a
// .gltf or .glb file, loaded from memory with the same checks as a file. The scene's folder is
// an empty one, so external buffers and images are not found. Bad input must end in
// afr::Error; anything else (a crash, undefined behaviour, a failed AFR_CHECK, a runaway
// allocation or a hang) is a bug the fuzzer reports. A scene that loads is then used as a
// renderer uses it: evaluated at its start, middle and end and past both ends (transforms,
// skins, morph weights, animated properties and visibility), its camera placed, its bounds
// taken and its deformed primitives deformed, since a scene the loader accepts must be one
// whose every time can be rendered.
#include <afr/common/error.h>
#include <afr/common/gltf_loader.h>

#include <spdlog/spdlog.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace {

const std::filesystem::path& scene_path() {
  static const std::filesystem::path path = [] {
    const auto dir = std::filesystem::temp_directory_path() / "afr_fuzz_gltf" / "scene";
    std::filesystem::create_directories(dir);
    return dir / "fuzz.gltf";
  }();
  return path;
}

// Everything a renderer asks of a loaded scene at a few times (see the header comment).
void use(const afr::Scene& scene) {
  // Deforming costs the vertex count at each time; a small input can describe many vertices
  // (a sparse accessor, a repeated buffer view), so very large meshes are left to the tests.
  constexpr size_t kMaxDeformedVertices = 1 << 16;
  const double d = scene.duration();
  afr::SceneState state;
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;
  std::vector<glm::vec4> tangents;
  for (const double t : {-1.0, 0.0, 0.5 * d, d, d + 1.0}) {
    scene.evaluate(t, &state);
    (void)scene.camera_at(state);
    glm::dvec3 lo, hi;
    scene.bounds(state, &lo, &hi);
    for (size_t i = 0; i < scene.lights.size(); ++i) (void)scene.light_at(state, i);
    for (size_t i = 0; i < scene.materials.size(); ++i) (void)scene.material_at(state, i);
    for (const int node : scene.scene_nodes()) {
      (void)scene.node_hidden(state, node);
      if (!scene.node_deforms(node)) continue;
      const afr::Mesh& mesh = scene.meshes[size_t(scene.nodes[size_t(node)].mesh)];
      for (size_t p = 0; p < mesh.primitives.size(); ++p) {
        const size_t n = mesh.primitives[p].positions.size();
        if (n > kMaxDeformedVertices) continue;
        positions.resize(n);
        normals.resize(n);
        tangents.resize(n);
        scene.deform(node, p, state, positions.data(), normals.data(), tangents.data());
      }
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);  // unsupported features warn once per input
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    use(afr::load_gltf_bytes(std::span<const uint8_t>(data, size), scene_path()));
  } catch (const afr::Error&) {
    // Rejected with a message: what bad input should get.
  }
  return 0;
}
