// The scene model of afr: what a glTF 2.0 file (or the built-in scene) describes, in plain
// structs: meshes (with skins and morph targets), materials, textures, a node hierarchy,
// animations of node transforms and morph weights, cameras and punctual lights.
// Scene::evaluate gives every node's world transform at a time t, deform the vertices of a
// skinned or morphed mesh at that time; camera_at gives the active camera.
#pragma once

#include <afr/common/animation.h>
#include <afr/common/camera.h>
#include <afr/common/math.h>

#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace afr {

// One morph target of a primitive (glTF 2.0, 3.7.2.2): displacements of its vertices, added
// times the target's weight to the base positions and normals. An array is empty when the
// target does not displace that attribute; otherwise it has one entry per vertex.
struct MorphTarget {
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;
  // TANGENT displacements (of x, y, z; w stays), kept only where the primitive keeps its
  // tangents (Primitive::tangents).
  std::vector<glm::vec3> tangents;
};

// An indexed triangle list with one material. Normals are per vertex (generated when the
// source has none); uvs and colors are empty when the source has none. Skinning data and morph
// targets are present only where the mesh has them.
struct Primitive {
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;
  // Texture coordinates, one per vertex (or empty: none), in the sets its material's texture
  // slots read (Material::TextureSets): `uvs` is set 0, more_uvs[k - 1] set k. A set is one
  // glTF TEXCOORD_n through one KHR_texture_transform, applied at load; more_uvs is empty
  // unless the material's slots read more than one.
  std::vector<glm::vec2> uvs;
  std::vector<std::vector<glm::vec2>> more_uvs;
  // glTF's COLOR_0 in linear RGB, one per vertex: it multiplies the material's base color (and
  // its texture) like the base color factor does.
  std::vector<glm::vec3> colors;
  // COLOR_0's alpha (0 to 1), one per vertex, kept only where the primitive's material masks or
  // blends (Material::alpha_mode) and it is below 1 somewhere: it multiplies the opacity.
  std::vector<float> color_alpha;
  // glTF's TANGENT, one per vertex: a tangent (x, y, z, toward +u) and w = +1 or -1, the
  // bitangent being cross(normal, tangent) x w. Kept only where the primitive's material needs a
  // tangent frame (a normal or clearcoat normal texture, anisotropy), and generated there when
  // the file has none (generate_tangents); empty otherwise (each triangle's own frame is used
  // then, as for a scene made in code).
  std::vector<glm::vec4> tangents;
  // The texture coordinate set generate_tangents derived `tangents` from; -1 where they are the
  // file's TANGENT (or there are none). A generated frame follows its set's coordinates, so the
  // tracer turns it with that set's animated KHR_texture_transform (Material::uv_transforms).
  int tangent_set = -1;
  std::vector<uint32_t> indices;  // 3 per triangle
  int material = -1;              // index into Scene::materials; -1 = default material
  // JOINTS_0 and WEIGHTS_0 of a skinned mesh, one entry per vertex (else empty): four slots of
  // the skin's joint list and their weights, which are >= 0 and sum to 1. More than four
  // influences (JOINTS_1) are not modelled.
  std::vector<std::array<uint16_t, 4>> joints;
  std::vector<glm::vec4> joint_weights;
  std::vector<MorphTarget> targets;  // as many as the mesh has weights
  // The normals were generated from the positions (the source had none): a morphed shape then
  // gets its normals generated from its own positions.
  bool generated_normals = false;

  size_t triangle_count() const { return indices.size() / 3; }
  // Texture coordinate set k (0: uvs); empty where the primitive has none.
  const std::vector<glm::vec2>& uv_set(int k) const {
    static const std::vector<glm::vec2> kNone;
    if (k == 0) return uvs;
    return k > 0 && size_t(k) <= more_uvs.size() ? more_uvs[size_t(k) - 1] : kNone;
  }
};

struct Mesh {
  std::string name;
  std::vector<Primitive> primitives;
  // The default morph weights, one per morph target of every primitive; empty when the mesh
  // has no morph targets (then no primitive has any).
  std::vector<float> weights = {};
};

