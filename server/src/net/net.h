/// @brief The one place that includes Boost.Asio for sculptd (Boost 1.74 with g++ 12 needs
/// <utility> before <boost/asio.hpp>).
#ifndef SCULPT_SERVER_NET_NET_H_
#define SCULPT_SERVER_NET_NET_H_

#include <utility>

#include <boost/asio.hpp>

namespace sculpt::server {
namespace asio = boost::asio;
using tcp = boost::asio::ip::tcp;
}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_NET_H_
