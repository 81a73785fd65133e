/// @brief EtcdClient over etcd's v3 HTTP/JSON gateway: base64 keys and values, int64 as strings.
#include "cluster/etcd_client.h"

#include <openssl/err.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>
#include <openssl/x509v3.h>
#include <sodium.h>

#include <boost/asio/redirect_error.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/asio/ssl/host_name_verification.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "net/tls.h"

// Every call of a coroutine is made in its own statement and its awaitable then awaited
// (`auto x_call = F(args); auto x = co_await std::move(x_call);`): g++ 12 destroys temporaries
// of a co_await expression's arguments twice (heap corruption seen with a braced PutOp).
namespace sculpt::server::cluster {
namespace {

namespace beast = boost::beast;
namespace http = boost::beast::http;
using Json = nlohmann::json;

// A gateway answer is small (a few keys); a bound keeps a confused peer from growing memory.
constexpr uint64_t kMaxAnswerBytes = 4u << 20;

std::string Base64(const std::string& bytes) {
  std::string out(sodium_base64_ENCODED_LEN(bytes.size(), sodium_base64_VARIANT_ORIGINAL), '\0');
  sodium_bin2base64(out.data(), out.size(), reinterpret_cast<const unsigned char*>(bytes.data()),
                    bytes.size(), sodium_base64_VARIANT_ORIGINAL);
  out.resize(out.size() - 1);  // the terminating NUL
  return out;
}

StatusOr<std::string> FromBase64(const std::string& field, const std::string& text) {
  std::string out(text.size() / 4 * 3 + 3, '\0');
  size_t len = 0;
  if (sodium_base642bin(reinterpret_cast<unsigned char*>(out.data()), out.size(), text.data(),
                        text.size(), nullptr, &len, nullptr, sodium_base64_VARIANT_ORIGINAL) != 0) {
    return Outside(field, text.substr(0, 64), "base64", Status::Code::kInternal);
  }
  out.resize(len);
  return out;
}

// The gateway writes int64 as JSON strings and leaves out fields at their default (0, false).
int64_t Int(const Json& j, const char* key) {
  const auto it = j.find(key);
  if (it == j.end()) return 0;
  if (it->is_number_integer()) return it->get<int64_t>();
  if (it->is_string()) {
    try {
      return std::stoll(it->get<std::string>());
    } catch (const std::exception&) {
      return 0;
    }
  }
  return 0;
}

StatusOr<KeyValue> ToKeyValue(const Json& j) {
  KeyValue kv;
  SCULPT_ASSIGN_OR_RETURN(kv.key, FromBase64("kv.key", j.value("key", std::string())));
  SCULPT_ASSIGN_OR_RETURN(kv.value, FromBase64("kv.value", j.value("value", std::string())));
  kv.create_revision = Int(j, "create_revision");
  kv.mod_revision = Int(j, "mod_revision");
  kv.version = Int(j, "version");
  kv.lease = Int(j, "lease");
  return kv;
}

StatusOr<std::vector<KeyValue>> ToKeyValues(const Json& range_answer) {
  std::vector<KeyValue> out;
  const auto it = range_answer.find("kvs");
  if (it == range_answer.end()) return out;
  if (!it->is_array()) return Internal("etcd range answer: kvs is not an array");
  for (const Json& kv : *it) {
    SCULPT_ASSIGN_OR_RETURN(KeyValue v, ToKeyValue(kv));
    out.push_back(std::move(v));
  }
  return out;
}

StatusOr<Json> Parse(const std::string& target, const std::string& body) {
  Json j = Json::parse(body, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object()) {
    return Internal("etcd " + target + ": the answer is not a JSON object: " + body.substr(0, 200));
  }
  return j;
}

// etcd's errors carry a gRPC code; the nearest Status code keeps the caller's decisions simple.
Status FromGrpc(int64_t code, const std::string& message) {
  switch (code) {
    case 3:
      return InvalidArgument("etcd: " + message);
    case 5:
      return NotFound("etcd: " + message);
    case 9:
      return FailedPrecondition("etcd: " + message);
    case 8:
      return ResourceExhausted("etcd: " + message);
    case 14:
    case 4:
      return Status(Status::Code::kUnavailable, "etcd: " + message);
    default:
      return Internal("etcd (gRPC code " + std::to_string(code) + "): " + message);
  }
}

std::string RangeBody(const std::string& key, const std::string& range_end) {
  Json j = {{"key", Base64(key)}};
  if (!range_end.empty()) j["range_end"] = Base64(range_end);
  return j.dump();
}

// The bodies and answers of each call. Kept out of the coroutines: g++ 12 miscompiles string
// literals handed to nlohmann's templates inside a coroutine ("array used as initializer").

std::string GrantBody(int64_t seconds) { return Json{{"TTL", seconds}}.dump(); }

std::string LeaseIdBody(int64_t lease) { return Json{{"ID", std::to_string(lease)}}.dump(); }

std::string PutBody(const PutOp& put) {
  Json j = {{"key", Base64(put.key)}, {"value", Base64(put.value)}};
  if (put.lease != 0) j["lease"] = std::to_string(put.lease);
  return j.dump();
}

std::string TxnBody(const TxnRequest& txn) {
  Json compares = Json::array();
  for (const Compare& c : txn.compares) {
    const bool create = c.target == Compare::Target::kCreateRevision;
    compares.push_back({{"key", Base64(c.key)},
                        {"result", "EQUAL"},
                        {"target", create ? "CREATE" : "MOD"},
                        {create ? "create_revision" : "mod_revision", std::to_string(c.revision)}});
  }
  Json success = Json::array();
  for (const PutOp& p : txn.success) success.push_back({{"request_put", Json::parse(PutBody(p))}});
  for (const std::string& k : txn.success_deletes) {
    success.push_back({{"request_delete_range", {{"key", Base64(k)}}}});
  }
  Json failure = Json::array();
  for (const std::string& k : txn.failure_ranges) {
    failure.push_back({{"request_range", {{"key", Base64(k)}}}});
  }
  return Json{{"compare", compares}, {"success", success}, {"failure", failure}}.dump();
}

StatusOr<Lease> ParseGrant(const std::string& body) {
  SCULPT_ASSIGN_OR_RETURN(Json j, Parse("/v3/lease/grant", body));
  if (const std::string e = j.value("error", std::string()); !e.empty()) {
    return Internal("etcd lease grant: " + e);
  }
  Lease lease{Int(j, "ID"), std::chrono::seconds(Int(j, "TTL"))};
  if (lease.id == 0 || lease.ttl.count() <= 0) {
    return Internal("etcd lease grant answered no lease: " + body.substr(0, 200));
  }
  return lease;
}

StatusOr<std::chrono::milliseconds> ParseKeepAlive(int64_t lease, const std::string& body) {
  // A streaming call: one {"result": ...} (or {"error": ...}) per line; one request, one line.
  const std::string first = body.substr(0, body.find('\n'));
  SCULPT_ASSIGN_OR_RETURN(Json j, Parse("/v3/lease/keepalive", first));
  if (const auto err = j.find("error"); err != j.end()) {
    return err->is_object() ? FromGrpc(Int(*err, "grpc_code"), err->value("message", std::string()))
                            : Internal("etcd keepalive: " + err->dump());
  }
  const auto result = j.find("result");
  if (result == j.end() || !result->is_object()) {
    return Internal("etcd keepalive answered no result: " + first.substr(0, 200));
  }
  // A lease that has expired or was revoked is answered with TTL 0 (left out).
  const int64_t ttl = Int(*result, "TTL");
  if (ttl <= 0) return NotFound("etcd lease " + std::to_string(lease) + " has expired");
  return std::chrono::milliseconds(std::chrono::seconds(ttl));
}

StatusOr<int64_t> ParseRevision(const std::string& target, const std::string& body) {
  SCULPT_ASSIGN_OR_RETURN(Json j, Parse(target, body));
  return Int(j.value("header", Json::object()), "revision");
}

StatusOr<std::vector<KeyValue>> ParseRange(const std::string& body) {
  SCULPT_ASSIGN_OR_RETURN(Json j, Parse("/v3/kv/range", body));
  return ToKeyValues(j);
}

StatusOr<std::optional<KeyValue>> ParseGet(const std::string& body) {
  SCULPT_ASSIGN_OR_RETURN(std::vector<KeyValue> kvs, ParseRange(body));
  if (kvs.empty()) return std::optional<KeyValue>();
  return std::optional<KeyValue>(std::move(kvs.front()));
}

StatusOr<TxnResult> ParseTxn(const std::string& body) {
  SCULPT_ASSIGN_OR_RETURN(Json j, Parse("/v3/kv/txn", body));
  TxnResult r;
  r.succeeded = j.value("succeeded", false);
  r.revision = Int(j.value("header", Json::object()), "revision");
  if (!r.succeeded) {
    for (const Json& response : j.value("responses", Json::array())) {
      const auto range = response.find("response_range");
      if (range == response.end()) continue;
      SCULPT_ASSIGN_OR_RETURN(std::vector<KeyValue> kvs, ToKeyValues(*range));
      for (KeyValue& kv : kvs) r.read.push_back(std::move(kv));
    }
  }
  return r;
}

StatusOr<int64_t> ParseDeleted(const std::string& body) {
  SCULPT_ASSIGN_OR_RETURN(Json j, Parse("/v3/kv/deleterange", body));
  return Int(j, "deleted");
}

// An error answer (HTTP status other than 200): etcd's gRPC code when the body carries one.
Status ErrorAnswer(const std::string& where, unsigned status, const std::string& body) {
  Json j = Json::parse(body, nullptr, false);
  if (!j.is_discarded() && j.is_object() && j.contains("code")) {
    return FromGrpc(Int(j, "code"), j.value("message", j.value("error", std::string())));
  }
  return Internal(where + ": HTTP " + std::to_string(status) + ": " + body.substr(0, 200));
}

// The client context of every https:// call: TLS 1.2+ with the suites sculptd's own ports allow,
// etcd's certificate verified against `ca_file` (or the system's store), and the client
// certificate when one is given.
StatusOr<std::shared_ptr<ssl::context>> MakeEtcdTlsContext(const EtcdClient::Options& o) {
  if (o.cert_file.empty() != o.key_file.empty()) {
    const char* missing = o.cert_file.empty() ? "cluster.etcd_cert_file" : "cluster.etcd_key_file";
    return InvalidArgument(std::string(missing) +
                           " is empty: a client certificate for etcd needs both "
                           "cluster.etcd_cert_file and cluster.etcd_key_file");
  }
  if (!o.ca_file.empty()) SCULPT_RETURN_IF_ERROR(CheckReadable("cluster.etcd_ca_file", o.ca_file));
  if (!o.cert_file.empty()) {
    SCULPT_RETURN_IF_ERROR(CheckReadable("cluster.etcd_cert_file", o.cert_file));
    SCULPT_RETURN_IF_ERROR(CheckReadable("cluster.etcd_key_file", o.key_file));
  }
  ERR_clear_error();
  auto ctx = std::make_shared<ssl::context>(ssl::context::tls_client);
  SSL_CTX* native = ctx->native_handle();
  SSL_CTX_set_min_proto_version(native, TLS1_2_VERSION);
  SSL_CTX_set_options(native, SSL_OP_NO_COMPRESSION | SSL_OP_NO_RENEGOTIATION);
  if (SSL_CTX_set_cipher_list(native, kTls12Ciphers) != 1 ||
      SSL_CTX_set_ciphersuites(native, kTls13Suites) != 1) {
    return Internal("OpenSSL refused the cipher list: " + TakeOpenSslError("unknown"));
  }
  if (o.ca_file.empty()) {
    boost::system::error_code ec;
    ctx->set_default_verify_paths(ec);
    if (ec) return Internal("OpenSSL: no default verify paths: " + ec.message());
  } else if (SSL_CTX_load_verify_locations(native, o.ca_file.c_str(), nullptr) != 1) {
    return InvalidArgument("cluster.etcd_ca_file=" + o.ca_file + ": not a PEM CA certificate (" +
                           TakeOpenSslError("unreadable") + ")");
  }
  if (!o.cert_file.empty()) {
    if (SSL_CTX_use_certificate_chain_file(native, o.cert_file.c_str()) != 1) {
      return InvalidArgument("cluster.etcd_cert_file=" + o.cert_file + ": not a PEM certificate (" +
                             TakeOpenSslError("unreadable") + ")");
    }
    if (SSL_CTX_use_PrivateKey_file(native, o.key_file.c_str(), SSL_FILETYPE_PEM) != 1 ||
        SSL_CTX_check_private_key(native) != 1) {
      return InvalidArgument("cluster.etcd_key_file=" + o.key_file +
                             ": not the unencrypted PEM key of cluster.etcd_cert_file=" +
                             o.cert_file + " (" + TakeOpenSslError("unreadable") + ")");
    }
  }
  ctx->set_verify_mode(ssl::verify_peer);
  ERR_clear_error();
  return ctx;
}

// Why a TLS operation failed: the certificate check's own reason when that was it (wrong CA,
// wrong host name, expired), else OpenSSL's reason ("sslv3 alert bad certificate": etcd refused
// this client's certificate or its absence).
std::string TlsFailure(const boost::system::error_code& ec, SSL* ssl) {
  const long verify = ssl ? SSL_get_verify_result(ssl) : X509_V_OK;
  std::string text = "TLS: " + ec.message();
  if (verify != X509_V_OK) text += std::string(": ") + X509_verify_cert_error_string(verify);
  if (ec.category() == asio::error::get_ssl_category()) {
    const int reason = ERR_GET_REASON(static_cast<unsigned long>(ec.value()));
    if (reason == SSL_R_SSLV3_ALERT_BAD_CERTIFICATE || reason == SSL_R_TLSV1_ALERT_UNKNOWN_CA ||
        reason == SSL_R_TLSV13_ALERT_CERTIFICATE_REQUIRED) {
      text +=
          " (etcd refused the client certificate: with --client-cert-auth it needs one "
          "of its --trusted-ca-file, cluster.etcd_cert_file and etcd_key_file)";
    } else if (reason == SSL_R_WRONG_VERSION_NUMBER) {
      text += " (does etcd listen with TLS on this port? if not, use http://)";
    }
  }
  if (ec == asio::error::eof || ec == ssl::error::stream_truncated) {
    text += " (does etcd listen with TLS on this port?)";
  }
  return text;
}

// Writes `req` and reads the answer on a connected (and for TLS, handshaken) stream; `describe`
// turns an error into text.
template <typename Stream, typename Describe>
asio::awaitable<StatusOr<http::response<http::string_body>>> Exchange(
    Stream& stream, http::request<http::string_body>& req, const std::string& where,
    Describe describe) {
  boost::system::error_code ec;
  auto token = asio::redirect_error(asio::use_awaitable, ec);
  co_await http::async_write(stream, req, token);
  if (ec) co_return Status(Status::Code::kUnavailable, where + ": write: " + describe(ec));
  beast::flat_buffer buffer;
  http::response_parser<http::string_body> parser;
  parser.body_limit(kMaxAnswerBytes);
  co_await http::async_read(stream, buffer, parser, token);
  if (ec) co_return Status(Status::Code::kUnavailable, where + ": read: " + describe(ec));
  co_return parser.release();
}

}  // namespace

StatusOr<std::unique_ptr<EtcdClient>> EtcdClient::Create(Options options) {
  if (options.endpoints.empty()) {
    return Outside("cluster.etcd", "[]", "1 or more http://HOST:PORT endpoints");
  }
  std::vector<Endpoint> endpoints;
  std::optional<bool> https;  // the first endpoint's scheme
  for (const std::string& text : options.endpoints) {
    std::string rest = text;
    const bool is_https = rest.rfind("https://", 0) == 0;
    if (is_https) rest = rest.substr(8);
    if (rest.rfind("http://", 0) == 0) rest = rest.substr(7);
    if (https.has_value() && *https != is_https) {
      return InvalidArgument("cluster.etcd=" + text + ": not the scheme of the other endpoints (" +
                             (*https ? "https" : "http") +
                             "://): every endpoint is TLS or none is");
    }
    https = is_https;
    while (!rest.empty() && rest.back() == '/') rest.pop_back();
    const size_t colon = rest.rfind(':');
    if (colon == std::string::npos || colon == 0 || colon + 1 == rest.size() ||
        rest.find('/') != std::string::npos) {
      return Outside("cluster.etcd", text, "http://HOST:PORT or https://HOST:PORT");
    }
    Endpoint e{rest.substr(0, colon), rest.substr(colon + 1)};
    if (e.host.size() > 2 && e.host.front() == '[' && e.host.back() == ']') {
      e.host = e.host.substr(1, e.host.size() - 2);
    }
    if (e.port.find_first_not_of("0123456789") != std::string::npos || e.port.size() > 5 ||
        std::stoi(e.port) == 0 || std::stoi(e.port) > 65535) {
      return Outside("cluster.etcd", text, "http(s)://HOST:PORT with PORT in [1, 65535]");
    }
    endpoints.push_back(std::move(e));
  }
  if (options.timeout <= std::chrono::milliseconds(0)) {
    return Outside("EtcdClient timeout", std::to_string(options.timeout.count()), "> 0 ms");
  }
  std::shared_ptr<ssl::context> tls;
  if (*https) {
    SCULPT_ASSIGN_OR_RETURN(tls, MakeEtcdTlsContext(options));
  } else {
    for (auto [field, value] : {std::pair{"cluster.etcd_ca_file", &options.ca_file},
                                std::pair{"cluster.etcd_cert_file", &options.cert_file},
                                std::pair{"cluster.etcd_key_file", &options.key_file}}) {
      if (!value->empty()) {
        return InvalidArgument(std::string(field) + "=" + *value +
                               " is set but the etcd endpoints are http://: TLS files are for "
                               "https:// endpoints");
      }
    }
  }
  return std::unique_ptr<EtcdClient>(
      new EtcdClient(std::move(options), std::move(endpoints), std::move(tls)));
}

EtcdClient::EtcdClient(Options options, std::vector<Endpoint> endpoints,
                       std::shared_ptr<ssl::context> tls)
    : options_(std::move(options)),
      endpoints_(std::move(endpoints)),
      tls_(std::move(tls)),
      work_(asio::make_work_guard(io_)) {
  thread_ = std::thread([this] { io_.run(); });
}

EtcdClient::~EtcdClient() { Halt(); }

void EtcdClient::Halt() {
  work_.reset();
  io_.stop();
  if (thread_.joinable()) thread_.join();
}

std::string EtcdClient::PrefixEnd(const std::string& prefix) {
  std::string end = prefix;
  while (!end.empty()) {
    if (static_cast<unsigned char>(end.back()) < 0xff) {
      end.back() = static_cast<char>(static_cast<unsigned char>(end.back()) + 1);
      return end;
    }
    end.pop_back();
  }
  return std::string(1, '\0');  // every key
}

asio::awaitable<StatusOr<std::string>> EtcdClient::CallOne(Endpoint e, std::string target,
                                                           std::string body) {
  boost::system::error_code ec;
  auto token = asio::redirect_error(asio::use_awaitable, ec);
  const auto executor = co_await asio::this_coro::executor;
  const std::string where =
      std::string("etcd ") + (tls_ ? "https://" : "http://") + e.host + ":" + e.port + target;
  tcp::resolver resolver(executor);
  // The resolver has no timeout of its own; endpoints are addresses or local names.
  const auto results = co_await resolver.async_resolve(e.host, e.port, token);
  if (ec) co_return Status(Status::Code::kUnavailable, where + ": " + ec.message());
  http::request<http::string_body> req{http::verb::post, target, 11};
  req.set(http::field::host, e.host + ":" + e.port);
  req.set(http::field::content_type, "application/json");
  req.body() = std::move(body);
  req.prepare_payload();
  StatusOr<http::response<http::string_body>> res = Internal("unreached");
  if (!tls_) {
    beast::tcp_stream stream(executor);
    stream.expires_after(options_.timeout);
    co_await stream.async_connect(results, token);
    if (ec) co_return Status(Status::Code::kUnavailable, where + ": " + ec.message());
    auto exchange_call = Exchange(stream, req, where, [](const boost::system::error_code& ec) {
      // etcd's TLS-only client port closes a plaintext request without an answer.
      return ec == http::error::end_of_stream || ec == asio::error::eof
                 ? ec.message() + " (does etcd's client port speak TLS? then use https://)"
                 : ec.message();
    });
    res = co_await std::move(exchange_call);
    stream.socket().shutdown(tcp::socket::shutdown_both, ec);
  } else {
    beast::ssl_stream<beast::tcp_stream> stream(executor, *tls_);
    SSL* native = stream.native_handle();
    boost::system::error_code not_ip;
    asio::ip::make_address(e.host, not_ip);
    if (not_ip) SSL_set_tlsext_host_name(native, e.host.c_str());  // SNI takes names only
    // The certificate must name the endpoint's host (DNS name or IP address); a mismatch is
    // reported as such rather than as OpenSSL's "unspecified" verification error.
    const int mismatch = not_ip ? X509_V_ERR_HOSTNAME_MISMATCH : X509_V_ERR_IP_ADDRESS_MISMATCH;
    stream.set_verify_callback(
        [check = ssl::host_name_verification(e.host), mismatch](bool preverified,
                                                                ssl::verify_context& ctx) mutable {
          const bool ok = check(preverified, ctx);
          if (preverified && !ok) X509_STORE_CTX_set_error(ctx.native_handle(), mismatch);
          return ok;
        },
        ec);
    beast::get_lowest_layer(stream).expires_after(options_.timeout);
    co_await beast::get_lowest_layer(stream).async_connect(results, token);
    if (ec) co_return Status(Status::Code::kUnavailable, where + ": " + ec.message());
    co_await stream.async_handshake(ssl::stream_base::client, token);
    if (ec) {
      co_return Status(Status::Code::kUnavailable,
                       where + ": handshake failed: " + TlsFailure(ec, native));
    }
    auto exchange_call =
        Exchange(stream, req, where, [native](const boost::system::error_code& ec) {
          return ec.category() == asio::error::get_ssl_category() ||
                         ec == ssl::error::stream_truncated || ec == asio::error::eof
                     ? TlsFailure(ec, native)
                     : ec.message();
        });
    res = co_await std::move(exchange_call);
    // No close_notify round trip: the answer is complete, and etcd keeps nothing per connection.
    beast::get_lowest_layer(stream).socket().shutdown(tcp::socket::shutdown_both, ec);
  }
  if (!res.ok()) co_return res.status();
  if (res->result() != http::status::ok)
    co_return ErrorAnswer(where, res->result_int(), res->body());
  co_return std::move(res->body());
}

asio::awaitable<StatusOr<std::string>> EtcdClient::Call(std::string target, std::string body) {
  Status last;
  // The endpoint that answered last first; on a network failure, the next one. An error etcd
  // itself returned is final (another member would say the same).
  for (size_t i = 0; i < endpoints_.size(); ++i) {
    const size_t k = (preferred_ + i) % endpoints_.size();
    auto answer_call = CallOne(endpoints_[k], target, body);
    auto answer = co_await std::move(answer_call);
    if (answer.ok() || answer.status().code() != Status::Code::kUnavailable) {
      if (answer.ok()) preferred_ = k;
      co_return answer;
    }
    last = answer.status();
  }
  co_return last;
}

asio::awaitable<StatusOr<Lease>> EtcdClient::Grant(std::chrono::milliseconds ttl) {
  // etcd's TTL is whole seconds: rounded up, so the lease outlives what the caller asked.
  const int64_t seconds = std::max<int64_t>(1, (ttl.count() + 999) / 1000);
  auto body_call = Call("/v3/lease/grant", GrantBody(seconds));
  auto body = co_await std::move(body_call);
  if (!body.ok()) co_return body.status();
  co_return ParseGrant(*body);
}

asio::awaitable<StatusOr<std::chrono::milliseconds>> EtcdClient::KeepAlive(int64_t lease) {
  auto body_call = Call("/v3/lease/keepalive", LeaseIdBody(lease));
  auto body = co_await std::move(body_call);
  if (!body.ok()) co_return body.status();
  co_return ParseKeepAlive(lease, *body);
}

asio::awaitable<Status> EtcdClient::Revoke(int64_t lease) {
  auto body_call = Call("/v3/lease/revoke", LeaseIdBody(lease));
  auto body = co_await std::move(body_call);
  co_return body.status();
}

asio::awaitable<StatusOr<int64_t>> EtcdClient::Put(PutOp put) {
  auto body_call = Call("/v3/kv/put", PutBody(put));
  auto body = co_await std::move(body_call);
  if (!body.ok()) co_return body.status();
  co_return ParseRevision("/v3/kv/put", *body);
}

asio::awaitable<StatusOr<std::optional<KeyValue>>> EtcdClient::Get(std::string key) {
  auto body_call = Call("/v3/kv/range", RangeBody(key, ""));
  auto body = co_await std::move(body_call);
  if (!body.ok()) co_return body.status();
  co_return ParseGet(*body);
}

asio::awaitable<StatusOr<std::vector<KeyValue>>> EtcdClient::GetPrefix(std::string prefix) {
  auto body_call = Call("/v3/kv/range", RangeBody(prefix, PrefixEnd(prefix)));
  auto body = co_await std::move(body_call);
  if (!body.ok()) co_return body.status();
  co_return ParseRange(*body);
}

asio::awaitable<StatusOr<TxnResult>> EtcdClient::Txn(TxnRequest txn) {
  auto body_call = Call("/v3/kv/txn", TxnBody(txn));
  auto body = co_await std::move(body_call);
  if (!body.ok()) co_return body.status();
  co_return ParseTxn(*body);
}

asio::awaitable<StatusOr<int64_t>> EtcdClient::Delete(std::string key) {
  auto body_call = Call("/v3/kv/deleterange", RangeBody(key, ""));
  auto body = co_await std::move(body_call);
  if (!body.ok()) co_return body.status();
  co_return ParseDeleted(*body);
}

}  // namespace sculpt::server::cluster