// A glTF skin: the joints (nodes) whose world transforms move the vertices of the meshes on
// the nodes that name the skin, and for each joint the inverse bind matrix that takes the
// mesh's bind pose into the joint's space. A vertex goes to
// sum_i w_i (world(joint_i) x inverse_bind_i) x v in world space; the transform of the node that
// carries the mesh is ignored (glTF 2.0, 3.7.3).
struct Skin {
  std::string name;
  std::vector<int> joints;                        // node indices
  std::vector<glm::dmat4> inverse_bind_matrices;  // one per joint
  int skeleton = -1;                              // the file's skeleton root (not used)
};

// A decoded texture in linear RGB, row 0 at the top (v = 0), texel centers at (i + 0.5) / size.
struct Texture {
  std::string name;
  int width = 0;
  int height = 0;
  // Level 0, row by row, either as linear values (`texels`: textures made in code, such as the
  // built-in scene's) or as the 8-bit codes of the image it was decoded from (`codes`: glTF's;
  // one uint32 a texel, red in the low byte, then green, blue, alpha), which `encoding` turns
  // into linear values at each lookup: a quarter of the floats' memory. One of the two is empty.
  std::vector<glm::vec3> texels;
  enum class Encoding : uint8_t { kSrgb, kLinear };  // of the codes' red, green, blue
  std::vector<uint32_t> codes;
  Encoding encoding = Encoding::kLinear;

  // Level 0's alpha (linear, 0 to 1), kept only where a material masks or blends with it
  // (Material::AlphaMode::kMask, kBlend): `alpha` beside `texels` (empty: opaque), or the codes'
  // fourth byte where `coded_alpha`.
  std::vector<float> alpha;
  bool coded_alpha = false;

  size_t texel_count() const { return codes.empty() ? texels.size() : codes.size(); }
  // Whether level 0 holds width x height texels (a lookup of anything else is white).
  bool whole() const {
    return width > 0 && height > 0 && texel_count() == size_t(width) * size_t(height);
  }
  // Level 0's texel i (linear), and its alpha (1 without one).
  glm::vec3 texel(size_t i) const;
  float texel_alpha(size_t i) const;

  // glTF's sampler: how coordinates outside [0, 1] wrap in u (wrapS) and v (wrapT), and
  // whether a lookup at level 0 takes the nearest texel instead of blending four (magFilter
  // NEAREST: pixel art stays crisp when magnified).
  enum class Wrap : uint8_t { kRepeat, kClampToEdge, kMirroredRepeat };
  Wrap wrap_s = Wrap::kRepeat;
  Wrap wrap_t = Wrap::kRepeat;
  bool nearest = false;

  // Level 0's lookup: bilinear (or the nearest texel), through the wrap modes.
  glm::vec3 sample_bilinear(glm::vec2 uv) const;
  // The alpha channel's lookup at level 0, as sample_bilinear's (1 without one).
  float sample_alpha(glm::vec2 uv) const;

  // Minification (docs/scene-model.md, "Texture filtering"): mip levels 1, 2, ... down to
  // 1 x 1 (level 0 is `texels` or `codes`), each (w + 1) / 2 x (h + 1) / 2 of the one before,
  // every texel the mean of the 2 x 2 it covers (through the wrap modes at the edges), stored as
  // level 0 is (a coded texture's levels are coded too, alpha 255). Made by build_mips(), which
  // Scene::finalize() calls for every texture.
  struct Level {
    int width = 0;
    int height = 0;
    std::vector<glm::vec3> texels;
    std::vector<uint32_t> codes;
  };
  std::vector<Level> mips;
  void build_mips();
  // Trilinear lookup: `lod` is log2 of the lookup's footprint in level-0 texels. lod <= 0 (or
  // not finite, or no mips) is sample_bilinear; above, the two levels around lod, blended.
  glm::vec3 sample(glm::vec2 uv, float lod) const;
};

