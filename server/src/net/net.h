/// @brief The one place that includes Boost.Asio for sculptd (Boost 1.74 with g++ 12 needs
/// <utility> before <boost/asio.hpp>).
#ifndef SCULPT_SERVER_NET_NET_H_
#define SCULPT_SERVER_NET_NET_H_

#include <utility>

#include <boost/asio.hpp>

namespace sculpt::server {
namespace asio = boost::asio;
using tcp = boost::asio::ip::tcp;
/// The executor every session, connection and transport of one client runs on.
using Strand = asio::strand<asio::io_context::executor_type>;
}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_NET_H_
