/// @brief StaticFiles: safe lookup of the web client's files.
#include "net/static_files.h"

#include <array>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <system_error>
#include <utility>

namespace sculpt::server {
namespace {

namespace fs = std::filesystem;

int HexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// Percent-decodes a path; InvalidArgument for a truncated or non-hex escape.
StatusOr<std::string> PercentDecode(std::string_view in) {
  std::string out;
  out.reserve(in.size());
  for (size_t i = 0; i < in.size(); ++i) {
    if (in[i] != '%') {
      out += in[i];
      continue;
    }
    const bool complete = i + 2 < in.size();
    const int hi = complete ? HexValue(in[i + 1]) : -1;
    const int lo = complete ? HexValue(in[i + 2]) : -1;
    if (hi < 0 || lo < 0) {
      return Outside("path", std::string(in), "percent-encoded paths");
    }
    out += static_cast<char>(hi * 16 + lo);
    i += 2;
  }
  return out;
}

bool EndsWith(std::string_view s, std::string_view suffix) {
  return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

}  // namespace

StaticFiles::StaticFiles(std::filesystem::path root) : root_(std::move(root)) {}

bool StaticFiles::root_exists() const {
  std::error_code ec;
  return !root_.empty() && fs::is_directory(root_, ec);
}

std::string_view StaticFiles::ContentType(std::string_view name) {
  static constexpr std::array<std::pair<std::string_view, std::string_view>, 13> kTypes = {{
      {".html", "text/html; charset=utf-8"},
      {".js", "text/javascript; charset=utf-8"},
      {".mjs", "text/javascript; charset=utf-8"},
      {".css", "text/css; charset=utf-8"},
      {".wasm", "application/wasm"},
      {".png", "image/png"},
      {".json", "application/json"},
      {".svg", "image/svg+xml"},
      {".ico", "image/x-icon"},
      {".map", "application/json"},
      {".txt", "text/plain; charset=utf-8"},
      {".jpg", "image/jpeg"},
      {".webp", "image/webp"},
  }};
  for (const auto& [ext, type] : kTypes) {
    if (EndsWith(name, ext)) return type;
  }
  return "application/octet-stream";
}

StatusOr<StaticFile> StaticFiles::Lookup(std::string_view target) const {
  const size_t query = target.find_first_of("?#");
  if (query != std::string_view::npos) target = target.substr(0, query);
  if (target.empty() || target[0] != '/') {
    return Outside("path", std::string(target), "absolute paths");
  }
  SCULPT_ASSIGN_OR_RETURN(std::string path, PercentDecode(target));
  if (path.back() == '/') path += "index.html";
  // Each segment is a plain name: nothing that could climb out of the root or name a device.
  fs::path relative;
  size_t start = 1;
  while (start <= path.size()) {
    const size_t end = std::min(path.find('/', start), path.size());
    const std::string segment = path.substr(start, end - start);
    if (segment.empty() || segment == "." || segment == ".." ||
        segment.find('\0') != std::string::npos || segment.find('\\') != std::string::npos) {
      return Outside("path", std::string(target),
                     "paths of plain names (no empty, \".\" or \"..\" segment, NUL or backslash)");
    }
    relative /= segment;
    start = end + 1;
  }
  if (!root_exists()) {
    return NotFound("web root=" + root_.string() +
                    " does not exist: build the web client (client/web) or pass --web-root");
  }
  const fs::path file = root_ / relative;
  std::error_code ec;
  const fs::file_status st = fs::status(file, ec);
  if (ec || !fs::is_regular_file(st)) {
    return Outside("path", std::string(target), std::string("the files of ") + root_.string(),
                   Status::Code::kNotFound);
  }
  const uint64_t size = fs::file_size(file, ec);
  if (ec) return Internal("stat " + file.string() + ": " + ec.message());
  if (size > kMaxStaticFileBytes) {
    return Outside("file size", std::to_string(size),
                   std::string("[0, ") + std::to_string(kMaxStaticFileBytes) + "] bytes",
                   Status::Code::kResourceExhausted);
  }
  const auto mtime = fs::last_write_time(file, ec);
  StaticFile out;
  out.body.resize(size);
  std::ifstream in(file, std::ios::binary);
  if (!in.read(out.body.data(), static_cast<std::streamsize>(size))) {
    return Internal("read " + file.string() + " failed");
  }
  out.content_type = std::string(ContentType(file.filename().string()));
  char etag[64];
  std::snprintf(etag, sizeof etag, "\"%llx-%llx\"", static_cast<unsigned long long>(size),
                static_cast<unsigned long long>(mtime.time_since_epoch().count()));
  out.etag = etag;
  // Bundlers put content-hashed names under assets/: they never change. Everything else (the
  // page, the decoder) is revalidated with the ETag each time.
  const bool hashed = path.rfind("/assets/", 0) == 0;
  out.cache_control = hashed ? "public, max-age=31536000, immutable" : "no-cache";
  return out;
}

}  // namespace sculpt::server