// The part of glTF's metallic-roughness material that afr shades, plus an ambient reflectance
// (AFF scenes carry one; for glTF without it, it is the base color).
struct Material {
  std::string name;
  glm::vec4 base_color_factor{1.0f};
  int base_color_texture = -1;  // index into Scene::textures (sRGB-decoded color)
  float metallic = 1.0f;
  float roughness = 1.0f;
  // glTF's metallicRoughnessTexture (linear data): its green channel multiplies `roughness`,
  // its blue `metallic`, at each point. -1: none.
  int metallic_roughness_texture = -1;
  glm::vec3 emissive{0.0f};   // emissive_factor x emissive_strength
  int emissive_texture = -1;  // sRGB-decoded color multiplying `emissive`; -1: none
  // glTF's emissiveFactor and KHR_materials_emissive_strength, kept apart for an animation of
  // either (PropertyChannel), which sets `emissive` to their product again.
  glm::vec3 emissive_factor{0.0f};
  float emissive_strength = 1.0f;
  // glTF's occlusionTexture (linear data): its red channel, moved toward 1 by
  // 1 - occlusion_strength, scales the ambient light a point receives. -1: none.
  int occlusion_texture = -1;
  float occlusion_strength = 1.0f;
  // glTF's normalTexture (linear data): a tangent-space normal, its x and y scaled by
  // normal_scale, replaces the shading normal. -1: none.
  int normal_texture = -1;
  float normal_scale = 1.0f;
  // Which texture coordinate set of its primitives (Primitive::uv_set) each texture slot reads.
  // Slots whose glTF texCoord and KHR_texture_transform agree share a set; the first textured
  // slot's (base color first) is set 0.
  struct TextureSets {
    uint8_t base_color = 0;
    uint8_t metallic_roughness = 0;
    uint8_t emissive = 0;
    uint8_t occlusion = 0;
    uint8_t normal = 0;
    uint8_t transmission = 0;
    uint8_t specular = 0;
    uint8_t specular_color = 0;
    uint8_t clearcoat = 0;
    uint8_t clearcoat_roughness = 0;
    uint8_t clearcoat_normal = 0;
    uint8_t sheen_color = 0;
    uint8_t sheen_roughness = 0;
    uint8_t anisotropy = 0;
    uint8_t glossiness = 0;
    uint8_t iridescence = 0;
    uint8_t iridescence_thickness = 0;
    uint8_t diffuse_transmission = 0;
    uint8_t diffuse_transmission_color = 0;
    bool operator==(const TextureSets&) const = default;
  };
  TextureSets uv_set;
  // A KHR_texture_transform: texture coordinates (u, v) read as T(offset) R(rotation) S(scale)
  // (u, v), the rotation turning (u, v) to (c u + s v, -s u + c v) (the Khronos sample viewer's
  // order and sense; the loader's TextureTransformTest models agree).
  struct UvTransform {
    glm::dvec2 offset{0.0};
    double rotation = 0.0;  // radians
    glm::dvec2 scale{1.0};
    glm::dmat3 matrix() const;  // column-major, acting on (u, v, 1)
    bool operator==(const UvTransform&) const = default;
  };
  // Where KHR_animation_pointer animates a slot's texture transform, the transform of each set
  // at this time, indexed like the sets (empty where none is animated). An animated slot reads
  // a set of its own that holds its TEXCOORD_n untransformed, and the tracer applies the set's
  // transform at each lookup; every other set is transformed at load and holds the identity
  // here.
  std::vector<UvTransform> uv_transforms;
  // glTF's alphaMode. kMask cuts the surface away where its alpha (base_color_factor's alpha x
  // the base-color texture's x COLOR_0's) is below alpha_cutoff, for every ray (camera, reflection,
  // shadow, occlusion). kBlend shows alpha of the surface's own light over 1 - alpha of what
  // lies behind it, and lets 1 - alpha of a light through to what it shadows.
  enum class AlphaMode { kOpaque, kMask, kBlend };
  AlphaMode alpha_mode = AlphaMode::kOpaque;
  float alpha_cutoff = 0.5f;
  std::optional<glm::vec3> ambient;  // reflectance of the scene's ambient light
  // KHR_materials_transmission: the fraction of the non-metallic part that light passes
  // through (refracted, tinted by the base color) instead of reflecting diffusely; 0 = opaque.
  float transmission = 0.0f;
  int transmission_texture = -1;  // linear data: its red channel multiplies `transmission`
  // KHR_materials_diffuse_transmission: the share of the diffuse part (of the non-metallic,
  // non-transmitting part) that passes through the thin surface instead of reflecting: light
  // from the side the viewer does not see comes through as a Lambertian transmission of color
  // diffuse_transmission_color (not the base color), and the diffuse reflection keeps
  // 1 - diffuse_transmission. 0: none. diffuse_transmission_texture's alpha channel (decoded as
  // data, held in red) multiplies the factor, diffuse_transmission_color_texture's color (sRGB)
  // the color; -1: none.
  float diffuse_transmission = 0.0f;
  glm::vec3 diffuse_transmission_color{1.0f};
  int diffuse_transmission_texture = -1;
  int diffuse_transmission_color_texture = -1;
  // KHR_materials_ior: the index of refraction inside the surface (outside is 1). Either >= 1,
  // or 0, which the extension defines as a Fresnel term of 1 (all reflection).
  float ior = 1.5f;
  // KHR_materials_specular (factors): the strength of the non-metallic part's specular
  // reflection, and its color at normal incidence. The dielectric's F0 is
  // min(((ior - 1) / (ior + 1))^2 x specular_color, 1) x specular, its F90 `specular`.
  float specular = 1.0f;
  glm::vec3 specular_color{1.0f};
  bool has_specular_extension = false;  // F0 from ior then (else 0.04, glTF's core default)
  // Its textures: specularTexture's alpha channel multiplies `specular` (decoded as linear data
  // with the alpha in every channel, Texture's red), specularColorTexture's color (sRGB)
  // multiplies `specular_color`. -1: none.
  int specular_texture = -1;
  int specular_color_texture = -1;
  // KHR_materials_clearcoat: a clear dielectric layer (F0 0.04) over the material, of weight
  // `clearcoat` and roughness `clearcoat_roughness`, times the red channel of
  // clearcoat_texture and the green of clearcoat_roughness_texture (linear data; -1: none). The
  // layer lies on the surface's interpolated normal, bent by its own clearcoat_normal_texture
  // (tangent space, x and y scaled by clearcoat_normal_scale) where it has one, never by the
  // material's normal texture.
  float clearcoat = 0.0f;
  float clearcoat_roughness = 0.0f;
  int clearcoat_texture = -1;
  int clearcoat_roughness_texture = -1;
  int clearcoat_normal_texture = -1;
  float clearcoat_normal_scale = 1.0f;
  // KHR_materials_sheen: a layer of fibres over the material (cloth, velvet) that reflects
  // sheen_color toward grazing angles through a Charlie lobe of roughness sheen_roughness, and
  // takes from the material beneath what it reflects. sheen_color_texture (sRGB) multiplies
  // the color, sheen_roughness_texture's alpha channel (decoded as data, held in red) the
  // roughness. A black color: no sheen.
  glm::vec3 sheen_color{0.0f};
  float sheen_roughness = 0.0f;
  int sheen_color_texture = -1;
  int sheen_roughness_texture = -1;
  // KHR_materials_anisotropy: the specular lobe stretched along a direction of the surface, by
  // `anisotropy` (0: none, 1: fully) times anisotropy_texture's blue channel; the direction is
  // the texture's red and green (tangent space, 0 to 1 for -1 to 1; without a texture the
  // tangent), turned by anisotropy_rotation radians toward the bitangent. Linear data.
  float anisotropy = 0.0f;
  float anisotropy_rotation = 0.0f;
  int anisotropy_texture = -1;
  // KHR_materials_pbrSpecularGlossiness, read into the fields above: base_color_factor and
  // base_color_texture are its diffuse; metallic is 0; specular_color and
  // specular_color_texture its specular color, which is F0 itself here (not scaled by the ior's
  // Fresnel term; specular 1); roughness is 1 - its glossiness factor, and glossiness_texture
  // (the image's alpha, decoded as data and held in red) g makes it 1 - (1 - roughness) x g. The
  // diffuse part keeps 1 - max(F0) of its light, as the extension's model has it.
  bool specular_glossiness = false;
  int glossiness_texture = -1;
  // KHR_materials_iridescence: a thin film over the material, of weight `iridescence` (times
  // iridescence_texture's red) and index of refraction iridescence_ior, whose interference
  // colors its specular reflection: the Fresnel term becomes mix(F, F_film, weight), F_film the
  // extension's thin-film reflectance for a film of thickness iridescence_thickness_max
  // nanometres, or with iridescence_thickness_texture mix(min, max, its green). Linear data.
  float iridescence = 0.0f;
  float iridescence_ior = 1.3f;
  float iridescence_thickness_min = 100.0f;
  float iridescence_thickness_max = 400.0f;
  int iridescence_texture = -1;
  int iridescence_thickness_texture = -1;
  // KHR_materials_volume: a transmissive material whose thickness is above 0 fills the volume
  // its closed mesh bounds, and light crossing it keeps attenuation_color per
  // attenuation_distance travelled (Beer-Lambert; infinity: none). Thickness 0 is a thin wall.
  float thickness = 0.0f;
  glm::vec3 attenuation_color{1.0f};
  float attenuation_distance = std::numeric_limits<float>::infinity();
  // KHR_materials_dispersion: 20 / the Abbe number V_d (0: none). In a volume (thickness > 0)
  // each color channel refracts with its own ior, red the smallest.
  float dispersion = 0.0f;
  bool double_sided = false;
  // KHR_materials_unlit: the surface shows its base color (factor x texture x COLOR_0) as it
  // is, whatever the light; every other property but alpha is ignored.
  bool unlit = false;
};

