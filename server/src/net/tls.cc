/// @brief The OpenSSL server context of sculptd's TLS ports.
#include "net/tls.h"

#include <openssl/err.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <filesystem>

namespace sculpt::server {

Status CheckReadable(const char* key, const std::string& file) {
  std::error_code ec;
  if (!std::filesystem::exists(file, ec)) {
    return InvalidArgument(std::string(key) + "=" + file + ": no such file");
  }
  if (std::filesystem::is_directory(file, ec)) {
    return InvalidArgument(std::string(key) + "=" + file + ": is a directory, not a PEM file");
  }
  FILE* f = std::fopen(file.c_str(), "rb");
  if (!f) return InvalidArgument(std::string(key) + "=" + file + ": not readable");
  std::fclose(f);
  return Status::Ok();
}

std::string TakeOpenSslError(const std::string& fallback) {
  unsigned long last = 0;
  while (unsigned long e = ERR_get_error()) last = e;
  if (last == 0) return fallback;
  char buf[256];
  ERR_error_string_n(last, buf, sizeof buf);
  const char* reason = ERR_reason_error_string(last);
  return reason ? std::string(reason) : std::string(buf);
}

std::string DescribeHandshakeError(const boost::system::error_code& ec) {
  std::string text = ec.message();
  if (ec.category() == asio::error::get_ssl_category()) {
    const int reason = ERR_GET_REASON(static_cast<unsigned long>(ec.value()));
    if (reason == SSL_R_WRONG_VERSION_NUMBER || reason == SSL_R_HTTP_REQUEST ||
        reason == SSL_R_UNKNOWN_PROTOCOL) {
      text += " (plaintext on the TLS port?)";
    }
  }
  return text;
}

StatusOr<std::shared_ptr<ssl::context>> MakeServerTlsContext(const TlsConfig& tls,
                                                             bool require_client_certs) {
  if (!tls.enabled()) return InvalidArgument("tls.cert_file is empty: TLS is off");
  SCULPT_RETURN_IF_ERROR(CheckReadable("tls.cert_file", tls.cert_file));
  SCULPT_RETURN_IF_ERROR(CheckReadable("tls.key_file", tls.key_file));
  const bool client_certs = require_client_certs && !tls.client_ca_file.empty();
  if (client_certs) SCULPT_RETURN_IF_ERROR(CheckReadable("tls.client_ca_file", tls.client_ca_file));

  ERR_clear_error();
  auto ctx = std::make_shared<ssl::context>(ssl::context::tls_server);
  SSL_CTX* native = ctx->native_handle();
  SSL_CTX_set_min_proto_version(native, TLS1_2_VERSION);
  // No renegotiation (a renegotiation flood costs the server a handshake each), no compression.
  SSL_CTX_set_options(native, SSL_OP_NO_COMPRESSION | SSL_OP_NO_RENEGOTIATION |
                                  SSL_OP_CIPHER_SERVER_PREFERENCE);
  if (SSL_CTX_set_cipher_list(native, kTls12Ciphers) != 1 ||
      SSL_CTX_set_ciphersuites(native, kTls13Suites) != 1) {
    return Internal("OpenSSL refused the cipher list: " + TakeOpenSslError("unknown"));
  }
  if (SSL_CTX_use_certificate_chain_file(native, tls.cert_file.c_str()) != 1) {
    return InvalidArgument("tls.cert_file=" + tls.cert_file + ": not a PEM certificate (" +
                           TakeOpenSslError("unreadable") + ")");
  }
  // OpenSSL compares the key with the certificate as it loads it ("key values mismatch").
  const bool key_loaded =
      SSL_CTX_use_PrivateKey_file(native, tls.key_file.c_str(), SSL_FILETYPE_PEM) == 1;
  const std::string key_error = key_loaded ? "" : TakeOpenSslError("unreadable");
  if (!key_loaded && key_error != "key values mismatch") {
    return InvalidArgument("tls.key_file=" + tls.key_file +
                           ": not an unencrypted PEM private key (" + key_error + ")");
  }
  if (!key_loaded || SSL_CTX_check_private_key(native) != 1) {
    return InvalidArgument("tls.key_file=" + tls.key_file +
                           " does not match the certificate in tls.cert_file=" + tls.cert_file +
                           " (" + (key_error.empty() ? TakeOpenSslError("key mismatch") : key_error) +
                           ")");
  }
  if (X509* cert = SSL_CTX_get0_certificate(native)) {
    if (X509_cmp_current_time(X509_get0_notAfter(cert)) < 0) {
      spdlog::warn("tls.cert_file={}: the certificate has expired; clients will refuse it",
                   tls.cert_file);
    }
  }
  if (client_certs) {
    if (SSL_CTX_load_verify_locations(native, tls.client_ca_file.c_str(), nullptr) != 1) {
      return InvalidArgument("tls.client_ca_file=" + tls.client_ca_file +
                             ": not a PEM CA certificate (" + TakeOpenSslError("unreadable") + ")");
    }
    if (STACK_OF(X509_NAME)* names = SSL_load_client_CA_file(tls.client_ca_file.c_str())) {
      SSL_CTX_set_client_CA_list(native, names);
    }
    SSL_CTX_set_verify(native, SSL_VERIFY_PEER | SSL_VERIFY_FAIL_IF_NO_PEER_CERT, nullptr);
  }
  // Resumed sessions must be tied to this server's verification settings.
  static constexpr unsigned char kSessionContext[] = "sculptd";
  SSL_CTX_set_session_id_context(native, kSessionContext, sizeof kSessionContext - 1);
  ERR_clear_error();
  return ctx;
}

}  // namespace sculpt::server
