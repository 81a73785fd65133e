/// @brief StaticFiles: the web client's files under a root directory, looked up from an HTTP
/// request path without ever leaving the root, with content type and caching headers.
#ifndef SCULPT_SERVER_NET_STATIC_FILES_H_
#define SCULPT_SERVER_NET_STATIC_FILES_H_

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include "sculpt/core/status.h"

namespace sculpt::server {

/// One file ready to serve.
struct StaticFile {
  std::string body;
  std::string content_type;
  std::string etag;           // a strong validator: size and modification time
  std::string cache_control;  // immutable for hashed build assets, else revalidate
};

/// Largest file served (the Draco decoder is 286 KB; bundles are a few MB at most).
inline constexpr uint64_t kMaxStaticFileBytes = 64ull << 20;

/// Read-only view of a web root. Thread safety: const methods may run concurrently.
class StaticFiles {
 public:
  /// `root` need not exist: every lookup then answers NotFound naming it.
  explicit StaticFiles(std::filesystem::path root);

  /// The file for a request path ("/", "/assets/index-3f2a.js", query ignored). "/" and a path
  /// ending in "/" mean its index.html. InvalidArgument for a path that is not absolute, has a
  /// bad percent escape, a NUL, a backslash, or a "." / ".." / empty segment; NotFound for a
  /// missing root, a missing file or anything but a regular file; ResourceExhausted above
  /// kMaxStaticFileBytes; Internal for a read error.
  StatusOr<StaticFile> Lookup(std::string_view target) const;

  const std::filesystem::path& root() const { return root_; }
  bool root_exists() const;

  /// Content type of a file name by its extension; application/octet-stream when unknown.
  static std::string_view ContentType(std::string_view file_name);

 private:
  std::filesystem::path root_;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_STATIC_FILES_H_
