#include "net/static_files.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

namespace sculpt::server {
namespace {

namespace fs = std::filesystem;

class StaticFilesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / ("sculpt_static_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_ / "web" / "assets");
    std::ofstream(root_ / "web" / "index.html") << "<p>hi</p>";
    std::ofstream(root_ / "web" / "assets" / "main-1a2b.js") << "x";
    std::ofstream(root_ / "secret") << "s";
  }
  void TearDown() override { fs::remove_all(root_); }
  fs::path root_;
};

TEST_F(StaticFilesTest, ServesIndexForTheRoot) {
  StaticFiles files(root_ / "web");
  auto f = files.Lookup("/?x=1");
  ASSERT_TRUE(f.ok()) << f.status();
  EXPECT_EQ(f->body, "<p>hi</p>");
  EXPECT_EQ(f->content_type, "text/html; charset=utf-8");
  EXPECT_EQ(f->cache_control, "no-cache");
  EXPECT_FALSE(f->etag.empty());
}

TEST_F(StaticFilesTest, HashedAssetsAreImmutable) {
  StaticFiles files(root_ / "web");
  auto f = files.Lookup("/assets/main-1a2b.js");
  ASSERT_TRUE(f.ok()) << f.status();
  EXPECT_EQ(f->cache_control, "public, max-age=31536000, immutable");
}

TEST_F(StaticFilesTest, RejectsTraversal) {
  StaticFiles files(root_ / "web");
  for (const char* bad : {"/../secret", "/%2e%2e/secret", "/assets/../../secret", "/a//b",
                          "/./index.html", "/a\\b", "/a%00", "/%zz", "/%4", "index.html", ""}) {
    auto f = files.Lookup(bad);
    EXPECT_FALSE(f.ok()) << bad;
    EXPECT_EQ(f.status().code(), Status::Code::kInvalidArgument) << bad;
  }
}

TEST_F(StaticFilesTest, MissingFileAndDirectoryAreNotFound) {
  StaticFiles files(root_ / "web");
  EXPECT_EQ(files.Lookup("/nope.js").status().code(), Status::Code::kNotFound);
  EXPECT_EQ(files.Lookup("/assets").status().code(), Status::Code::kNotFound);
}

TEST_F(StaticFilesTest, MissingRootNamesItself) {
  StaticFiles files(root_ / "nowhere");
  EXPECT_FALSE(files.root_exists());
  auto f = files.Lookup("/");
  ASSERT_FALSE(f.ok());
  EXPECT_EQ(f.status().code(), Status::Code::kNotFound);
  EXPECT_NE(f.status().message().find("nowhere"), std::string::npos);
}

TEST(ContentTypeTest, KnownExtensions) {
  EXPECT_EQ(StaticFiles::ContentType("a.wasm"), "application/wasm");
  EXPECT_EQ(StaticFiles::ContentType("a.mjs"), "text/javascript; charset=utf-8");
  EXPECT_EQ(StaticFiles::ContentType("a.css"), "text/css; charset=utf-8");
  EXPECT_EQ(StaticFiles::ContentType("a.png"), "image/png");
  EXPECT_EQ(StaticFiles::ContentType("a.json"), "application/json");
  EXPECT_EQ(StaticFiles::ContentType("a.bin"), "application/octet-stream");
}

}  // namespace
}  // namespace sculpt::server