// KHR_lights_punctual. Position and direction (local -Z) come from the light's node, or, for
// a light `on_camera`, from the active camera.
struct Light {
  enum class Type { kPoint, kDirectional, kSpot };
  std::string name;
  Type type = Type::kPoint;
  glm::vec3 color{1.0f};
  float intensity = 1.0f;
  float range = 0.0f;  // 0 = infinite
  float inner_cone_angle = 0.0f;
  float outer_cone_angle = 0.7853981633974483f;
  bool inverse_square_falloff = true;  // false for NFF/AFF lights, which do not fall off
  // A light that no node carries but the active camera (camera_at), as a child node of the
  // camera's would be, turned by `camera_rotation` in the camera's frame (x right, y up, z
  // back): the default headlight of a scene without lights (docs/scene-model.md).
  bool on_camera = false;
  glm::dquat camera_rotation{1.0, 0.0, 0.0, 0.0};
};

// A glTF perspective camera. The image's aspect ratio always comes from the render target.
struct CameraModel {
  std::string name;
  double yfov = 0.8;  // radians, full vertical field of view
  double znear = 0.01;
  double ymag = 0.0;  // > 0: orthographic, the view's half height (Camera::ymag); yfov unused
  // The view's width over its height as the file gives it (a perspective camera's aspectRatio,
  // an orthographic one's xmag / ymag); 0: none. The image's own aspect ratio decides the view;
  // programs size their image by this one where no size is given (image_size_for_aspect).
  double aspect_ratio = 0.0;
};

