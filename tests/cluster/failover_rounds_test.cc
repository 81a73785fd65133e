// Three rounds of kill -9 of a scene's owner under 4 sculptors at 60 Hz with synchronous
// replication: nothing acknowledged lost, nothing applied twice, no refusal, the sculptors
// continuing without user action (tests/cluster/failover_rounds.h; the 20-round soak is
// tests/cluster/soak/failover_soak_test.cc).
#include "cluster/failover_rounds.h"

namespace sculpt::server::cluster::soak {
namespace {

TEST_F(FailoverSoakTest, ThreeOwnerKillsUnderFourSculptorsLoseAndRepeatNothing) {
  raised_bursts_ = true;
  RunRounds(3);
}

}  // namespace
}  // namespace sculpt::server::cluster::soak
