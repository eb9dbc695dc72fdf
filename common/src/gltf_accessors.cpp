// The glTF loader's accessors: buffer views, sparse and compressed data (Draco,
// EXT_/KHR_meshopt_compression) read into typed arrays.
#include "gltf_loader_parts.h"

#include "gltf_meshopt_json.h"

#include <draco/compression/decode.h>
#include <meshoptimizer.h>

#include <algorithm>
#include <cstring>

namespace afr::gltf_detail {

// ---- Accessors ----

std::span<const uint8_t> Loader::buffer_view_bytes(int view, const std::string& what) const {
  if (view < 0 || size_t(view) >= model_.bufferViews.size()) {
    fail(fmt::format("{} refers to buffer view {}, but there are {}", what, view,
                     model_.bufferViews.size()));
  }
  if (const auto decoded = meshopt_bytes_.find(view); decoded != meshopt_bytes_.end()) {
    return decoded->second;
  }
  const tinygltf::BufferView& bv = model_.bufferViews[size_t(view)];
  if (bv.buffer < 0 || size_t(bv.buffer) >= model_.buffers.size()) {
    fail(fmt::format("buffer view {} refers to buffer {}, but there are {}", view, bv.buffer,
                     model_.buffers.size()));
  }
  if (placeholder_buffers_.count(bv.buffer) != 0) {
    fail(
        fmt::format("buffer view {} ({}) is not compressed but reads buffer {}, which holds no "
                    "data (a meshopt fallback or placeholder buffer)",
                    view, what, bv.buffer));
  }
  const std::vector<unsigned char>& data = model_.buffers[size_t(bv.buffer)].data;
  if (bv.byteLength > data.size() || bv.byteOffset > data.size() - bv.byteLength) {
    fail(fmt::format("buffer view {} (bytes {} to {}) is out of bounds of buffer {} ({} bytes)",
                     view, bv.byteOffset, uint64_t(bv.byteOffset) + bv.byteLength, bv.buffer,
                     data.size()));
  }
  return {data.data() + bv.byteOffset, bv.byteLength};
}

// What glTF allows for colors and weights: floats, or unsigned bytes or shorts normalized to
// [0, 1].
bool float_or_normalized(const tinygltf::Accessor& a) {
  return a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT ||
         (a.normalized && (a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
                           a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT));
}

std::string_view type_name(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR:
      return "SCALAR";
    case TINYGLTF_TYPE_VEC2:
      return "VEC2";
    case TINYGLTF_TYPE_VEC3:
      return "VEC3";
    case TINYGLTF_TYPE_VEC4:
      return "VEC4";
    case TINYGLTF_TYPE_MAT2:
      return "MAT2";
    case TINYGLTF_TYPE_MAT3:
      return "MAT3";
    case TINYGLTF_TYPE_MAT4:
      return "MAT4";
    default:
      return "an unknown type";
  }
}

// The bytes of every element of accessor `index`, tightly packed, with sparse values applied:
// the one place where accessor offsets, strides and counts meet buffer sizes.
const tinygltf::Accessor& Loader::accessor_at(int index, const std::string& what) const {
  if (index < 0 || size_t(index) >= model_.accessors.size()) {
    fail(fmt::format("{} refers to accessor {}, but there are {}", what, index,
                     model_.accessors.size()));
  }
  return model_.accessors[size_t(index)];
}

