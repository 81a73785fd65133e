/// @brief `sculpt undo|redo`: --help, the options it refuses, and what it prints for the answers
/// of a scripted server (FakeSculptd), without sculptd.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "unit/client/fake_sculptd.h"

namespace sculpt {
namespace {

namespace fs = std::filesystem;
using testing_support::AcceptedUndo;
using testing_support::ErrorMessage;
using testing_support::FakeSculptd;
using Reply = FakeSculptd::Reply;

class UndoCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("sculpt_undo_cli_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  /// Runs `sculpt ARGS` (from the build's bin/) with a clean SCULPT_CLIENT_ID / SCULPT_TOKEN;
  /// returns the exit code, stdout and stderr together in `out`.
  int Sculpt(const std::string& args, std::string* out, const std::string& env = "") {
    const fs::path file = dir_ / "output";
    const std::string cmd = "env -u SCULPT_CLIENT_ID -u SCULPT_TOKEN " + env + " " +
                            std::string(SCULPT_BIN_DIR) + "/sculpt " + args + " > " +
                            file.string() + " 2>&1";
    const int status = std::system(cmd.c_str());
    std::ifstream in(file);
    std::stringstream ss;
    ss << in.rdbuf();
    *out = ss.str();
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

  std::string Server() const { return "--server 127.0.0.1:" + std::to_string(fake_.port()); }

  FakeSculptd fake_;
  fs::path dir_;
};

TEST_F(UndoCliTest, HelpNamesTheOptionsAndThePerAuthorRule) {
  for (const char* verb : {"undo", "redo"}) {
    std::string out;
    ASSERT_EQ(Sculpt(std::string(verb) + " --help", &out), 0) << out;
    for (const char* option : {"--server", "--object", "--steps", "--client-id", "--token-file",
                               "--json", "--tls", "SCULPT_CLIENT_ID", "Exit status"}) {
      EXPECT_NE(out.find(option), std::string::npos) << verb << " --help lacks " << option;
    }
  }
  std::string top;
  Sculpt("--help", &top);
  EXPECT_NE(top.find("undo"), std::string::npos) << top;
  EXPECT_NE(top.find("redo"), std::string::npos) << top;
}

TEST_F(UndoCliTest, RejectsMissingServerAndBadSteps) {
  std::string out;
  EXPECT_NE(Sculpt("undo --client-id 5", &out), 0);
  EXPECT_NE(out.find("--server"), std::string::npos) << out;
  EXPECT_NE(Sculpt("undo " + Server() + " --client-id 5 --steps 0", &out), 0);
  EXPECT_NE(out.find("--steps"), std::string::npos) << out;
  EXPECT_EQ(Sculpt("undo --server nowhere --client-id 5", &out), 2) << out;
  EXPECT_NE(out.find("HOST:PORT"), std::string::npos) << out;
  EXPECT_TRUE(fake_.received().empty());
}

TEST_F(UndoCliTest, RejectsATokenOnTheCommandLine) {
  std::string out;
  EXPECT_EQ(Sculpt("undo " + Server() + " --client-id 5 --token s3cret", &out), 2) << out;
  EXPECT_NE(out.find("--token-file"), std::string::npos) << out;
  EXPECT_NE(out.find("SCULPT_TOKEN"), std::string::npos) << out;
  EXPECT_TRUE(fake_.received().empty()) << "refused before connecting";
}

TEST_F(UndoCliTest, RequiresAClientIdAndRejectsABadOne) {
  std::string out;
  EXPECT_EQ(Sculpt("undo " + Server(), &out), 2) << out;
  EXPECT_NE(out.find("--client-id"), std::string::npos) << out;
  EXPECT_EQ(Sculpt("undo " + Server() + " --client-id 0", &out), 2) << out;
  EXPECT_NE(out.find("--client-id=0 outside [1, 2^63 - 1]"), std::string::npos) << out;
  EXPECT_EQ(Sculpt("redo " + Server(), &out, "SCULPT_CLIENT_ID=12x"), 2) << out;
  EXPECT_NE(out.find("$SCULPT_CLIENT_ID=12x"), std::string::npos) << out;
  EXPECT_TRUE(fake_.received().empty());
}

TEST_F(UndoCliTest, PrintsTheTargetTheReplayedEditsAndTheDepth) {
  fake_.set_handler([](const v1::ClientMessage& m, int) {
    Reply r;
    if (!m.has_undo()) return r;
    v1::ServerMessage a = AcceptedUndo(m.undo(), 90, 42);
    v1::UndoAck* ack = a.mutable_undo_ack();
    ack->set_replayed(3);
    for (auto [who, n] : {std::pair{"alice", 2}, std::pair{"bob", 1}}) {
      v1::ReplayedEdits* by = ack->add_replayed_by();
      by->set_author(who);
      by->set_edits(n);
    }
    ack->set_undo_depth(4);
    ack->set_redo_depth(1);
    r.messages.push_back(a);
    return r;
  });
  std::string out;
  ASSERT_EQ(Sculpt("undo " + Server(), &out, "SCULPT_CLIENT_ID=4242"), 0) << out;
  EXPECT_NE(out.find("undone: edit at seq 42 on clay"), std::string::npos) << out;
  EXPECT_NE(out.find("3 later edits replayed (alice 2, bob 1)"), std::string::npos) << out;
  EXPECT_NE(out.find("can undo 4 more, redo 1"), std::string::npos) << out;

  const auto hellos = fake_.received();
  ASSERT_FALSE(hellos.empty());
  EXPECT_EQ(hellos[0].second.hello().client_id(), 4242u);
  EXPECT_EQ(hellos[0].second.hello().role(), v1::ROLE_SCULPTOR);
  EXPECT_EQ(hellos[0].second.hello().token(), "sculpt-dev-sculptor");
  ASSERT_EQ(fake_.undos().size(), 1u);
  EXPECT_EQ(fake_.undos()[0].object(), "clay") << "the scene's first object";
  EXPECT_GT(fake_.undos()[0].client_seq(), uint64_t{1} << 50)
      << "numbered from the clock: an earlier run under the same id used lower numbers";

  ASSERT_EQ(Sculpt("redo " + Server() + " --client-id 4242 --object stone --json", &out), 0)
      << out;
  const auto j = nlohmann::json::parse(out.substr(out.find('{')));
  EXPECT_EQ(j["ok"], true);
  EXPECT_EQ(j["object"], "stone");
  EXPECT_EQ(j["steps_done"], 1);
  EXPECT_EQ(j["steps"][0]["target_seq"], 42);
  EXPECT_EQ(j["steps"][0]["replayed_by"]["alice"], 2);
  EXPECT_TRUE(fake_.undos().back().redo());
}

TEST_F(UndoCliTest, NothingToUndoIsAClearErrorAfterTheStepsDone) {
  int answered = 0;
  fake_.set_handler([&answered](const v1::ClientMessage& m, int) {
    Reply r;
    if (!m.has_undo()) return r;
    if (answered++ < 2) {
      r.messages.push_back(AcceptedUndo(m.undo(), 50 + answered, 10 - answered));
      return r;
    }
    v1::ServerMessage a;
    a.mutable_undo_ack()->set_client_seq(m.undo().client_seq());
    *a.mutable_undo_ack()->mutable_error() =
        ErrorMessage(v1::ERROR_CODE_FAILED_PRECONDITION, "", m.undo().client_seq(),
                     "undo: author=\"7\" has nothing to undo")
            .error();
    r.messages.push_back(a);
    return r;
  });
  std::string out;
  EXPECT_EQ(Sculpt("undo " + Server() + " --client-id 7 --steps 5", &out), 1) << out;
  EXPECT_NE(out.find("undone: edit at seq 9"), std::string::npos) << out;
  EXPECT_NE(out.find("undone: edit at seq 8"), std::string::npos) << out;
  EXPECT_NE(out.find("nothing to undo on clay for client id 7"), std::string::npos) << out;
  EXPECT_NE(out.find("undid 2 of 5 steps"), std::string::npos) << out;
  EXPECT_EQ(fake_.undos().size(), 3u) << "stops at the first refusal";
}

TEST_F(UndoCliTest, AnOlderServerIsNamed) {
  fake_.set_handler([](const v1::ClientMessage& m, int) {
    Reply r;
    if (m.has_undo()) {
      r.messages.push_back(
          ErrorMessage(v1::ERROR_CODE_MALFORMED, "ClientMessage.body", 0, "unknown message"));
    }
    return r;
  });
  std::string out;
  EXPECT_EQ(Sculpt("undo " + Server() + " --client-id 7 --timeout 20", &out), 1) << out;
  EXPECT_NE(out.find("does not know undo"), std::string::npos) << out;
}

}  // namespace
}  // namespace sculpt
