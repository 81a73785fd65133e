// The C++ client and a member's Redirect (issue 17: bad input between members): a redirect is
// input from the network like any other. The client follows one redirect to a usable address;
// it refuses one that names no usable address and a second redirect from the member the first
// named, saying which, instead of connecting wherever it is sent. The members are real servers
// in-process whose routing table the test sets (no etcd).
#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <string>
#include <utility>

#include "cluster/scene_router.h"
#include "integration/in_process_server.h"
#include "sculpt/client/client.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::server::cluster {
namespace {

using sculpt::testing_support::InProcessServer;

// Sends every JoinScene to member `member` at `tcp`.
class RedirectingRouter : public SceneRouter {
 public:
  RedirectingRouter(std::string member, std::string tcp)
      : member_(std::move(member)), tcp_(std::move(tcp)) {}
  Route RouteScene(const std::string& scene) const override {
    Route r;
    r.kind = Route::Kind::kRedirect;
    r.scene = scene.empty() ? "default" : scene;
    r.member = member_;
    r.tcp = tcp_;
    r.epoch = 3;
    return r;
  }

 private:
  std::string member_;
  std::string tcp_;
};

class ClientRedirectTest : public ::testing::Test {
 protected:
  // A sculptor that has said Hello to the server at `port` and asks to join the default scene.
  StatusOr<client::JoinedScene> JoinThrough(uint16_t port) {
    client::ClientOptions options;
    options.timeout = std::chrono::milliseconds(5000);
    client_ = std::make_unique<client::Client>(options);
    if (Status s = client_->Connect("127.0.0.1", port); !s.ok()) return s;
    auto hello = client_->Hello("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, "redirected", 0);
    if (!hello.ok()) return hello.status();
    return client_->Join("");
  }
  static std::string Address(uint16_t port) { return "127.0.0.1:" + std::to_string(port); }

  InProcessServer a_{"redirect_a"};
  InProcessServer b_{"redirect_b"};
  std::unique_ptr<client::Client> client_;
};

TEST_F(ClientRedirectTest, FollowsOneRedirectToTheOwner) {
  ASSERT_TRUE(a_.Start());
  ASSERT_TRUE(b_.Start());
  RedirectingRouter to_b("b", Address(b_.port()));
  a_.server().set_router(&to_b);
  auto joined = JoinThrough(a_.port());
  ASSERT_TRUE(joined.ok()) << joined.status();
  EXPECT_EQ(client_->stats().redirects, 1u);
  EXPECT_EQ(joined->info.global_seq(), b_.scene().global_seq());
}

TEST_F(ClientRedirectTest, RefusesARedirectToAnUnusableAddress) {
  ASSERT_TRUE(a_.Start());
  for (const char* bad : {"no-port-here", "127.0.0.1:0", "127.0.0.1:99999", ""}) {
    RedirectingRouter nowhere("x", bad);
    a_.server().set_router(&nowhere);
    auto joined = JoinThrough(a_.port());
    ASSERT_FALSE(joined.ok()) << "followed a redirect to \"" << bad << "\"";
    const std::string why = joined.status().ToString();
    EXPECT_NE(why.find("unusable address"), std::string::npos) << why;
    EXPECT_NE(why.find(std::string("Redirect.tcp_address=") + bad), std::string::npos) << why;
    EXPECT_NE(why.find("member x"), std::string::npos) << why;
    a_.server().set_router(nullptr);
  }
}

TEST_F(ClientRedirectTest, RefusesASecondRedirect) {
  ASSERT_TRUE(a_.Start());
  ASSERT_TRUE(b_.Start());
  // a names b the owner, and b names a: a client following both would go round for ever.
  RedirectingRouter to_b("b", Address(b_.port()));
  RedirectingRouter to_a("a", Address(a_.port()));
  a_.server().set_router(&to_b);
  b_.server().set_router(&to_a);
  auto joined = JoinThrough(a_.port());
  ASSERT_FALSE(joined.ok()) << "followed a second redirect";
  const std::string why = joined.status().ToString();
  EXPECT_NE(why.find("redirected twice"), std::string::npos) << why;
  EXPECT_NE(why.find("member b"), std::string::npos) << why;
  EXPECT_EQ(client_->stats().redirects, 1u);
  a_.server().set_router(nullptr);
  b_.server().set_router(nullptr);
}

}  // namespace
}  // namespace sculpt::server::cluster