std::vector<uint8_t> Loader::gather(int index, int type, const std::string& what,
                                    const tinygltf::Accessor** out) {
  const tinygltf::Accessor& a = accessor_at(index, what);
  *out = &a;
  const std::string name = fmt::format("accessor {} ({})", index, what);
  const int component_size = tinygltf::GetComponentSizeInBytes(uint32_t(a.componentType));
  const int components = tinygltf::GetNumComponentsInType(uint32_t(a.type));
  if (component_size <= 0 || a.componentType == TINYGLTF_COMPONENT_TYPE_DOUBLE) {
    fail(fmt::format("{} has invalid componentType {}", name, a.componentType));
  }
  if (components <= 0) fail(fmt::format("{} has an invalid type", name));
  if (a.type != type) {
    fail(fmt::format("{} is {} where {} is required", name, type_name(a.type), type_name(type)));
  }
  const auto draco = draco_bytes_.find(index);
  const bool has_bytes = a.bufferView >= 0 || draco != draco_bytes_.end();
  if (a.count > (has_bytes ? kMaxAccessorCount : kMaxAccessorCountWithoutView)) {
    fail(fmt::format("{} has {} elements, more than afr accepts", name, a.count));
  }
  const size_t element_size = size_t(component_size) * size_t(components);
  if (draco != draco_bytes_.end()) {
    AFR_CHECK(draco->second.size() == a.count * element_size);
    return draco->second;
  }
  std::vector<uint8_t> bytes(a.count * element_size, 0);

  if (a.bufferView >= 0) {
    const std::span<const uint8_t> view = buffer_view_bytes(a.bufferView, name);
    const size_t declared_stride = model_.bufferViews[size_t(a.bufferView)].byteStride;
    const size_t stride = declared_stride != 0 ? declared_stride : element_size;
    if (stride < element_size || stride > 252) {
      fail(fmt::format("{} has byteStride {} for elements of {} bytes", name, declared_stride,
                       element_size));
    }
    if (a.count > 0) {
      const uint64_t end = uint64_t(a.byteOffset) + uint64_t(a.count - 1) * stride + element_size;
      if (a.byteOffset > view.size() || end > view.size()) {
        fail(fmt::format("{} is out of bounds of buffer view {}: it reads bytes {} to {} of {}",
                         name, a.bufferView, a.byteOffset, end, view.size()));
      }
      for (size_t i = 0; i < a.count; ++i) {
        std::memcpy(&bytes[i * element_size], &view[a.byteOffset + i * stride], element_size);
      }
    }
  }

  if (a.sparse.isSparse) {
    const int n = a.sparse.count;
    if (n <= 0 || size_t(n) > a.count) {
      fail(fmt::format("{} has sparse count {} for {} elements", name, n, a.count));
    }
    const auto& si = a.sparse.indices;
    const int index_size = tinygltf::GetComponentSizeInBytes(uint32_t(si.componentType));
    if (si.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
        si.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
        si.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
      fail(
          fmt::format("{} has sparse indices of invalid componentType {}", name, si.componentType));
    }
    const std::span<const uint8_t> index_view =
        buffer_view_bytes(si.bufferView, name + " sparse indices");
    const std::span<const uint8_t> value_view =
        buffer_view_bytes(a.sparse.values.bufferView, name + " sparse values");
    const uint64_t index_end = uint64_t(std::max(si.byteOffset, 0)) + uint64_t(n) * index_size;
    const uint64_t value_end =
        uint64_t(std::max(a.sparse.values.byteOffset, 0)) + uint64_t(n) * element_size;
    if (si.byteOffset < 0 || index_end > index_view.size()) {
      fail(fmt::format("{} sparse indices are out of bounds of buffer view {}", name,
                       si.bufferView));
    }
    if (a.sparse.values.byteOffset < 0 || value_end > value_view.size()) {
      fail(fmt::format("{} sparse values are out of bounds of buffer view {}", name,
                       a.sparse.values.bufferView));
    }
    for (int k = 0; k < n; ++k) {
      const uint8_t* p = &index_view[size_t(si.byteOffset) + size_t(k) * size_t(index_size)];
      uint32_t target = 0;
      if (index_size == 1) {
        target = p[0];
      } else if (index_size == 2) {
        uint16_t v;
        std::memcpy(&v, p, 2);
        target = v;
      } else {
        std::memcpy(&target, p, 4);
      }
      if (target >= a.count) {
        fail(fmt::format("{} has sparse index {} out of range of its {} elements", name, target,
                         a.count));
      }
      std::memcpy(&bytes[size_t(target) * element_size],
                  &value_view[size_t(a.sparse.values.byteOffset) + size_t(k) * element_size],
                  element_size);
    }
  }
  return bytes;
}

namespace {

// One component as glTF defines it: normalized integers map to [0, 1] or [-1, 1].
double component_value(const uint8_t* p, int component_type, bool normalized) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      int8_t v;
      std::memcpy(&v, p, 1);
      return normalized ? std::max(v / 127.0, -1.0) : double(v);
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return normalized ? p[0] / 255.0 : double(p[0]);
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      int16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? std::max(v / 32767.0, -1.0) : double(v);
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? v / 65535.0 : double(v);
    }
    case TINYGLTF_COMPONENT_TYPE_INT: {
      int32_t v;
      std::memcpy(&v, p, 4);
      return normalized ? std::max(v / 2147483647.0, -1.0) : double(v);
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
      uint32_t v;
      std::memcpy(&v, p, 4);
      return normalized ? v / 4294967295.0 : double(v);
    }
    default: {
      float v;
      std::memcpy(&v, p, 4);
      return v;
    }
  }
}

}  // namespace

