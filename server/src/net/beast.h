/// @brief The one place that includes Boost.Beast for sculptd (after net.h, which sets up Asio).
#ifndef SCULPT_SERVER_NET_BEAST_H_
#define SCULPT_SERVER_NET_BEAST_H_

#include "net/net.h"

#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>

namespace sculpt::server {
namespace beast = boost::beast;
namespace http = boost::beast::http;
namespace websocket = boost::beast::websocket;
}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_BEAST_H_
