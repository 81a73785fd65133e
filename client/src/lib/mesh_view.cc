/// @brief MeshView: latest Draco chunk per key, decoded on demand.
#include "sculpt/client/mesh_view.h"

#include "sculpt/mesh/draco_chunk_codec.h"

namespace sculpt::client {

MeshView::MeshView(Client& client, std::string object, bool decode_on_receipt)
    : client_(client), object_(std::move(object)), decode_(decode_on_receipt) {
  client_.SetReplicationHandler([this](v1::ServerMessage&& m) { OnMessage(std::move(m)); });
}

MeshView::~MeshView() { client_.SetReplicationHandler(nullptr); }

Status MeshView::Subscribe(double max_rate_hz) {
  v1::ClientMessage m;
  m.mutable_viewer_subscribe()->set_object(object_);
  m.mutable_viewer_subscribe()->set_max_rate_hz(static_cast<float>(max_rate_hz));
  return client_.SendMessage(m);
}

void MeshView::OnMessage(v1::ServerMessage&& m) {
  if (!m.has_mesh_chunk() || m.mesh_chunk().object() != object_) return;
  v1::MeshChunk& c = *m.mutable_mesh_chunk();
  if (c.key_size() != 3) return;
  double decode_ms = -1;
  if (decode_ && !c.draco().empty()) {
    // On the I/O thread: a viewer that decodes pays for it there, as a real one would.
    auto d = mesh::DecodeChunk(c.draco());
    if (d.ok()) decode_ms = d->decode_ms;
  }
  std::lock_guard<std::mutex> lock(mu_);
  ++stats_.chunks_received;
  stats_.bytes += c.draco().size();
  stats_.max_version = std::max(stats_.max_version, c.version());
  stats_.encode_ms.push_back(c.encode_ms());
  if (decode_ms >= 0) stats_.decode_ms.push_back(decode_ms);
  const std::array<int, 3> key{c.key(0), c.key(1), c.key(2)};
  Chunk& slot = chunks_[key];
  if (c.version() < slot.version) return;  // an older update overtaken (never on one stream)
  slot.version = c.version();
  slot.faces = c.faces();
  slot.draco = std::move(*c.mutable_draco());
  if (slot.draco.empty()) chunks_.erase(key);
}

StatusOr<mesh::TriangleMesh> MeshView::Assemble() const {
  std::lock_guard<std::mutex> lock(mu_);
  mesh::TriangleMesh out;
  std::vector<mesh::TriangleMesh> parts;
  bool coloured = !chunks_.empty();
  for (const auto& [key, c] : chunks_) {
    auto d = mesh::DecodeChunk(c.draco);
    if (!d.ok()) return d.status();
    coloured = coloured && d->mesh.colours.size() == d->mesh.positions.size();
    parts.push_back(std::move(d->mesh));
  }
  // Colours only when every chunk has them (a scene with materials): one attribute or none.
  for (const mesh::TriangleMesh& m : parts) {
    const uint32_t base = static_cast<uint32_t>(out.vertex_count());
    out.positions.insert(out.positions.end(), m.positions.begin(), m.positions.end());
    if (coloured) out.colours.insert(out.colours.end(), m.colours.begin(), m.colours.end());
    for (uint32_t i : m.indices) out.indices.push_back(base + i);
  }
  return out;
}

uint64_t MeshView::FaceCount() const {
  std::lock_guard<std::mutex> lock(mu_);
  uint64_t n = 0;
  for (const auto& [key, c] : chunks_) n += c.faces;
  return n;
}

size_t MeshView::ChunkCount() const {
  std::lock_guard<std::mutex> lock(mu_);
  return chunks_.size();
}

MeshViewStats MeshView::stats() const {
  std::lock_guard<std::mutex> lock(mu_);
  return stats_;
}

}  // namespace sculpt::client