// EXT_ and KHR_meshopt_compression (one bitstream; KHR adds version 1 of the attribute codec and
// a COLOR filter): every buffer view with the extension is decoded at load through meshoptimizer
// into meshopt_bytes_, `count` elements of `byteStride` bytes (the view's byteLength), then
// filtered; everything after reads it through buffer_view_bytes as if it were in the view's
// buffer. What the extension forbids, data that does not decode, and a codec version or filter
// this meshoptimizer lacks are errors naming the buffer view.
void Loader::decode_meshopt() {
  uint64_t total = 0;
  for (size_t v = 0; v < model_.bufferViews.size(); ++v) {
    const tinygltf::BufferView& bv = model_.bufferViews[v];
    const tinygltf::Value* e = nullptr;
    std::string_view name;
    for (std::string_view ext : gltf_meshopt::kExtensions) {
      if (const auto it = bv.extensions.find(std::string(ext)); it != bv.extensions.end()) {
        e = &it->second;
        name = ext;
        break;
      }
    }
    if (e == nullptr) continue;
    const std::string where = fmt::format("buffer view {} {}", v, name);
    if (!e->IsObject()) fail(where + " is not an object");
    // A non-negative integer property (a JSON number that is one).
    const auto integer = [&](const char* key, std::optional<uint64_t> otherwise) -> uint64_t {
      if (!e->Has(key)) {
        if (otherwise) return *otherwise;
        fail(fmt::format("{} has no \"{}\"", where, key));
      }
      const tinygltf::Value& x = e->Get(key);
      const double d = x.IsNumber() ? x.GetNumberAsDouble() : -1.0;
      if (!(d >= 0.0 && d <= double(uint64_t(1) << 53) && d == std::floor(d))) {
        fail(fmt::format("{} has an invalid \"{}\"", where, key));
      }
      return uint64_t(d);
    };
    const auto text = [&](const char* key, const char* otherwise) -> std::string {
      if (!e->Has(key) && otherwise != nullptr) return otherwise;
      const tinygltf::Value& x = e->Get(key);
      if (!x.IsString()) fail(fmt::format("{} has no valid \"{}\"", where, key));
      return x.Get<std::string>();
    };
    const uint64_t buffer = integer("buffer", std::nullopt);
    const uint64_t offset = integer("byteOffset", 0);
    const uint64_t length = integer("byteLength", std::nullopt);
    const uint64_t stride = integer("byteStride", std::nullopt);
    const uint64_t count = integer("count", std::nullopt);
    const std::string mode = text("mode", nullptr);
    const std::string filter = text("filter", "NONE");

    if (buffer >= model_.buffers.size()) {
      fail(fmt::format("{} refers to buffer {}, but there are {}", where, buffer,
                       model_.buffers.size()));
    }
    if (placeholder_buffers_.count(int(buffer)) != 0) {
      fail(
          fmt::format("{} reads its compressed data from buffer {}, which holds no data (a "
                      "fallback or placeholder buffer)",
                      where, buffer));
    }
    const std::vector<unsigned char>& data = model_.buffers[buffer].data;
    if (length > data.size() || offset > data.size() - length) {
      fail(
          fmt::format("{}: its compressed bytes {} to {} are out of bounds of buffer {} ({} "
                      "bytes)",
                      where, offset, offset + length, buffer, data.size()));
    }
    const bool attributes = mode == "ATTRIBUTES";
    if (!attributes && mode != "TRIANGLES" && mode != "INDICES") {
      fail(fmt::format("{} has mode \"{}\" (ATTRIBUTES, TRIANGLES or INDICES)", where, mode));
    }
    if (attributes && (stride == 0 || stride % 4 != 0 || stride > 256)) {
      fail(fmt::format("{}: ATTRIBUTES need a byteStride of a multiple of 4 up to 256, not {}",
                       where, stride));
    }
    if (!attributes && stride != 2 && stride != 4) {
      fail(fmt::format("{}: {} need a byteStride of 2 or 4, not {}", where, mode, stride));
    }
    if (mode == "TRIANGLES" && count % 3 != 0) {
      fail(fmt::format("{}: TRIANGLES need a count that is a multiple of 3, not {}", where, count));
    }
    if (!attributes && filter != "NONE") {
      fail(fmt::format("{}: {} take no filter, not {}", where, mode, filter));
    }
    if (filter == "COLOR" && name == "KHR_meshopt_compression") {
      fail(
          fmt::format("{} uses the COLOR filter, which afr's meshoptimizer ({}.{}) does not "
                      "decode",
                      where, MESHOPTIMIZER_VERSION / 1000, MESHOPTIMIZER_VERSION % 1000 / 10));
    }
    const bool filter_fits =
        filter == "NONE" || (filter == "OCTAHEDRAL" && (stride == 4 || stride == 8)) ||
        (filter == "QUATERNION" && stride == 8) || (filter == "EXPONENTIAL" && stride % 4 == 0);
    if (filter != "NONE" && filter != "OCTAHEDRAL" && filter != "QUATERNION" &&
        filter != "EXPONENTIAL") {
      fail(fmt::format("{} has filter \"{}\" (NONE, OCTAHEDRAL, QUATERNION or EXPONENTIAL)", where,
                       filter));
    }
    if (!filter_fits) {
      fail(
          fmt::format("{}: the {} filter does not take a byteStride of {}", where, filter, stride));
    }
    if (count > kMaxAccessorCount) {
      fail(fmt::format("{} has {} elements, more than afr accepts", where, count));
    }
    if (count * stride != bv.byteLength) {
      fail(
          fmt::format("{}: count x byteStride is {} x {} = {} bytes, but the buffer view's "
                      "byteLength is {}",
                      where, count, stride, count * stride, bv.byteLength));
    }
    total += count * stride;
    if (total > kMaxFileBytes) {
      fail(
          fmt::format("{}: the file's compressed buffer views decode to more than {} bytes, "
                      "more than afr accepts",
                      where, kMaxFileBytes));
    }

    std::vector<uint8_t> bytes(count * stride);
    const unsigned char* in = data.data() + offset;
    if (attributes && length > 0 && in[0] == 0xa1) {
      fail(
          fmt::format("{} uses version 1 of the attribute codec, which afr's meshoptimizer "
                      "({}.{}) does not decode",
                      where, MESHOPTIMIZER_VERSION / 1000, MESHOPTIMIZER_VERSION % 1000 / 10));
    }
    int result = 0;
    if (count > 0) {
      if (attributes) {
        result = meshopt_decodeVertexBuffer(bytes.data(), count, stride, in, length);
      } else if (mode == "TRIANGLES") {
        result = meshopt_decodeIndexBuffer(bytes.data(), count, stride, in, length);
      } else {
        result = meshopt_decodeIndexSequence(bytes.data(), count, stride, in, length);
      }
    }
    if (result != 0) {
      fail(fmt::format("{}: cannot decode its {} data (meshoptimizer error {})", where, mode,
                       result));
    }
    if (filter == "OCTAHEDRAL") {
      meshopt_decodeFilterOct(bytes.data(), count, stride);
    } else if (filter == "QUATERNION") {
      meshopt_decodeFilterQuat(bytes.data(), count, stride);
    } else if (filter == "EXPONENTIAL") {
      meshopt_decodeFilterExp(bytes.data(), count, stride);
    }
    meshopt_bytes_[int(v)] = std::move(bytes);
  }
}

