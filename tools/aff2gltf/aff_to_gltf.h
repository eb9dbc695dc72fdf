// Turns a parsed AFF scene into glTF 2.0 (one AFF transform = one glTF node; keyframes as
// CUBICSPLINE or densely baked LINEAR/STEP samplers; the `camera` animation as a camera node;
// lights as KHR_lights_punctual) and writes it as .gltf + .bin + PNG textures, or as one .glb. The
// mapping is documented in docs/aff2gltf.md. Order of calls: parse (aff_parser.h), build_gltf,
// write_gltf; or convert_aff_to_gltf for all three.
#pragma once

#include "aff_parser.h"
#include "aff_scene.h"

#include <tiny_gltf.h>

#include <filesystem>
#include <string>
#include <vector>

namespace afr::aff {

struct GltfOptions {
  // Baked rotations: a LINEAR sample at every key time, then halving intervals until
  // consecutive samples turn by at most `max_rotation_step_deg` and the slerp between them is
  // within `rotation_tolerance_deg` of squad at the midpoint. (Frame times are not sampled:
  // only as many samples as the tolerance needs, docs/aff2gltf.md "Animation".)
  double max_rotation_step_deg = 10.0;
  double rotation_tolerance_deg = 0.01;
  // Baked translations/scales (only where key times repeat): midpoint error at most this
  // fraction of the channel's largest absolute value (and at least 1e-7 absolute).
  double position_tolerance = 1e-5;
  // Each light's intensity in NFF's units (1: diffuse x light colour x cos). The formats leave
  // it open; with `spd_light_intensity` it is sqrt(N) / (2 N) for the scene's N lights, the
  // Standard Procedural Databases' readme's suggestion, which keeps scenes of many lights from
  // washing out.
  double light_intensity = 1.0;
  bool spd_light_intensity = false;
};

// A texture to write: `source` is the AFF's .ppm, `uri` the PNG name next to the .gltf.
struct GltfImage {
  std::filesystem::path source;
  std::string uri;
};

struct GltfScene {
  tinygltf::Model model;          // buffers[0] holds all binary data; its uri is set on write
  std::vector<GltfImage> images;  // parallel to model.images
  std::vector<std::string> warnings;
  size_t triangle_count = 0;  // over all mesh instances in the node tree
  double time_offset = 0.0;   // glTF time = AFF time + time_offset (see docs)
};

GltfScene build_gltf(const Scene& scene, const GltfOptions& options = {});

// Writes `path` (.gltf), its .bin (same stem) and the PNG textures into path's directory.
// Images are written by afr (write_image8), tinygltf only references their uri. A `path` ending
// in .glb is one binary glTF file instead, with the buffer and the PNGs inside. Throws
// afr::Error naming the file on failure.
void write_gltf(GltfScene* gltf, const std::filesystem::path& path);

struct ConvertReport {
  size_t triangles = 0;
  size_t nodes = 0;
  size_t meshes = 0;
  size_t materials = 0;
  size_t textures = 0;
  size_t animation_channels = 0;
  std::vector<std::string> warnings;  // of the parser, then of the conversion
};

ConvertReport convert_aff_to_gltf(const std::filesystem::path& aff_path,
                                  const std::filesystem::path& gltf_path,
                                  const ParseOptions& parse_options = {},
                                  const GltfOptions& gltf_options = {});

}  // namespace afr::aff
