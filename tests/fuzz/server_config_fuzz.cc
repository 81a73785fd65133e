/// @brief libFuzzer target for the TOML scene/server file: LoadConfigFile on arbitrary text, then
/// ValidateConfig on whatever it accepted; ParseHostPort on the same bytes.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "config/server_config.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  namespace fs = std::filesystem;
  namespace server = sculpt::server;
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::string host;
  uint16_t port = 0;
  (void)server::ParseHostPort(text, &host, &port);

  const fs::path base = fs::exists("/dev/shm") ? fs::path("/dev/shm") : fs::temp_directory_path();
  const fs::path path = base / ("sculpt-fuzz-config-" + std::to_string(getpid()) + ".toml");
  {
    std::ofstream out(path, std::ios::binary);
    out << text;
  }
  server::ServerConfig config;
  if (server::LoadConfigFile(path.string(), &config).ok()) {
    (void)server::ValidateConfig(config);
  }
  fs::remove(path);
  return 0;
}