// KHR_draco_mesh_compression: the primitive's indices and the attributes the extension names are
// decoded from the Draco data in its buffer view (libdraco) into draco_bytes_, as the elements of
// the accessors they stand for, in those accessors' component types; everything after reads
// them through gather() as if they were in a buffer. Attributes the extension does not name are
// read from their own accessors.
void Loader::decode_draco(const tinygltf::Primitive& in, const std::string& what) {
  const auto ext = in.extensions.find("KHR_draco_mesh_compression");
  if (ext == in.extensions.end()) return;
  const std::string where = what + " KHR_draco_mesh_compression";
  const tinygltf::Value& e = ext->second;
  if (!e.IsObject() || !e.Get("bufferView").IsInt() || !e.Get("attributes").IsObject()) {
    fail(where + " has no valid \"bufferView\" and \"attributes\"");
  }
  const std::span<const uint8_t> data =
      buffer_view_bytes(e.Get("bufferView").GetNumberAsInt(), where);
  draco::DecoderBuffer buffer;
  buffer.Init(reinterpret_cast<const char*>(data.data()), data.size());
  draco::Decoder decoder;
  auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
  if (!decoded.ok()) {
    fail(fmt::format("{}: cannot decode its Draco data ({})", where,
                     decoded.status().error_msg_string()));
  }
  const std::unique_ptr<draco::Mesh> mesh = std::move(decoded).value();
  const size_t points = mesh->num_points();
  if (points > kMaxAccessorCount || size_t(mesh->num_faces()) > kMaxAccessorCount) {
    fail(
        fmt::format("{}: its Draco data holds more vertices or triangles than afr accepts", where));
  }
  // The elements of accessor `index` (what the decoded data stands for), `count` of them, each
  // written by value(element, component type, components, out) in the accessor's type.
  const auto store = [&](int index, size_t count, const std::string& part, const auto& value) {
    const tinygltf::Accessor& a = accessor_at(index, where + " " + part);
    if (a.count != count) {
      fail(fmt::format("{} {}: accessor {} has {} elements, but the Draco data {}", where, part,
                       index, a.count, count));
    }
    const int components = tinygltf::GetNumComponentsInType(uint32_t(a.type));
    const int size = tinygltf::GetComponentSizeInBytes(uint32_t(a.componentType));
    if (components <= 0 || size <= 0 || a.componentType == TINYGLTF_COMPONENT_TYPE_DOUBLE) {
      fail(fmt::format("{} {}: accessor {} has an invalid type", where, part, index));
    }
    const size_t element_size = size_t(components) * size_t(size);
    std::vector<uint8_t> bytes(count * element_size);
    for (size_t i = 0; i < count; ++i) {
      value(i, a.componentType, components, &bytes[i * element_size]);
    }
    draco_bytes_[index] = std::move(bytes);
  };
  // An integer value in the component type (it fits: checked by the caller or by the data).
  const auto put_integer = [](uint32_t v, int type, uint8_t* out) {
    if (type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE || type == TINYGLTF_COMPONENT_TYPE_BYTE) {
      *out = uint8_t(v);
    } else if (type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ||
               type == TINYGLTF_COMPONENT_TYPE_SHORT) {
      const uint16_t s = uint16_t(v);
      std::memcpy(out, &s, 2);
    } else {
      std::memcpy(out, &v, 4);
    }
  };
  if (in.indices < 0) fail(where + ": the primitive has no indices, which the extension requires");
  {
    const tinygltf::Accessor& a = accessor_at(in.indices, where + " indices");
    const uint64_t limit = a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE    ? 0xff
                           : a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ? 0xffff
                                                                                       : 0xffffffff;
    if (points > limit + 1) {
      fail(fmt::format("{}: {} vertices do not fit the indices' component type", where, points));
    }
    store(in.indices, 3 * size_t(mesh->num_faces()), "indices",
          [&](size_t i, int type, int, uint8_t* out) {
            const draco::Mesh::Face& f = mesh->face(draco::FaceIndex(uint32_t(i / 3)));
            put_integer(f[i % 3].value(), type, out);
          });
  }
  for (const auto& [name, id] : e.Get("attributes").Get<tinygltf::Value::Object>()) {
    const auto accessor = in.attributes.find(name);
    if (accessor == in.attributes.end()) continue;  // the primitive does not use it
    const draco::PointAttribute* attribute =
        id.IsInt() && id.GetNumberAsInt() >= 0
            ? mesh->GetAttributeByUniqueId(uint32_t(id.GetNumberAsInt()))
            : nullptr;
    if (attribute == nullptr) {
      fail(fmt::format("{}: its attribute {} names no attribute of the Draco data", where, name));
    }
    // glTF's component types; Draco's others (64-bit, bool) have no accessor to fill, and
    // libdraco reads a bool's byte as it is, whatever its value.
    switch (attribute->data_type()) {
      case draco::DT_INT8:
      case draco::DT_UINT8:
      case draco::DT_INT16:
      case draco::DT_UINT16:
      case draco::DT_INT32:
      case draco::DT_UINT32:
      case draco::DT_FLOAT32:
        break;
      default:
        fail(
            fmt::format("{}: its attribute {} has Draco data type {}, which no glTF component "
                        "type matches",
                        where, name, int(attribute->data_type())));
    }
    // Up to four components of each point's value (the accessor's beyond the data's are 0).
    const int8_t available = int8_t(std::min(int(attribute->num_components()), 4));
    store(accessor->second, points, name, [&](size_t i, int type, int components, uint8_t* out) {
      const draco::AttributeValueIndex v = attribute->mapped_index(draco::PointIndex(uint32_t(i)));
      const size_t size = size_t(tinygltf::GetComponentSizeInBytes(uint32_t(type)));
      if (type == TINYGLTF_COMPONENT_TYPE_FLOAT) {
        float values[4] = {};
        attribute->ConvertValue<float>(v, available, values);
        std::memcpy(out, values, size_t(std::min(components, 4)) * size);
      } else {
        int32_t values[4] = {};
        attribute->ConvertValue<int32_t>(v, available, values);
        for (int c = 0; c < std::min(components, 4); ++c) {
          put_integer(uint32_t(values[c]), type, out + size_t(c) * size);
        }
      }
    });
  }
}

