// The 20 rounds of kill -9 of a scene's owner under 4 sculptors (label soak, about
// 2 min, run by hand; figures in docs/cluster.md). The 3-round version runs in `make test`
// (tests/cluster/failover_rounds_test.cc).
#include "cluster/failover_rounds.h"

namespace sculpt::server::cluster::soak {
namespace {

TEST_F(FailoverSoakTest, TwentyOwnerKillsUnderFourSculptorsLoseAndRepeatNothing) {
  RunRounds(20);
}

}  // namespace
}  // namespace sculpt::server::cluster::soak