struct Node {
  std::string name;
  int parent = -1;
  std::vector<int> children;
  glm::dvec3 translation{0.0};
  glm::dquat rotation{1.0, 0.0, 0.0, 0.0};  // glm order: w, x, y, z
  glm::dvec3 scale{1.0};
  std::optional<glm::dmat4> matrix;  // a glTF node given as a matrix (not animatable)
  int mesh = -1;
  int camera = -1;
  int light = -1;
  int skin = -1;               // index into Scene::skins; the mesh is then skinned
  std::vector<float> weights;  // morph weights instead of the mesh's; empty: the mesh's
  // KHR_node_visibility: false hides the node's and its descendants' meshes and lights (not
  // its camera), whatever their own. A property channel (kNodeVisible) may drive it.
  bool visible = true;
};

// The deepest Scene::ray_depth: a glass hit branches in two, so a sample may cast up to
// 2 + 4 + ... + 2^depth secondary rays (fewer where the light a branch carries runs out).
inline constexpr int kMaxRayDepth = 10;

// The world transforms of every node at one time, and what deforms meshes at that time.
struct SceneState {
  double time = 0.0;
  std::vector<glm::dmat4> world;  // indexed like Scene::nodes
  // The morph weights of every node whose mesh has morph targets (Scene::morph_weights), and
  // world(joint) x inverse bind matrix for every joint of every skin, skin after skin.
  std::vector<float> morph_weights;
  std::vector<glm::mat4x3> joint_matrices;  // affine: the bottom row is (0, 0, 0, 1)
  // Where property channels drive them (Scene::property_channels), the lights, cameras and
  // materials at this time, indexed like the Scene's; each empty when none of its kind is
  // animated (read them through Scene::light_at, camera_at, material_at).
  std::vector<Light> lights;
  std::vector<CameraModel> cameras;
  std::vector<Material> materials;
  // Per node, whether it or an ancestor is hidden at this time (Node::visible); empty where
  // every node is visible at all times (read it through Scene::node_hidden).
  std::vector<uint8_t> hidden;
};