// Components of accessor `index`, which must be of `type`, as floats; all finite.
std::vector<float> Loader::read_floats(int index, int type, const std::string& what) {
  const tinygltf::Accessor* a = nullptr;
  const std::vector<uint8_t> bytes = gather(index, type, what, &a);
  const size_t component_size = size_t(tinygltf::GetComponentSizeInBytes(a->componentType));
  const size_t n = bytes.size() / component_size;
  std::vector<float> values(n);
  for (size_t i = 0; i < n; ++i) {
    const double v = component_value(&bytes[i * component_size], a->componentType, a->normalized);
    if (!std::isfinite(v)) {
      fail(fmt::format("accessor {} ({}) holds a NaN or infinite value at element {}", index, what,
                       i / size_t(tinygltf::GetNumComponentsInType(a->type))));
    }
    values[i] = float(v);
  }
  return values;
}

std::vector<uint32_t> Loader::read_indices(int index, const std::string& what) {
  const tinygltf::Accessor* a = nullptr;
  const std::vector<uint8_t> bytes = gather(index, TINYGLTF_TYPE_SCALAR, what, &a);
  std::vector<uint32_t> indices(a->count);
  switch (a->componentType) {
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      for (size_t i = 0; i < indices.size(); ++i) indices[i] = bytes[i];
      break;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      for (size_t i = 0; i < indices.size(); ++i) {
        uint16_t v;
        std::memcpy(&v, &bytes[2 * i], 2);
        indices[i] = v;
      }
      break;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
      if (!indices.empty()) std::memcpy(indices.data(), bytes.data(), 4 * indices.size());
      break;
    default:
      fail(fmt::format("accessor {} ({}) has componentType {}, not an unsigned integer type", index,
                       what, a->componentType));
  }
  return indices;
}

