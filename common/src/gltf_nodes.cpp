// The glTF loader's cameras, lights and nodes (with EXT_mesh_gpu_instancing and
// KHR_node_visibility).
#include "gltf_loader_parts.h"

#include <algorithm>
#include <numbers>

namespace afr::gltf_detail {

// ---- Cameras and lights ----

void Loader::load_cameras() {
  for (size_t i = 0; i < model_.cameras.size(); ++i) {
    const tinygltf::Camera& in = model_.cameras[i];
    const std::string what =
        fmt::format("camera {}{}", i, in.name.empty() ? "" : " ('" + in.name + "')");
    CameraModel camera;
    camera.name = in.name;
    if (in.type == "perspective") {
      const double yfov = in.perspective.yfov;
      const double znear = in.perspective.znear;
      if (!(yfov > 0.0 && yfov < std::numbers::pi)) {
        fail(fmt::format("{} has a yfov of {} radians, outside (0, pi)", what, yfov));
      }
      if (!(znear > 0.0 && std::isfinite(znear))) {
        fail(fmt::format("{} has a znear of {}: a perspective camera's is finite and > 0", what,
                         znear));
      }
      camera.yfov = yfov;
      camera.znear = znear;
      // aspectRatio is optional (tinygltf reads an absent one as 0); one given must be > 0.
      const double aspect = in.perspective.aspectRatio;
      if (aspect > 0.0 && std::isfinite(aspect)) {
        camera.aspect_ratio = aspect;
      } else if (aspect != 0.0) {
        warn_once("aspect ratio " + what,
                  fmt::format("{} has an aspectRatio of {}, not a finite number > 0: it is not "
                              "used",
                              what, aspect));
      }
    } else if (in.type == "orthographic") {
      // The view is 2 ymag high; its width follows from the image's aspect ratio, as a
      // perspective camera's does, so xmag gives only the aspect ratio the image is sized by
      // where no size is given (CameraModel::aspect_ratio). zfar is not used: a ray tracer
      // needs no far plane.
      const double ymag = in.orthographic.ymag;
      const double znear = in.orthographic.znear;
      if (!std::isfinite(ymag) || ymag == 0.0) {
        fail(
            fmt::format("{} is orthographic with a ymag of {}: glTF requires a finite ymag "
                        "other than 0",
                        what, ymag));
      }
      if (!(znear >= 0.0 && std::isfinite(znear))) {
        fail(
            fmt::format("{} is orthographic with a znear of {}: glTF requires a finite znear "
                        ">= 0",
                        what, znear));
      }
      if (ymag < 0.0) {
        warn_once("negative ymag " + what,
                  fmt::format("{} has a negative ymag ({}): its magnitude is used", what, ymag));
      }
      camera.ymag = std::abs(ymag);
      const double xmag = std::abs(in.orthographic.xmag);
      if (xmag > 0.0 && std::isfinite(xmag)) camera.aspect_ratio = xmag / camera.ymag;
      // The near plane at 0 (glTF allows it here) is kept just in front of the eye's plane.
      camera.znear = std::max(znear, 1e-9);
    } else {
      warn_once("camera " + in.type,
                fmt::format("{} cameras are not supported: {} is skipped, and the first other "
                            "camera (else the default camera) is used",
                            in.type, what));
      camera_map_.push_back(-1);
      continue;
    }
    camera_map_.push_back(int(scene_.cameras.size()));
    scene_.cameras.push_back(std::move(camera));
  }
}

void Loader::load_lights() {
  for (size_t i = 0; i < model_.lights.size(); ++i) {
    const tinygltf::Light& in = model_.lights[i];
    const std::string what = fmt::format("light {}", i);
    Light light;
    light.name = in.name;
    if (in.type == "point") {
      light.type = Light::Type::kPoint;
    } else if (in.type == "directional") {
      light.type = Light::Type::kDirectional;
    } else if (in.type == "spot") {
      light.type = Light::Type::kSpot;
    } else {
      warn_once("light " + in.type, fmt::format("lights of type \"{}\" are not supported "
                                                "(skipped)",
                                                in.type));
      light_map_.push_back(-1);
      continue;
    }
    if (!in.color.empty()) {
      if (in.color.size() != 3 || !is_finite(in.color) ||
          std::any_of(in.color.begin(), in.color.end(), [](double c) { return c < 0.0; })) {
        fail(what + " has an invalid color (three finite numbers, none below 0)");
      }
      light.color = glm::vec3(float(in.color[0]), float(in.color[1]), float(in.color[2]));
    }
    if (!std::isfinite(in.intensity) || in.intensity < 0.0) {
      fail(fmt::format("{} has an invalid intensity {}", what, in.intensity));
    }
    if (!std::isfinite(in.range) || in.range < 0.0) {
      fail(fmt::format("{} has an invalid range {}", what, in.range));
    }
    light.intensity = float(in.intensity);
    light.range = float(in.range);
    // The tracer's radiance is color x intensity in float: beyond its range it would be
    // infinite, and every sample it lights NaN.
    const glm::vec3 radiance = light.color * light.intensity;
    if (!std::isfinite(radiance.x) || !std::isfinite(radiance.y) || !std::isfinite(radiance.z)) {
      fail(fmt::format("{} has an intensity {} that, times its color, is beyond a float's range",
                       what, in.intensity));
    }
    if (light.type == Light::Type::kSpot) {
      const double inner = in.spot.innerConeAngle;
      const double outer = in.spot.outerConeAngle;
      if (!(inner >= 0.0 && inner <= outer && outer > 0.0 &&
            outer <= std::numbers::pi / 2 + 1e-9)) {
        fail(fmt::format("{} has invalid cone angles (inner {}, outer {})", what, inner, outer));
      }
      light.inner_cone_angle = float(inner);
      light.outer_cone_angle = float(outer);
    }
    if (in.extras.Has("afr_falloff")) {
      const tinygltf::Value& falloff = in.extras.Get("afr_falloff");
      if (falloff.IsString() && falloff.Get<std::string>() == "none") {
        light.inverse_square_falloff = false;
      } else if (!(falloff.IsString() && falloff.Get<std::string>() == "inverse_square")) {
        fail(what + " extra \"afr_falloff\" is neither \"none\" nor \"inverse_square\"");
      }
    }
    light_map_.push_back(int(scene_.lights.size()));
    scene_.lights.push_back(std::move(light));
  }
}

// ---- Nodes ----

void Loader::load_nodes() {
  const size_t count = model_.nodes.size();
  std::vector<int> parent(count, -1);
  for (size_t i = 0; i < count; ++i) {
    const tinygltf::Node& in = model_.nodes[i];
    const std::string what = fmt::format("node {}", i);
    Node node;
    node.name = in.name;
    for (int child : in.children) {
      if (child < 0 || size_t(child) >= count) {
        fail(fmt::format("{} has child {}, but there are {} nodes", what, child, count));
      }
      if (size_t(child) == i)
        fail(fmt::format("{} is its own child: a cycle in the node graph", what));
      if (parent[size_t(child)] >= 0) {
        fail(
            fmt::format("node {} is a child of both node {} and node {}: the node graph is not a "
                        "tree",
                        child, parent[size_t(child)], i));
      }
      parent[size_t(child)] = int(i);
      node.children.push_back(child);
    }
    if (in.mesh < -1 || in.mesh >= int(model_.meshes.size())) {
      fail(fmt::format("{} refers to mesh {}, but there are {}", what, in.mesh,
                       model_.meshes.size()));
    }
    node.mesh = in.mesh;
    if (in.camera < -1 || in.camera >= int(model_.cameras.size())) {
      fail(fmt::format("{} refers to camera {}, but there are {}", what, in.camera,
                       model_.cameras.size()));
    }
    node.camera = in.camera >= 0 ? camera_map_[size_t(in.camera)] : -1;
    if (in.skin < -1 || in.skin >= int(model_.skins.size())) {
      fail(fmt::format("{} refers to skin {}, but there are {}", what, in.skin,
                       model_.skins.size()));
    }
    if (in.skin >= 0 && in.mesh < 0) fail(fmt::format("{} has skin {} but no mesh", what, in.skin));
    node.skin = in.skin;
    if (!in.weights.empty()) {
      const size_t targets = in.mesh >= 0 ? scene_.meshes[size_t(in.mesh)].weights.size() : 0;
      if (in.weights.size() != targets) {
        fail(fmt::format("{} has {} morph weights, but {} {} morph targets", what,
                         in.weights.size(), in.mesh >= 0 ? "its mesh has" : "it has no mesh and",
                         targets));
      }
      if (!is_finite(in.weights)) fail(what + " has a morph weight that is not finite");
      node.weights.assign(in.weights.begin(), in.weights.end());
    }
    if (const auto ext = in.extensions.find("KHR_lights_punctual"); ext != in.extensions.end()) {
      const int light = ext->second.Has("light") && ext->second.Get("light").IsInt()
                            ? ext->second.Get("light").GetNumberAsInt()
                            : -1;
      if (light < 0 || size_t(light) >= light_map_.size()) {
        fail(fmt::format("{} refers to an invalid light (there are {})", what, light_map_.size()));
      }
      node.light = light_map_[size_t(light)];
    }
    if (!in.matrix.empty()) {
      if (in.matrix.size() != 16 || !is_finite(in.matrix)) fail(what + " has an invalid matrix");
      glm::dmat4 m;
      for (int c = 0; c < 4; ++c) {
        for (int r = 0; r < 4; ++r) m[c][r] = in.matrix[size_t(4 * c + r)];
      }
      node.matrix = m;
    }
    if (!in.translation.empty()) {
      if (in.translation.size() != 3 || !is_finite(in.translation)) {
        fail(what + " has an invalid translation");
      }
      node.translation = {in.translation[0], in.translation[1], in.translation[2]};
    }
    if (!in.rotation.empty()) {
      if (in.rotation.size() != 4 || !is_finite(in.rotation)) {
        fail(what + " has an invalid rotation");
      }
      // glTF stores (x, y, z, w); glm's constructor takes w first.
      const glm::dquat q(in.rotation[3], in.rotation[0], in.rotation[1], in.rotation[2]);
      const double length = glm::length(q);
      if (!(length > 1e-12)) fail(what + " has a zero rotation quaternion");
      node.rotation = q / length;
    }
    if (!in.scale.empty()) {
      if (in.scale.size() != 3 || !is_finite(in.scale)) fail(what + " has an invalid scale");
      node.scale = {in.scale[0], in.scale[1], in.scale[2]};
    }
    scene_.nodes.push_back(std::move(node));
  }
  // Every node has at most one parent now; a node not reachable from a parentless node lies
  // on a cycle (or below one).
  std::vector<char> reached(count, 0);
  std::vector<int> stack;
  for (size_t i = 0; i < count; ++i) {
    if (parent[i] < 0) stack.push_back(int(i));
  }
  while (!stack.empty()) {
    const int n = stack.back();
    stack.pop_back();
    reached[size_t(n)] = 1;
    for (int child : scene_.nodes[size_t(n)].children) stack.push_back(child);
  }
  for (size_t i = 0; i < count; ++i) {
    if (!reached[i]) fail(fmt::format("node {} is part of a cycle in the node graph", i));
  }
  for (size_t i = 0; i < count; ++i) instance_node(int(i));
  hide_invisible_nodes();
}

// KHR_node_visibility: a node whose `visible` is false hides its own and all its descendants'
// meshes and lights, whatever theirs say (cameras stay: visibility does not affect them). The
// value is the file's: KHR_animation_pointer does not animate it (read_animation_pointers).
void Loader::hide_invisible_nodes() {
  // Nodes whose visibility an animation drives keep what they carry (Node::visible).
  std::set<size_t> animated;
  for (const PointerChannel& p : pointer_channels_) {
    if (p.target.property == AnimatedProperty::kNodeVisible) animated.insert(p.target.index);
  }
  size_t hidden = 0;
  std::vector<int> stack;
  for (size_t i = 0; i < model_.nodes.size(); ++i) {
    const auto ext = model_.nodes[i].extensions.find("KHR_node_visibility");
    if (ext == model_.nodes[i].extensions.end()) continue;
    const tinygltf::Value& e = ext->second;
    if (!e.IsObject()) fail(fmt::format("node {} KHR_node_visibility is not an object", i));
    if (!e.Has("visible")) continue;  // default: true
    if (!e.Get("visible").IsBool()) {
      fail(fmt::format("node {} KHR_node_visibility has an invalid visible (true or false)", i));
    }
    if (e.Get("visible").Get<bool>()) continue;
    if (animated.count(i) != 0) {
      scene_.nodes[i].visible = false;
      continue;
    }
    stack.push_back(int(i));
    while (!stack.empty()) {  // the node graph is a tree here (load_nodes checked)
      hidden_nodes_.insert(stack.back());
      Node& node = scene_.nodes[size_t(stack.back())];
      stack.pop_back();
      hidden += node.mesh >= 0 || node.light >= 0 ? 1 : 0;
      node.mesh = -1;
      node.light = -1;
      node.skin = -1;
      node.weights.clear();
      for (int child : node.children) stack.push_back(child);
    }
  }
  if (hidden > 0) {
    spdlog::info("{}: {} node(s) with a mesh or light hidden by KHR_node_visibility",
                 path_.string(), hidden);
  }
}

// EXT_mesh_gpu_instancing: a node's mesh drawn once for each element of its instance attributes
// (TRANSLATION, ROTATION, SCALE, any of them; all of one count), each instance's transform
// applied before the node's own. Each instance becomes a child node carrying the mesh (added
// after the file's nodes, so that no index changes) and the node keeps none; the tracer then
// instances the copies of a mesh that would take much memory (TracerOptions::
// max_copied_vertices) rather than copying them.
void Loader::instance_node(int index) {
  const tinygltf::Node& in = model_.nodes[size_t(index)];
  const auto ext = in.extensions.find("EXT_mesh_gpu_instancing");
  if (ext == in.extensions.end()) return;
  const std::string what = fmt::format("node {} EXT_mesh_gpu_instancing", index);
  const tinygltf::Value& e = ext->second;
  if (!e.IsObject() || !e.Get("attributes").IsObject()) fail(what + " has no \"attributes\"");
  if (scene_.nodes[size_t(index)].mesh < 0) fail(what + ": the node has no mesh");
  if (scene_.nodes[size_t(index)].skin >= 0) {
    warn_once("instanced skin",
              "EXT_mesh_gpu_instancing on a node with a skin is not supported (the mesh is drawn "
              "once)");
    return;
  }
  const tinygltf::Value& attributes = e.Get("attributes");
  // Attribute `name` of `type`, as floats, or empty where the extension does not give it.
  std::optional<size_t> count;
  const auto read = [&](const char* name, int type) -> std::vector<float> {
    if (!attributes.Has(name)) return {};
    const tinygltf::Value& v = attributes.Get(name);
    if (!v.IsInt()) fail(fmt::format("{} attribute {} is not an accessor index", what, name));
    const std::string part = fmt::format("{} {}", what, name);
    std::vector<float> values = read_floats(v.GetNumberAsInt(), type, part);
    const size_t n = values.size() / (type == TINYGLTF_TYPE_VEC4 ? 4 : 3);
    if (count && *count != n) {
      fail(fmt::format("{} has {} instances in {} but {} in another attribute", what, n, name,
                       *count));
    }
    count = n;
    return values;
  };
  for (const std::string& name : attributes.Keys()) {
    if (name != "TRANSLATION" && name != "ROTATION" && name != "SCALE") {
      warn_once("instance attribute " + name,
                fmt::format("EXT_mesh_gpu_instancing attribute {} is not read", name));
    }
  }
  const std::vector<float> t = read("TRANSLATION", TINYGLTF_TYPE_VEC3);
  const std::vector<float> r = read("ROTATION", TINYGLTF_TYPE_VEC4);
  const std::vector<float> s = read("SCALE", TINYGLTF_TYPE_VEC3);
  if (!count) fail(what + " has none of TRANSLATION, ROTATION and SCALE");
  instanced_nodes_.insert(index);
  if (scene_.nodes.size() + *count > kMaxNodes) {
    fail(fmt::format("{} makes {} nodes, more than afr accepts ({})", what,
                     scene_.nodes.size() + *count, kMaxNodes));
  }
  Node copy;
  copy.parent = index;
  {
    Node& node = scene_.nodes[size_t(index)];
    copy.mesh = node.mesh;
    copy.weights = node.weights;
    node.mesh = -1;
    node.weights.clear();
  }
  const std::string name = scene_.nodes[size_t(index)].name;
  scene_.nodes.reserve(scene_.nodes.size() + *count);
  for (size_t k = 0; k < *count; ++k) {
    copy.name = fmt::format("{} instance {}", name, k);
    if (!t.empty()) copy.translation = {t[3 * k], t[3 * k + 1], t[3 * k + 2]};
    if (!r.empty()) {
      const glm::dquat q(r[4 * k + 3], r[4 * k], r[4 * k + 1], r[4 * k + 2]);
      const double length = glm::length(q);
      if (!(length > 1e-12)) fail(fmt::format("{} instance {} has a zero rotation", what, k));
      copy.rotation = q / length;
    }
    if (!s.empty()) copy.scale = {s[3 * k], s[3 * k + 1], s[3 * k + 2]};
    scene_.nodes[size_t(index)].children.push_back(int(scene_.nodes.size()));
    scene_.nodes.push_back(copy);
  }
}

}  // namespace afr::gltf_detail