class Scene {
 public:
  std::string source;  // file name, or "builtin"
  std::vector<Mesh> meshes;
  std::vector<Material> materials;
  std::vector<Texture> textures;
  std::vector<Light> lights;
  std::vector<CameraModel> cameras;
  std::vector<Node> nodes;
  std::vector<Skin> skins;
  std::vector<int> roots;  // nodes of the displayed scene with no parent
  std::vector<AnimationChannel> channels;
  std::vector<PropertyChannel> property_channels;  // lights', cameras' and materials' properties
  glm::vec3 background{0.0f};                      // radiance of rays that hit nothing
  glm::vec3 ambient{0.0f};                         // ambient light, times Material::ambient
  // Secondary rays in a row that the tracers follow (mirror reflections, glass's reflections
  // and refractions; 0 to kMaxRayDepth): the file's extras.afr_ray_depth, which display_node
  // --ray-depth writes into the scene it serves and afr-render --ray-depth sets. None: the
  // tracer's own (TracerOptions::max_mirror_depth).
  std::optional<int> ray_depth;

  // Checks every index and channel, fills Node::parent from children, and derives which
  // nodes move. Call once after building or loading, before any other method. Throws
  // afr::Error naming the first problem found.
  void finalize();

  // Seconds covered by the animation (0 for a static scene).
  double duration() const { return duration_; }
  bool is_animated() const { return !channels.empty() || !property_channels.empty(); }
  // True when the world transform of node i depends on time (it or an ancestor is animated).
  bool node_moves(int i) const { return node_moves_[i]; }
  // True when node i carries a mesh that is skinned or has morph targets: its vertices are
  // those deform() gives, not the mesh's under the node's world transform.
  bool node_deforms(int i) const { return node_deforms_[i]; }
  // True when the world-space vertices of node i's mesh depend on time: the node moves (a
  // mesh that is not skinned), a joint of its skin moves, or a weights channel drives it.
  bool node_geometry_moves(int i) const { return node_geometry_moves_[i]; }
  // True when node i's visibility depends on time: a property channel drives it or an
  // ancestor's (Node::visible).
  bool node_visibility_varies(int i) const { return visibility_varies_[i]; }
  // Whether node i's mesh and light are hidden at the state's time.
  bool node_hidden(const SceneState& state, int i) const {
    return !state.hidden.empty() && state.hidden[size_t(i)];
  }
  // True when any mesh of the displayed scene moves or deforms: samples then need a velocity.
  bool has_moving_geometry() const { return has_moving_geometry_; }
  // The node whose camera is active (the first camera node in scene order), or -1.
  int camera_node() const { return camera_node_; }
  // The active camera's CameraModel::aspect_ratio; 0 without a camera or without one given.
  double camera_aspect_ratio() const {
    if (camera_node_ < 0) return 0.0;
    const int c = nodes[size_t(camera_node_)].camera;
    return c >= 0 && size_t(c) < cameras.size() ? cameras[size_t(c)].aspect_ratio : 0.0;
  }
  // The nodes reachable from `roots`, parents before children: what is rendered.
  const std::vector<int>& scene_nodes() const { return scene_nodes_; }

  // World transforms of all nodes at time t (seconds; clamped to the keyframe range by each
  // channel). `state` is reused without allocating once sized.
  void evaluate(double t, SceneState* state) const;
  SceneState evaluate(double t) const;