// JOINTS_0: four unsigned bytes or shorts per vertex (glTF 2.0, 3.7.3.1).
std::vector<std::array<uint16_t, 4>> Loader::read_joints(int index, const std::string& what) {
  const tinygltf::Accessor* a = nullptr;
  const std::vector<uint8_t> bytes = gather(index, TINYGLTF_TYPE_VEC4, what, &a);
  const bool bytes_type = a->componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
  if ((!bytes_type && a->componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT) ||
      a->normalized) {
    fail(fmt::format(
        "accessor {} ({}) has componentType {}{}, not unsigned bytes or shorts as joints must be",
        index, what, a->componentType, a->normalized ? " (normalized)" : ""));
  }
  std::vector<std::array<uint16_t, 4>> joints(a->count);
  for (size_t v = 0; v < joints.size(); ++v) {
    for (size_t c = 0; c < 4; ++c) {
      if (bytes_type) {
        joints[v][c] = bytes[4 * v + c];
      } else {
        std::memcpy(&joints[v][c], &bytes[2 * (4 * v + c)], 2);
      }
    }
  }
  return joints;
}

// A VEC3 attribute of `count` elements.
std::vector<glm::vec3> Loader::read_vec3s(int index, size_t count, const std::string& attribute,
                                          const std::string& what) {
  const std::vector<float> f = read_floats(index, TINYGLTF_TYPE_VEC3, what + " " + attribute);
  if (f.size() != 3 * count) {
    fail(fmt::format("{} has {} {} values for {} positions", what, f.size() / 3, attribute, count));
  }
  std::vector<glm::vec3> v(count);
  for (size_t i = 0; i < count; ++i) v[i] = {f[3 * i], f[3 * i + 1], f[3 * i + 2]};
  return v;
}

}  // namespace afr::gltf_detail
