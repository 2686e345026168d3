// A C interface to the reference Draco decoder (Debian's libdraco-dev), for
// `hlod_builder::import::draco`: decode a stream into a mesh, then read its
// faces and its attributes' raw values by point. Every C++ exception (an
// allocation a damaged stream asks for, among them) becomes an error here;
// nothing is thrown across the interface.
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>

#include "draco/compression/decode.h"

namespace {

void say(char *err, size_t cap, const std::string &msg) {
  if (cap == 0) return;
  size_t n = msg.size() < cap - 1 ? msg.size() : cap - 1;
  std::memcpy(err, msg.data(), n);
  err[n] = 0;
}

const draco::Mesh *mesh_of(const void *m) {
  return static_cast<const draco::Mesh *>(m);
}

}  // namespace

extern "C" {

// Decodes `len` bytes; on success stores the mesh in `*out` and returns 0,
// else writes a message into `err` (at most `cap` bytes, terminated) and
// returns 1.
int hlod_draco_decode(const uint8_t *data, size_t len, void **out, char *err,
                      size_t cap) {
  *out = nullptr;
  try {
    draco::DecoderBuffer buffer;
    buffer.Init(reinterpret_cast<const char *>(data), len);
    draco::Decoder decoder;
    auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
    if (!decoded.ok()) {
      say(err, cap, decoded.status().error_msg_string());
      return 1;
    }
    std::unique_ptr<draco::Mesh> mesh = std::move(decoded).value();
    if (!mesh) {
      say(err, cap, "not a mesh");
      return 1;
    }
    *out = mesh.release();
    return 0;
  } catch (const std::exception &e) {
    say(err, cap, std::string("decoder failed: ") + e.what());
  } catch (...) {
    say(err, cap, "decoder failed");
  }
  return 1;
}

void hlod_draco_free(void *m) { delete static_cast<draco::Mesh *>(m); }

uint32_t hlod_draco_num_faces(const void *m) {
  return mesh_of(m)->num_faces();
}

uint32_t hlod_draco_num_points(const void *m) {
  return mesh_of(m)->num_points();
}

// The faces' point indices, three a face, into `out` (3 × num_faces).
void hlod_draco_faces(const void *m, uint32_t *out) {
  const draco::Mesh *mesh = mesh_of(m);
  for (uint32_t f = 0; f < mesh->num_faces(); ++f) {
    const draco::Mesh::Face &face = mesh->face(draco::FaceIndex(f));
    for (int k = 0; k < 3; ++k) out[3 * f + k] = face[k].value();
  }
}

// The attribute of unique id `uid`: its components and Draco data type
// (`draco::DataType`) and the bytes of one component; 0 when there is none.
int hlod_draco_attribute(const void *m, uint32_t uid, int *components,
                         int *data_type, int *component_bytes) {
  const draco::PointAttribute *a = mesh_of(m)->GetAttributeByUniqueId(uid);
  if (a == nullptr) return 0;
  *components = a->num_components();
  *data_type = a->data_type();
  *component_bytes = draco::DataTypeLength(a->data_type());
  return 1;
}

// Each point's value of attribute `uid`, its bytes as stored, into `out`
// (num_points × components × component bytes); 1 when a point names a
// value the attribute does not have, else 0.
int hlod_draco_values(const void *m, uint32_t uid, uint8_t *out) {
  const draco::Mesh *mesh = mesh_of(m);
  const draco::PointAttribute *a = mesh->GetAttributeByUniqueId(uid);
  if (a == nullptr) return 1;
  if (!a->is_mapping_identity() && a->indices_map_size() < mesh->num_points())
    return 1;
  const size_t stride =
      size_t(a->num_components()) * draco::DataTypeLength(a->data_type());
  for (uint32_t p = 0; p < mesh->num_points(); ++p) {
    const draco::AttributeValueIndex v = a->mapped_index(draco::PointIndex(p));
    if (v.value() >= a->size()) return 1;
    a->GetValue(v, out + size_t(p) * stride);
  }
  return 0;
}

}  // extern "C"
