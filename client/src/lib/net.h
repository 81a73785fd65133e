/// @brief The one place the client library includes Boost.Asio (Boost 1.74 with g++ 12 needs
/// <utility> before <boost/asio.hpp>).
#ifndef SCULPT_CLIENT_LIB_NET_H_
#define SCULPT_CLIENT_LIB_NET_H_

#include <utility>

#include <boost/asio.hpp>
#include <boost/asio/ssl.hpp>

namespace sculpt::client {
namespace asio = boost::asio;
namespace ssl = boost::asio::ssl;
using tcp = boost::asio::ip::tcp;
}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_LIB_NET_H_
