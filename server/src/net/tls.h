/// @brief TLS for sculptd's ports: the OpenSSL server context (TLS 1.2+, ECDHE with AEAD ciphers
/// only, optional client certificates) built from the configuration's files.
#ifndef SCULPT_SERVER_NET_TLS_H_
#define SCULPT_SERVER_NET_TLS_H_

#include <memory>
#include <string>

#include "config/server_config.h"
#include "net/net.h"

#include <boost/asio/ssl.hpp>

namespace sculpt::server {

namespace ssl = boost::asio::ssl;

/// TLS 1.2 suites allowed: forward-secret key exchange (ECDHE) and AEAD ciphers only; no RSA key
/// exchange, no CBC. TLS 1.3's suites are all of that kind.
inline constexpr char kTls12Ciphers[] =
    "ECDHE-ECDSA-AES128-GCM-SHA256:ECDHE-RSA-AES128-GCM-SHA256:"
    "ECDHE-ECDSA-AES256-GCM-SHA384:ECDHE-RSA-AES256-GCM-SHA384:"
    "ECDHE-ECDSA-CHACHA20-POLY1305:ECDHE-RSA-CHACHA20-POLY1305";
inline constexpr char kTls13Suites[] =
    "TLS_AES_128_GCM_SHA256:TLS_AES_256_GCM_SHA384:TLS_CHACHA20_POLY1305_SHA256";

/// A server context for `tls` (which must be enabled()). With `require_client_certs` and a
/// client_ca_file, a client must present a certificate signed by one of its CAs. Returns
/// InvalidArgument naming the key and the file for a file that is missing, unreadable or not
/// PEM, and for a key that does not match the certificate.
StatusOr<std::shared_ptr<ssl::context>> MakeServerTlsContext(const TlsConfig& tls,
                                                             bool require_client_certs);

/// The newest OpenSSL error queued on this thread as text (and the queue cleared), or
/// `fallback` when there is none.
std::string TakeOpenSslError(const std::string& fallback);

/// Whether a PEM file a TLS context will load exists and opens for reading: InvalidArgument
/// naming `key` (the setting) and the file otherwise.
Status CheckReadable(const char* key, const std::string& file);

/// A TLS handshake failure as a log line says it ("wrong version number (plaintext on the TLS
/// port?)").
std::string DescribeHandshakeError(const boost::system::error_code& ec);

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_TLS_H_
