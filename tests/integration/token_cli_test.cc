/// @brief Secrets stay off command lines: the clients refuse token flags with directions and take
/// tokens from a file (owner-only) or the environment (issue 14).
#include "sculpt/client/token.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "integration/in_process_server.h"

namespace sculpt {
namespace {

namespace fs = std::filesystem;

class TokenTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("sculpt_token_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  /// Writes `text` to a file in the test directory with permission bits `mode`.
  std::string TokenFile(const std::string& name, const std::string& text, mode_t mode) {
    const fs::path p = dir_ / name;
    std::ofstream(p) << text;
    EXPECT_EQ(::chmod(p.c_str(), mode), 0);
    return p.string();
  }

  /// Runs `command` through the shell (binaries from the build's bin/); returns its exit code,
  /// its output (spdlog writes to stdout) and standard error in `err`.
  int Run(const std::string& command, std::string* err) {
    const fs::path err_file = dir_ / "output";
    const std::string cmd = "cd " + std::string(SCULPT_BIN_DIR) + " && " + command +
                            " > " + err_file.string() + " 2>&1";
    const int status = std::system(cmd.c_str());
    std::ifstream in(err_file);
    std::stringstream ss;
    ss << in.rdbuf();
    *err = ss.str();
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

  fs::path dir_;
};

TEST_F(TokenTest, ReadsTheFirstLineWithoutBlanks) {
  auto t = client::ReadTokenFile(TokenFile("t", "  s3cret-token \r\nsecond line\n", 0600));
  ASSERT_TRUE(t.ok()) << t.status();
  EXPECT_EQ(*t, "s3cret-token");
  auto owner_read_only = client::ReadTokenFile(TokenFile("r", "abc", 0400));
  ASSERT_TRUE(owner_read_only.ok()) << owner_read_only.status();
  EXPECT_EQ(*owner_read_only, "abc");
}

TEST_F(TokenTest, RejectsMissingTokenFile) {
  auto t = client::ReadTokenFile((dir_ / "nosuch").string());
  ASSERT_FALSE(t.ok());
  EXPECT_EQ(t.status().code(), Status::Code::kNotFound);
  EXPECT_NE(t.status().message().find("does not exist"), std::string::npos) << t.status();
}

TEST_F(TokenTest, RejectsTokenFileOthersCanReadOrWrite) {
  for (mode_t mode : {0644, 0640, 0604, 0620, 0602}) {
    const std::string path = TokenFile("t" + std::to_string(mode), "s3cret-token\n", mode);
    auto t = client::ReadTokenFile(path);
    ASSERT_FALSE(t.ok()) << std::oct << mode;
    EXPECT_EQ(t.status().code(), Status::Code::kFailedPrecondition);
    char expected[8];
    std::snprintf(expected, sizeof expected, "%04o", static_cast<unsigned>(mode));
    EXPECT_NE(t.status().message().find(std::string("has mode ") + expected), std::string::npos)
        << t.status();
    EXPECT_NE(t.status().message().find("chmod 600 " + path), std::string::npos) << t.status();
  }
}

TEST_F(TokenTest, RejectsEmptyTokenFileAndDirectory) {
  auto empty = client::ReadTokenFile(TokenFile("e", " \n", 0600));
  ASSERT_FALSE(empty.ok());
  EXPECT_EQ(empty.status().code(), Status::Code::kInvalidArgument);
  fs::create_directories(dir_ / "d");
  ::chmod((dir_ / "d").c_str(), 0700);
  auto directory = client::ReadTokenFile((dir_ / "d").string());
  ASSERT_FALSE(directory.ok());
  EXPECT_EQ(directory.status().code(), Status::Code::kFailedPrecondition);
}

TEST_F(TokenTest, FileBeforeEnvironmentBeforeDevelopmentToken) {
  const char* env = "SCULPT_TOKEN_TEST_ONLY";
  ::unsetenv(env);
  EXPECT_EQ(client::ResolveToken("", env, "dev").value(), "dev");
  ::setenv(env, "", 1);
  EXPECT_EQ(client::ResolveToken("", env, "dev").value(), "dev") << "an empty variable is unset";
  ::setenv(env, "from-env", 1);
  EXPECT_EQ(client::ResolveToken("", env, "dev").value(), "from-env");
  EXPECT_EQ(client::ResolveToken(TokenFile("t", "from-file\n", 0600), env, "dev").value(),
            "from-file");
  // A file that cannot be used is an error, not a silent fall-back to the environment.
  EXPECT_FALSE(client::ResolveToken(TokenFile("w", "x\n", 0644), env, "dev").ok());
  ::unsetenv(env);
}

TEST_F(TokenTest, SculptRefusesTokenFlagWithDirections) {
  std::string err;
  for (const char* sub : {"info --server 127.0.0.1:1", "play --server 127.0.0.1:1",
                          "export --server 127.0.0.1:1 --out x.glb"}) {
    EXPECT_EQ(Run(std::string("./sculpt ") + sub + " --token s3cret-token", &err), 2) << sub;
    EXPECT_NE(err.find("--token is refused"), std::string::npos) << sub << ": " << err;
    EXPECT_NE(err.find("--token-file PATH"), std::string::npos) << err;
    EXPECT_NE(err.find("SCULPT_TOKEN"), std::string::npos) << err;
    EXPECT_EQ(err.find("s3cret-token"), std::string::npos) << "the refusal repeats the secret";
  }
}

TEST_F(TokenTest, LoadgenRefusesTokenFlagsWithDirections) {
  std::string err;
  EXPECT_EQ(Run("./sculpt-loadgen --server 127.0.0.1:1 --sculptor-token s3cret-token", &err), 2);
  EXPECT_NE(err.find("--sculptor-token is refused"), std::string::npos) << err;
  EXPECT_NE(err.find("--sculptor-token-file PATH"), std::string::npos) << err;
  EXPECT_NE(err.find("SCULPT_SCULPTOR_TOKEN"), std::string::npos) << err;
  EXPECT_EQ(Run("./sculpt-loadgen --server 127.0.0.1:1 --viewer-token s3cret-token", &err), 2);
  EXPECT_NE(err.find("--viewer-token-file PATH"), std::string::npos) << err;
  EXPECT_NE(err.find("SCULPT_VIEWER_TOKEN"), std::string::npos) << err;
}

TEST_F(TokenTest, SculptRefusesWorldReadableTokenFileBeforeConnecting) {
  const std::string f = TokenFile("open", "viewer-secret-22\n", 0644);
  std::string err;
  EXPECT_EQ(Run("./sculpt info --server 127.0.0.1:1 --token-file " + f, &err), 2);
  EXPECT_NE(err.find("chmod 600"), std::string::npos) << err;
}

// The token from a file and from SCULPT_TOKEN reaches a server whose tokens are not the
// development ones; a wrong one is refused by the server.
TEST_F(TokenTest, SculptTakesTokenFromFileOrEnvironment) {
  testing_support::InProcessServer srv("token_cli");
  srv.config().sculptor_token = "sculptor-secret-11";
  srv.config().viewer_token = "viewer-secret-22";
  ASSERT_TRUE(srv.Start());
  const std::string info = "./sculpt info --server 127.0.0.1:" + std::to_string(srv.port());
  std::string err;
  EXPECT_EQ(Run(info + " --token-file " + TokenFile("v", "viewer-secret-22\n", 0600), &err), 0)
      << err;
  EXPECT_EQ(Run("SCULPT_TOKEN=viewer-secret-22 " + info, &err), 0) << err;
  EXPECT_EQ(Run("SCULPT_TOKEN=wrong-token-33 " + info, &err), 1) << err;
  EXPECT_NE(err.find("UNAUTHENTICATED"), std::string::npos) << err;
  EXPECT_EQ(Run(info, &err), 1) << "the development token is not this server's: " << err;
}

}  // namespace
}  // namespace sculpt
