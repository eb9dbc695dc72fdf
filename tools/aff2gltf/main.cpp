// aff2gltf: converts a BART AFF scene to glTF 2.0 (.gltf + .bin + PNG textures, or one .glb).
//   aff2gltf scene.aff -o scene.gltf
//   aff2gltf scene.aff -o scene.glb
#include "aff_to_gltf.h"

#include <afr/common/cli.h>
#include <afr/common/error.h>

#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>

int main(int argc, char** argv) {
  CLI::App app{"Converts a BART AFF scene (and the files it includes) to glTF 2.0"};
  std::filesystem::path input, output;
  afr::aff::ParseOptions parse_options;
  afr::aff::GltfOptions gltf_options;
  app.add_option("input", input, "The root .aff file")->required();
  app.add_option(
      "-o,--output", output,
      "The .gltf to write, or a .glb: one binary file with the buffer and textures inside "
      "(default: input name, .gltf)");
  app.add_option("--detail-level", parse_options.detail_level,
                 "Initial detail level D: includes above it are skipped")
      ->capture_default_str();
  app.add_option("--sphere-slices", parse_options.tessellation.sphere_slices,
                 "Vertices around a sphere's latitude rings")
      ->capture_default_str()
      ->check(CLI::Range(3, 4096));
  app.add_option("--sphere-stacks", parse_options.tessellation.sphere_stacks,
                 "Latitude bands of a sphere, pole to pole")
      ->capture_default_str()
      ->check(CLI::Range(2, 4096));
  app.add_option("--cone-slices", parse_options.tessellation.cone_slices,
                 "Quads around a cone or cylinder")
      ->capture_default_str()
      ->check(CLI::Range(3, 4096));
  app.add_option("--max-rotation-step", gltf_options.max_rotation_step_deg,
                 "Baked rotations: largest turn between samples, degrees")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 180.0));
  app.add_option("--rotation-tolerance", gltf_options.rotation_tolerance_deg,
                 "Baked rotations: largest angle between the spline and the samples' slerp at the "
                 "middle of two samples, degrees")
      ->capture_default_str()
      ->check(CLI::Range(1e-6, 10.0));
  std::string light_intensity = "1";
  app.add_option("--light-intensity", light_intensity,
                 "Each light's intensity, 1 being NFF's (diffuse x light colour x cos), or 'spd': "
                 "sqrt(N) / (2 N) for N lights, as the Standard Procedural Databases suggest")
      ->capture_default_str()
      ->check(CLI::IsMember({"spd"}) | (afr::finite_number() & CLI::Range(0.0, 1e6)));
  afr::refuse_non_finite(app);
  CLI11_PARSE(app, argc, argv);
  if (light_intensity == "spd") {
    gltf_options.spd_light_intensity = true;
  } else {
    CLI::detail::lexical_cast(light_intensity, gltf_options.light_intensity);
  }
  if (output.empty()) output = std::filesystem::path(input).replace_extension(".gltf").filename();

  try {
    const auto start = std::chrono::steady_clock::now();
    const afr::aff::ConvertReport report =
        afr::aff::convert_aff_to_gltf(input, output, parse_options, gltf_options);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    for (const std::string& warning : report.warnings) spdlog::warn("{}", warning);
    spdlog::info(
        "{}: {} triangles, {} nodes, {} meshes, {} materials, {} textures, {} animation "
        "channels ({:.2f} s)",
        output.string(), report.triangles, report.nodes, report.meshes, report.materials,
        report.textures, report.animation_channels, seconds);
  } catch (const afr::Error& e) {
    std::fprintf(stderr, "aff2gltf: %s\n", e.what());
    return 1;
  }
  return 0;
}
