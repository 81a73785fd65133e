/// @brief ViewerSeats: how many of a scene's seats viewers may take (limits.reserved_sculptor_seats).
#ifndef SCULPT_SERVER_CONFIG_SEATS_H_
#define SCULPT_SERVER_CONFIG_SEATS_H_

#include <cstdint>

#include "config/server_config.h"

namespace sculpt::server {

/// max_clients_per_scene less the reserved sculptor seats, the reservation being at most half
/// of the scene (a two-seat scene still has a seat for a viewer).
uint32_t ViewerSeats(const LimitsConfig& limits);

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_CONFIG_SEATS_H_
