// Named users (issue 14): the users file's checks, `sculptd user add`'s hashes, and a server with
// a users file: who gets in, in which role, under which id, and how a guessing address is slowed.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>
#include <variant>

#include "integration/raw_client.h"
#include "integration/raw_server.h"
#include "net/server.h"
#include "net/users.h"
#include "scene/scene.h"
#include "sculpt/codec/log_records.h"
#include "store/edit_log.h"

namespace sculpt::server {
namespace {

namespace fs = std::filesystem;
using sculpt::testing::RawClient;

fs::path TestDir(const std::string& tag) {
  const fs::path d = fs::temp_directory_path() /
                     ("sculpt_users_" + tag + "_" +
                      ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_" +
                      std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

void WriteFile(const fs::path& p, const std::string& text, mode_t mode = 0600) {
  std::ofstream(p) << text;
  ::chmod(p.c_str(), mode);
}

class UsersFileTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = TestDir("file"); }
  void TearDown() override { fs::remove_all(dir_); }
  StatusOr<UserTable> LoadText(const std::string& text, mode_t mode = 0600) {
    WriteFile(dir_ / "users.toml", text, mode);
    return UserTable::Load((dir_ / "users.toml").string());
  }
  std::string Hash() { return HashToken("a-token").value(); }
  fs::path dir_;
};

TEST_F(UsersFileTest, RefusesMissingFile) {
  auto t = UserTable::Load((dir_ / "none.toml").string());
  ASSERT_FALSE(t.ok());
  EXPECT_EQ(t.status().code(), Status::Code::kNotFound);
  EXPECT_NE(t.status().message().find("does not exist"), std::string::npos);
}

TEST_F(UsersFileTest, RefusesFileReadableByOthers) {
  auto t = LoadText("", 0644);
  ASSERT_FALSE(t.ok());
  EXPECT_EQ(t.status().code(), Status::Code::kFailedPrecondition);
  EXPECT_NE(t.status().message().find("mode 0644"), std::string::npos) << t.status();
  EXPECT_NE(t.status().message().find("chmod 600"), std::string::npos) << t.status();
  auto g = LoadText("", 0620);
  ASSERT_FALSE(g.ok());
  EXPECT_NE(g.status().message().find("mode 0620"), std::string::npos) << g.status();
}

TEST_F(UsersFileTest, RefusesUnreadableFile) {
  if (::geteuid() == 0) GTEST_SKIP() << "root reads a mode-000 file";
  auto t = LoadText("", 0000);
  ASSERT_FALSE(t.ok());
  EXPECT_NE(t.status().message().find("not readable"), std::string::npos) << t.status();
}

TEST_F(UsersFileTest, RefusesMalformedEntries) {
  const std::string h = Hash();
  struct Case {
    std::string text, says;
  } cases[] = {
      {"[[users]\nname = 'a'", "users.toml:"},
      {"[[users]]\nname = 'alice'\nrole = 'sculptor'\ntoken_hash = '" + h + "'\ncolour = 1\n",
       "unknown key users[0].colour"},
      {"[[users]]\nrole = 'sculptor'\ntoken_hash = '" + h + "'\n", "users[0].name missing"},
      {"[[users]]\nname = 'al ice'\nrole = 'sculptor'\ntoken_hash = '" + h + "'\n",
       "[A-Za-z0-9._-]"},
      {"[[users]]\nname = 'alice'\nrole = 'admin'\ntoken_hash = '" + h + "'\n",
       "role=admin outside {sculptor, viewer}"},
      {"[[users]]\nname = 'alice'\nrole = 'viewer'\ntoken_hash = 'plain-token'\n",
       "not a crypto_pwhash string"},
      {"[[users]]\nname = 'alice'\nrole = 'viewer'\ntoken_hash = '" + h +
           "'\n[[users]]\nname = 'alice'\nrole = 'sculptor'\ntoken_hash = '" + h + "'\n",
       "users[1].name=alice appears twice"},
      {"admins = 1\n", "unknown key admins"},
  };
  for (const Case& c : cases) {
    auto t = LoadText(c.text);
    ASSERT_FALSE(t.ok()) << c.text;
    EXPECT_EQ(t.status().code(), Status::Code::kInvalidArgument) << c.text;
    EXPECT_NE(t.status().message().find(c.says), std::string::npos)
        << t.status() << " should say " << c.says;
  }
}

TEST_F(UsersFileTest, SavedTableLoadsBackWithOwnerOnlyModeAndHashesVerify) {
  UserTable t;
  const std::string alice = NewToken(), bob = NewToken();
  EXPECT_EQ(alice.size(), 43u);  // 32 bytes, URL-safe base64 without padding
  EXPECT_NE(alice, bob);
  t.Put({"alice", UserRole::kSculptor, HashToken(alice).value()});
  t.Put({"bob", UserRole::kViewer, HashToken(bob).value()});
  const fs::path p = dir_ / "users.toml";
  ASSERT_TRUE(t.Save(p.string()).ok());
  struct stat st {};
  ASSERT_EQ(::stat(p.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  std::ifstream in(p);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(text.find(alice), std::string::npos) << "the token itself must never be stored";
  auto back = UserTable::Load(p.string());
  ASSERT_TRUE(back.ok()) << back.status();
  ASSERT_EQ(back->users().size(), 2u);
  const User* a = back->Find("alice");
  ASSERT_NE(a, nullptr);
  EXPECT_EQ(a->role, UserRole::kSculptor);
  EXPECT_TRUE(VerifyToken(a->token_hash, alice));
  EXPECT_FALSE(VerifyToken(a->token_hash, bob));
  EXPECT_FALSE(VerifyToken(a->token_hash, alice.substr(1)));
  EXPECT_TRUE(back->Remove("alice"));
  EXPECT_FALSE(back->Remove("alice"));
}

// A server whose users file holds alice and carol (sculptors) and bob (a viewer).
class NamedUsersTest : public sculpt::testing::RawServerTest {
 protected:
  void SetUp() override {
    Prepare("sculpt_users_server");
    tokens_["alice"] = NewToken();
    tokens_["bob"] = NewToken();
    tokens_["carol"] = NewToken();
    UserTable t;
    t.Put({"alice", UserRole::kSculptor, HashToken(tokens_["alice"]).value()});
    t.Put({"bob", UserRole::kViewer, HashToken(tokens_["bob"]).value()});
    t.Put({"carol", UserRole::kSculptor, HashToken(tokens_["carol"]).value()});
    users_ = dir_ / "users.toml";
    ASSERT_TRUE(t.Save(users_.string()).ok());
    config_.users_file = users_.string();
    config_.scene.objects[0].radius = 12;
    config_.limits.auth_timeout_ms = 2000;
    config_.limits.auth_backoff_ms = 300;
    config_.limits.auth_free_failures = 3;
    Start();
  }
  // Sends a Hello as `name` and returns the Welcome or the Error that answers it.
  static std::optional<v1::ServerMessage> Hello(RawClient& c, const std::string& name,
                                                const std::string& token, v1::Role role,
                                                uint64_t client_id = 77) {
    v1::ClientMessage m;
    auto* h = m.mutable_hello();
    h->set_protocol_version(1);
    h->set_token(token);
    h->set_role(role);
    h->set_client_name(name);
    h->set_client_id(client_id);
    c.Send(m);
    for (;;) {
      auto r = c.Read();
      if (!r || r->has_welcome() || r->has_error()) return r;
    }
  }
  // Joined as `name`: the Welcome.
  v1::Welcome Enter(RawClient& c, const std::string& name, v1::Role role, uint64_t client_id) {
    auto w = Hello(c, name, tokens_[name], role, client_id);
    EXPECT_TRUE(w && w->has_welcome()) << (w ? w->DebugString() : "closed");
    c.Join();
    EXPECT_TRUE(c.ReadUntil(v1::ServerMessage::kSceneInfo));
    return w && w->has_welcome() ? w->welcome() : v1::Welcome{};
  }

  fs::path users_;
  std::map<std::string, std::string> tokens_;
};

TEST_F(NamedUsersTest, AUserSculptsUnderItsNameAndPresenceShowsIt) {
  RawClient c(port_);
  const v1::Welcome w = Enter(c, "alice", v1::ROLE_SCULPTOR, 77);
  EXPECT_EQ(w.user(), "alice");
  EXPECT_NE(w.client_id(), 0u);
  EXPECT_NE(w.client_id(), 77u) << "a named user's id is bound to the user";
  c.Send(RawClient::PressStroke(1, {0, 0, 12.3}));
  auto ack = c.ReadUntil(v1::ServerMessage::kAck);
  ASSERT_TRUE(ack);
  EXPECT_EQ(ack->ack().edits(), 4u);
  // Presence goes out once two are in the scene: bob watches and sees alice by her name.
  RawClient b(port_);
  Enter(b, "bob", v1::ROLE_VIEWER, 9);
  bool seen = false;
  for (int i = 0; i < 50 && !seen; ++i) {
    auto p = b.ReadUntil(v1::ServerMessage::kPresence);
    ASSERT_TRUE(p);
    for (const auto& u : p->presence().users()) seen = seen || u.name() == "alice";
  }
  EXPECT_TRUE(seen);
}

TEST_F(NamedUsersTest, WrongTokenUnknownNameAndSharedTokenAreRefusedAlike) {
  const std::pair<std::string, std::string> attempts[] = {
      {"alice", tokens_["carol"]},        // another user's token
      {"mallory", tokens_["alice"]},      // no such user
      {"alice", "sculpt-dev-sculptor"},  // the development token means nothing here
  };
  for (const auto& [name, token] : attempts) {
    RawClient c(port_);
    auto r = Hello(c, name, token, v1::ROLE_SCULPTOR);
    ASSERT_TRUE(r && r->has_error()) << name;
    EXPECT_EQ(r->error().code(), v1::ERROR_CODE_UNAUTHENTICATED) << name;
    EXPECT_EQ(r->error().field(), "Hello.token");
    EXPECT_EQ(r->error().value(), "(hidden)");
    EXPECT_TRUE(c.WaitClosed());
  }
  RawClient ok(port_);
  Enter(ok, "carol", v1::ROLE_SCULPTOR, 5);
}

TEST_F(NamedUsersTest, AViewerMayNotSculptButMayWatch) {
  RawClient c(port_);
  auto r = Hello(c, "bob", tokens_["bob"], v1::ROLE_SCULPTOR);
  ASSERT_TRUE(r && r->has_error());
  EXPECT_EQ(r->error().code(), v1::ERROR_CODE_PERMISSION_DENIED);
  EXPECT_NE(r->error().message().find("bob is a viewer"), std::string::npos);
  RawClient v(port_);
  EXPECT_EQ(Enter(v, "bob", v1::ROLE_VIEWER, 6).user(), "bob");
  RawClient a(port_);
  EXPECT_EQ(Enter(a, "alice", v1::ROLE_VIEWER, 7).role(), v1::ROLE_VIEWER);
}

TEST_F(NamedUsersTest, AnotherUsersClientIdCannotSwallowTheirStrokes) {
  // carol presents alice's client_id and her client_seq: today's de-duplication would take
  // alice's stroke for carol's resend. Bound ids keep them apart.
  RawClient a(port_), c(port_);
  const v1::Welcome wa = Enter(a, "alice", v1::ROLE_SCULPTOR, 4242);
  const v1::Welcome wc = Enter(c, "carol", v1::ROLE_SCULPTOR, 4242);
  EXPECT_NE(wa.client_id(), wc.client_id());
  c.Send(RawClient::PressStroke(1, {0, 0, 12.3}));
  auto ack_c = c.ReadUntil(v1::ServerMessage::kAck);
  ASSERT_TRUE(ack_c);
  a.Send(RawClient::PressStroke(1, {3, 0, 11.9}));
  auto ack_a = a.ReadUntil(v1::ServerMessage::kAck);
  ASSERT_TRUE(ack_a);
  EXPECT_FALSE(ack_a->ack().duplicate());
  EXPECT_EQ(ack_a->ack().edits(), 4u);
  EXPECT_NE(ack_a->ack().global_seq_first(), ack_c->ack().global_seq_first());
  // The same user reconnecting with the same client_id is the same client: a resend is one.
  a.Close();
  RawClient again(port_);
  EXPECT_EQ(Enter(again, "alice", v1::ROLE_SCULPTOR, 4242).client_id(), wa.client_id());
  again.Send(RawClient::PressStroke(1, {3, 0, 11.9}));
  auto resend = again.ReadUntil(v1::ServerMessage::kAck);
  ASSERT_TRUE(resend);
  EXPECT_TRUE(resend->ack().duplicate());
}

// Who made each edit is in the log (every record of it), in the history view (filtered by the
// name too), and still there after a restart that learns the names back from the log.
TEST_F(NamedUsersTest, TheLogAndTheHistoryNameTheUserWhoMadeEachEdit) {
  const auto history = [this](const std::string& author) {
    RawClient c(port_);
    Enter(c, "carol", v1::ROLE_SCULPTOR, 5);
    v1::ClientMessage q;
    q.mutable_history()->set_request_id(1);
    q.mutable_history()->set_object("clay");
    q.mutable_history()->set_author(author);
    c.Send(q);
    auto a = c.ReadUntil(v1::ServerMessage::kHistory);
    EXPECT_TRUE(a);
    return a ? a->history() : v1::HistoryAnswer{};
  };
  uint64_t alice_id = 0;
  {
    RawClient c(port_);
    alice_id = Enter(c, "alice", v1::ROLE_SCULPTOR, 77).client_id();
    c.Send(RawClient::PressStroke(1, {0, 0, 12.3}));
    ASSERT_TRUE(c.ReadUntil(v1::ServerMessage::kAck));
  }
  for (int round = 0; round < 2; ++round) {  // live, then after a restart
    const v1::HistoryAnswer by_name = history("alice");
    ASSERT_EQ(by_name.entries_size(), 1) << "round " << round << by_name.DebugString();
    EXPECT_EQ(by_name.entries(0).user(), "alice");
    EXPECT_EQ(by_name.entries(0).author(), std::to_string(alice_id));
    EXPECT_EQ(history("carol").entries_size(), 0);
    Stop();
    if (round == 0) {
      store::RecoveryReport report;
      auto log = store::EditLog::Open((dir_ / "data" / "log").string(), store::FsyncPolicy{},
                                      &report);
      ASSERT_TRUE(log.ok()) << log.status();
      auto records = (*log)->ReadFrom(0);
      ASSERT_TRUE(records.ok()) << records.status();
      ASSERT_EQ(records->size(), 4u);  // the stroke's poses
      for (const store::LogRecord& r : *records) {
        auto decoded = codec::DecodeLogRecord(r.seq, r.payload);
        ASSERT_TRUE(decoded.ok()) << decoded.status();
        const auto* pose = std::get_if<codec::StrokePoseRecord>(&*decoded);
        ASSERT_NE(pose, nullptr);
        EXPECT_EQ(pose->user, "alice");
        EXPECT_EQ(pose->client_id, alice_id);
      }
    }
    Start();
  }
}

TEST_F(NamedUsersTest, AGuessingAddressWaitsLongerAndLonger) {
  auto attempt = [&](const std::string& token) {
    RawClient c(port_);
    auto r = Hello(c, "alice", token, v1::ROLE_SCULPTOR);
    return r ? *r : v1::ServerMessage{};
  };
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(attempt("guess").error().code(), v1::ERROR_CODE_UNAUTHENTICATED) << i;
  }
  // The fourth failure starts the backoff: even the right token now waits it out.
  EXPECT_EQ(attempt("guess").error().code(), v1::ERROR_CODE_UNAUTHENTICATED);
  const v1::ServerMessage held = attempt(tokens_["alice"]);
  ASSERT_TRUE(held.has_error());
  EXPECT_EQ(held.error().code(), v1::ERROR_CODE_RESOURCE_EXHAUSTED);
  EXPECT_NE(held.error().message().find("retry after"), std::string::npos) << held.DebugString();
  std::this_thread::sleep_for(std::chrono::milliseconds(350));
  EXPECT_EQ(attempt("guess").error().code(), v1::ERROR_CODE_UNAUTHENTICATED);
  // The next wait is twice as long: 350 ms is no longer enough.
  std::this_thread::sleep_for(std::chrono::milliseconds(350));
  EXPECT_EQ(attempt(tokens_["alice"]).error().code(), v1::ERROR_CODE_RESOURCE_EXHAUSTED);
  std::this_thread::sleep_for(std::chrono::milliseconds(350));
  EXPECT_TRUE(attempt(tokens_["alice"]).has_welcome()) << "a success after the wait";
  // ... which resets the count.
  EXPECT_EQ(attempt("guess").error().code(), v1::ERROR_CODE_UNAUTHENTICATED);
  EXPECT_TRUE(attempt(tokens_["alice"]).has_welcome());
}

TEST_F(NamedUsersTest, ReloadAddsAndRemovesUsersAndKeepsThemOnABadFile) {
  UserTable t = UserTable::Load(users_.string()).value();
  const std::string dave = NewToken();
  t.Put({"dave", UserRole::kSculptor, HashToken(dave).value()});
  t.Remove("alice");
  ASSERT_TRUE(t.Save(users_.string()).ok());
  {
    RawClient c(port_);
    auto r = Hello(c, "dave", dave, v1::ROLE_SCULPTOR);
    ASSERT_TRUE(r && r->has_error()) << "not before the reload";
  }
  ASSERT_TRUE(server_->ReloadUsers().ok());
  {
    RawClient c(port_);
    auto r = Hello(c, "dave", dave, v1::ROLE_SCULPTOR);
    ASSERT_TRUE(r && r->has_welcome());
  }
  {
    RawClient c(port_);
    auto r = Hello(c, "alice", tokens_["alice"], v1::ROLE_SCULPTOR);
    ASSERT_TRUE(r && r->has_error()) << "alice was removed";
  }
  ::chmod(users_.c_str(), 0644);
  const Status bad = server_->ReloadUsers();
  EXPECT_FALSE(bad.ok());
  EXPECT_NE(bad.message().find("mode 0644"), std::string::npos);
  RawClient c(port_);
  auto r = Hello(c, "dave", dave, v1::ROLE_SCULPTOR);
  EXPECT_TRUE(r && r->has_welcome()) << "the previous users stay in force";
}

TEST(NamedUsersConfigTest, DevelopmentTokensStayOnLoopback) {
  ServerConfig c;
  c.listen = "0.0.0.0:7420";
  c.tls.allow_plaintext = true;  // the TLS rule aside (TlsTest)
  const Status s = ValidateConfig(c);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("development tokens"), std::string::npos) << s;
  c.users_file = "/etc/sculpt/users.toml";
  EXPECT_TRUE(ValidateConfig(c).ok());
  c.users_file.clear();
  c.sculptor_token = "a-long-sculptor-secret";
  c.viewer_token = "a-long-viewer-secret";
  EXPECT_TRUE(ValidateConfig(c).ok());
  ServerConfig local;
  local.listen = "127.0.0.1:7420";
  EXPECT_TRUE(ValidateConfig(local).ok());
}

TEST(NamedUsersConfigTest, ServerRefusesToStartOnABadUsersFile) {
  const fs::path dir = TestDir("start");
  ServerConfig c;
  c.listen = "127.0.0.1:0";
  c.data_dir = (dir / "data").string();
  c.users_file = (dir / "users.toml").string();
  WriteFile(dir / "users.toml", "", 0640);
  auto scene = Scene::Open(c);
  ASSERT_TRUE(scene.ok()) << scene.status();
  asio::io_context io;
  Server server(io, c, **scene);
  auto port = server.Start();
  ASSERT_FALSE(port.ok());
  EXPECT_NE(port.status().message().find("mode 0640"), std::string::npos) << port.status();
  server.Stop();
  scene->reset();
  fs::remove_all(dir);
}

}  // namespace
}  // namespace sculpt::server