  // The morph weights of node i at the state's time (empty when its mesh has no targets).
  std::span<const float> morph_weights(const SceneState& state, int i) const {
    return {state.morph_weights.data() + weight_start_[i], weight_start_[i + 1] - weight_start_[i]};
  }
  // The world-space vertices of primitive `primitive` of the mesh on node `node`
  // (node_deforms) at the state's time: morph targets applied in the mesh's space, then the
  // skin (or, without one, the node's world transform). Writes the primitive's vertex count
  // of positions, and of unit normals when `normals` is not null (zero where the normal is
  // degenerate), and of tangents when `tangents` is not null and the primitive has them
  // (Primitive::tangents: x, y, z moved with the surface, not unit; w turned where the skin or
  // the transform mirrors). Allocates nothing.
  void deform(int node, size_t primitive, const SceneState& state, glm::vec3* positions,
              glm::vec3* normals, glm::vec4* tangents = nullptr) const;

  // The active camera at the state's time. Without a camera node, the default camera: one
  // fixed camera that looks from the +Z side at the bounds of the whole animation (their
  // union over time 0 and every keyframe time), so a moving object moves across the image.
  Camera camera_at(const SceneState& state) const;
  // Light and material i at the state's time: the Scene's own unless a property channel
  // animates its kind.
  const Light& light_at(const SceneState& state, size_t i) const {
    return state.lights.empty() ? lights[i] : state.lights[i];
  }
  const Material& material_at(const SceneState& state, size_t i) const {
    return state.materials.empty() ? materials[i] : state.materials[i];
  }
  // The materials that property channels animate, ascending (a renderer re-derives what it
  // keeps of them at each time).
  const std::vector<int>& animated_materials() const { return animated_materials_; }

  // World-space bounds of all geometry at time t, deformed geometry included.
  void bounds(const SceneState& state, glm::dvec3* lo, glm::dvec3* hi) const;

  size_t triangle_count() const;  // over the instanced scene (one count per mesh node)

 private:
  void frame_default_camera();  // sets default_camera_ (finalize, without a camera node)
  void finalize_property_channels();
  void evaluate_properties(double t, SceneState* state) const;

  std::vector<char> node_moves_;
  std::vector<char> visibility_varies_;
  bool visibility_used_ = false;  // a node is hidden at some time: SceneState::hidden is kept
  std::vector<char> node_deforms_;
  std::vector<char> node_geometry_moves_;
  std::vector<int> order_;               // all nodes, parents before children
  std::vector<int> scene_nodes_;         // nodes reachable from roots, parents before children
  std::vector<uint32_t> channel_start_;  // channels of node i: channel_index_[start[i]..start[i+1])
  std::vector<uint32_t> channel_index_;
  std::vector<glm::vec3> mesh_lo_, mesh_hi_;  // local bounds per mesh
  // Morph weights of node i: SceneState::morph_weights[weight_start_[i]..weight_start_[i + 1]),
  // initialised from default_weights_ at every evaluation.
  std::vector<size_t> weight_start_;
  std::vector<float> default_weights_;
  std::vector<size_t>
      skin_start_;  // joints of skin s: SceneState::joint_matrices[skin_start_[s]..]
  size_t joint_matrix_count_ = 0;
  size_t deformation_work_ = 0;  // vertex updates of one deformation of the displayed scene
  bool has_moving_geometry_ = false;
  int camera_node_ = -1;
  double duration_ = 0.0;
  std::vector<int> animated_materials_;
  bool lights_animated_ = false, cameras_animated_ = false;
  Camera default_camera_;  // the camera without a camera node
};

// Generates normals for a primitive that has none: area-weighted vertex normals over the
// triangles sharing a vertex, (0, 0, 1) where all of them are degenerate. Sets
// Primitive::generated_normals.
void generate_normals(Primitive* primitive);

// Generates tangents for a primitive that has normals and texture coordinate set `uv_set`
// (Primitive::uv_set) but no tangents: per vertex, the directions of +u over the triangles
// sharing it (each triangle's dp/du, weighted by its area), made orthogonal to the vertex's
// normal, so that the frame turns smoothly across a curved surface; w makes the bitangent point
// against dp/dv, as glTF's v (down the image) and MikkTSpace's sign have it. A vertex whose
// triangles have no uv area gets a tangent orthogonal to its normal. Nothing where the set is
// missing.
void generate_tangents(Primitive* primitive, int uv_set);

}  // namespace afr
