/// @brief EtcdClient: the few etcd v3 calls a sculptd member needs (leases, put, range, txn,
/// delete), over etcd's HTTP/JSON gateway with Boost.Beast (plain or TLS), on a thread of its own.
#ifndef SCULPT_SERVER_CLUSTER_ETCD_CLIENT_H_
#define SCULPT_SERVER_CLUSTER_ETCD_CLIENT_H_

// clang-format off: net/net.h must come first (<utility> before Boost.Asio for coroutines with
// g++ 12), and Google style would regroup it after the Boost headers.
#include "net/net.h"
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/use_awaitable.hpp>
// clang-format on

#include <chrono>
#include <cstdint>
#include <future>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "sculpt/core/status.h"

// The TLS context is only pointed to here: OpenSSL and Beast's SSL stay out of this header.
namespace boost::asio::ssl {
class context;
}  // namespace boost::asio::ssl

namespace sculpt::server::cluster {

/// One key as etcd holds it (keys and values are bytes; the gateway's base64 is undone).
struct KeyValue {
  std::string key;
  std::string value;
  int64_t create_revision = 0;
  int64_t mod_revision = 0;
  int64_t version = 0;
  int64_t lease = 0;
};

/// A granted lease: its id and the TTL etcd granted (etcd rounds a TTL up to whole seconds and
/// to its minimum, 2 s with the default election timeout).
struct Lease {
  int64_t id = 0;
  std::chrono::milliseconds ttl{0};
};

/// A compare of a txn: `key`'s create or mod revision EQUAL to `revision` (0 for a key that does
/// not exist).
struct Compare {
  enum class Target { kCreateRevision, kModRevision };
  std::string key;
  Target target = Target::kCreateRevision;
  int64_t revision = 0;
};

struct PutOp {
  std::string key;
  std::string value;
  int64_t lease = 0;  // 0: none
};

/// If every compare holds, the puts and the deletes; otherwise the keys of `failure_ranges` are
/// read.
struct TxnRequest {
  std::vector<Compare> compares;
  std::vector<PutOp> success;
  std::vector<std::string> success_deletes;  // keys deleted when the compares hold
  std::vector<std::string> failure_ranges;
};

struct TxnResult {
  bool succeeded = false;
  int64_t revision = 0;        // the store's revision after the txn
  std::vector<KeyValue> read;  // what failure_ranges read, in order (when not succeeded)
};

/// A small etcd v3 client over the gateway (`POST /v3/kv/range` ...; one HTTP/1.1 connection
/// per call, endpoints tried in order until one answers). Each call is an awaitable run on the
/// client's own io_context and thread, so a slow or absent etcd never blocks a session's strand
/// or the compute thread; Sync() runs one from any other thread and waits.
/// Over https:// the client verifies etcd's certificate (chain to `ca_file`, or the system's
/// store, and the endpoint's host name) and may present a client certificate.
/// Errors: Unavailable when no endpoint answers within the timeout or its TLS handshake fails
/// (the message says "TLS" and OpenSSL's reason), NotFound for an unknown lease, Internal for an
/// answer that does not parse, and etcd's other errors by their gRPC code.
/// Thread safety: the awaitables run only on io(); Sync() from any thread but io()'s.
class EtcdClient {
 public:
  struct Options {
    /// "http://HOST:PORT" (the scheme may be left out: http) or "https://HOST:PORT"; every
    /// endpoint of one client has the same scheme.
    std::vector<std::string> endpoints;
    /// Bound of one call (connect, TLS handshake, write, read), per endpoint tried.
    std::chrono::milliseconds timeout{1000};
    /// https only. PEM CA certificates etcd's certificate must chain to; empty: the system's
    /// default verify paths.
    std::string ca_file{};
    /// https only, both or neither: the PEM client certificate (and its unencrypted PEM key)
    /// presented to an etcd started with --client-cert-auth.
    std::string cert_file{};
    std::string key_file{};
  };

  /// InvalidArgument naming the endpoint that is not http(s)://HOST:PORT or whose scheme differs
  /// from the others', and naming the field and the path of a TLS file that is missing,
  /// unreadable or not PEM (the files are read here, once).
  static StatusOr<std::unique_ptr<EtcdClient>> Create(Options options);
  ~EtcdClient();
  EtcdClient(const EtcdClient&) = delete;
  EtcdClient& operator=(const EtcdClient&) = delete;

  asio::io_context& io() { return io_; }
  /// Stops io() and joins its thread, keeping io() itself: I/O objects a caller made on it can
  /// then be destroyed before the client (their service must outlive them). Idempotent; the
  /// destructor calls it. Not from io()'s own thread.
  void Halt();

  asio::awaitable<StatusOr<Lease>> Grant(std::chrono::milliseconds ttl);
  /// One keep-alive: the lease's remaining TTL as etcd reset it. NotFound when the lease has
  /// expired or was revoked.
  asio::awaitable<StatusOr<std::chrono::milliseconds>> KeepAlive(int64_t lease);
  asio::awaitable<Status> Revoke(int64_t lease);
  /// The store's revision after the put.
  asio::awaitable<StatusOr<int64_t>> Put(PutOp put);
  /// The key, or nullopt when absent.
  asio::awaitable<StatusOr<std::optional<KeyValue>>> Get(std::string key);
  /// Every key starting with `prefix`, in key order.
  asio::awaitable<StatusOr<std::vector<KeyValue>>> GetPrefix(std::string prefix);
  asio::awaitable<StatusOr<TxnResult>> Txn(TxnRequest txn);
  /// How many keys were deleted.
  asio::awaitable<StatusOr<int64_t>> Delete(std::string key);

  /// Runs `op` on io() and waits for it. FailedPrecondition when called on io()'s thread (it
  /// would wait for itself).
  template <typename T>
  T Sync(asio::awaitable<T> op) {
    if (io_.get_executor().running_in_this_thread()) {
      return T(FailedPrecondition("EtcdClient::Sync called on the client's own thread"));
    }
    auto done = std::make_shared<std::promise<T>>();
    auto result = done->get_future();
    asio::co_spawn(
        io_,
        [done, op = std::move(op)]() mutable -> asio::awaitable<void> {
          try {
            done->set_value(co_await std::move(op));
          } catch (const std::exception& e) {
            done->set_value(T(Internal(std::string("etcd call threw: ") + e.what())));
          }
        },
        asio::detached);
    return result.get();
  }

  /// The key just past every key starting with `prefix` (etcd's range_end for a prefix).
  static std::string PrefixEnd(const std::string& prefix);

 private:
  struct Endpoint {
    std::string host;
    std::string port;
  };
  EtcdClient(Options options, std::vector<Endpoint> endpoints,
             std::shared_ptr<boost::asio::ssl::context> tls);
  // POSTs `body` (JSON text) to `target` on the first endpoint that answers; the parsed JSON
  // answer as text is returned for the caller to parse (keeps the JSON type out of this header).
  asio::awaitable<StatusOr<std::string>> Call(std::string target, std::string body);
  asio::awaitable<StatusOr<std::string>> CallOne(Endpoint e, std::string target, std::string body);

  Options options_;
  std::vector<Endpoint> endpoints_;
  // The context of every https:// call, built once by Create; null for http://.
  std::shared_ptr<boost::asio::ssl::context> tls_;
  size_t preferred_ = 0;  // io() only: the endpoint that answered last
  asio::io_context io_;
  asio::executor_work_guard<asio::io_context::executor_type> work_;
  std::thread thread_;
};

}  // namespace sculpt::server::cluster

#endif  // SCULPT_SERVER_CLUSTER_ETCD_CLIENT_H_
