// Triangles for the AFF primitives that are not triangles: spheres (`s`), open cones and
// cylinders (`c`) and convex polygons (`p`, `pp`). The tessellation density is fixed by
// TessellationOptions; docs/aff2gltf.md states the defaults.
#pragma once

#include "aff_scene.h"

#include <span>

namespace afr::aff {

struct TessellationOptions {
  int sphere_slices = 32;  // vertices around each latitude ring
  int sphere_stacks = 16;  // latitude bands from pole to pole
  int cone_slices = 32;    // quads around an open cone or cylinder
};

// Triangles a sphere and a cone turn into with these options (a cone with one zero radius has
// half as many: the quads degenerate to triangles).
size_t sphere_triangle_count(const TessellationOptions& options);
size_t cone_triangle_count(const TessellationOptions& options, double r0, double r1);

// Appends a UV sphere with outward normals and counter-clockwise front faces seen from outside;
// a negative radius makes the inside the front (normals inward, winding reversed). `out` must
// carry normals and no uvs.
void append_sphere(const glm::dvec3& center, double radius, const TessellationOptions& options,
                   TriangleSet* out);

// Appends the side of a cone from `base` (radius r0) to `apex` (radius r1), no end caps. If
// r0 < 0 both radii are negated and the inside is the front. `out` must carry normals and no uvs.
void append_cone(const glm::dvec3& base, double r0, const glm::dvec3& apex, double r1,
                 const TessellationOptions& options, TriangleSet* out);

// Appends a convex polygon as the fan (0, k, k+1). `normals` and `uvs` are empty or as long as
// `positions`, matching whether `out` carries them.
void append_polygon(std::span<const glm::vec3> positions, std::span<const glm::vec3> normals,
                    std::span<const glm::vec2> uvs, TriangleSet* out);

}  // namespace afr::aff
