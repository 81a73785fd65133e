/// @brief The TLS flags shared by the `sculpt` subcommands that connect and by sculpt-loadgen:
/// --tls, --ca, --tls-server-name, --tls-cert, --tls-key, --tls-no-verify-name.
#ifndef SCULPT_CLIENT_TLS_FLAGS_H_
#define SCULPT_CLIENT_TLS_FLAGS_H_

#include <CLI/CLI.hpp>

#include "sculpt/client/client.h"

namespace sculpt::client {

/// Adds the flags to `cmd`; any of them turns TLS on. `tls` must outlive parsing.
inline void AddTlsFlags(CLI::App& cmd, ClientTlsOptions* tls) {
  auto on = [tls](const std::string&) { tls->enabled = true; };
  cmd.add_flag_callback("--tls", [tls] { tls->enabled = true; },
                        "Connect over TLS (a sculptd with tls.cert_file)");
  cmd.add_option("--ca", tls->ca_file,
                 "PEM CA file the server's certificate must chain to (implies --tls; default: "
                 "the system's trust store)")
      ->check(CLI::ExistingFile)
      ->each(on);
  cmd.add_option("--tls-server-name", tls->server_name,
                 "Name the server's certificate must carry, and SNI (default: the --server host)")
      ->each(on);
  cmd.add_option("--tls-cert", tls->cert_file,
                 "PEM client certificate, for a sculptd with tls.client_ca_file (implies --tls)")
      ->check(CLI::ExistingFile)
      ->each(on);
  cmd.add_option("--tls-key", tls->key_file, "PEM key of --tls-cert")
      ->check(CLI::ExistingFile)
      ->each(on);
  cmd.add_flag_callback("--tls-no-verify-name", [tls] { tls->verify_server_name = false; },
                        "Accept a valid certificate for any name (the chain is still checked)");
}

}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_TLS_FLAGS_H_
