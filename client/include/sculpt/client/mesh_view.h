/// @brief MeshView: a viewer's copy of an object's mesh as Draco chunks from sculptd (issue 4).
#ifndef SCULPT_CLIENT_MESH_VIEW_H_
#define SCULPT_CLIENT_MESH_VIEW_H_

#include <array>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "sculpt/client/client.h"
#include "sculpt/core/status.h"
#include "sculpt/mesh/triangle_mesh.h"

namespace sculpt::client {

struct MeshViewStats {
  uint64_t chunks_received = 0;
  uint64_t bytes = 0;            // Draco payload bytes
  uint64_t max_version = 0;      // highest chunk version seen
  std::vector<double> decode_ms; // when decoding on receipt
  std::vector<double> encode_ms; // the server's per-chunk figures
};

/// Attach to a joined Client (it takes the client's replication handler), then Subscribe.
/// Chunks are kept as received (latest version per key); Assemble decodes them.
class MeshView {
 public:
  MeshView(Client& client, std::string object, bool decode_on_receipt = false);
  ~MeshView();
  MeshView(const MeshView&) = delete;
  MeshView& operator=(const MeshView&) = delete;

  Status Subscribe(double max_rate_hz = 0);
  /// Every chunk decoded and concatenated (vertices not welded across chunks), with per-vertex
  /// colours when every chunk carries them.
  StatusOr<mesh::TriangleMesh> Assemble() const;
  /// Faces over all chunks, from the chunk headers (no decode).
  uint64_t FaceCount() const;
  size_t ChunkCount() const;
  MeshViewStats stats() const;

 private:
  void OnMessage(v1::ServerMessage&& m);
  struct Chunk {
    uint64_t version = 0;
    std::string draco;
    uint32_t faces = 0;
  };
  Client& client_;
  std::string object_;
  bool decode_;
  mutable std::mutex mu_;
  std::map<std::array<int, 3>, Chunk> chunks_;
  MeshViewStats stats_;
};

}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_MESH_VIEW_H_
