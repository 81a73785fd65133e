/// @brief Unit tests for length-prefixed frames: round trips under any chunking, limits, errors.
#include "sculpt/codec/frame.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {
namespace {

/// Distinct payloads of varied sizes, including empty ones and bytes >= 0x80 in the header.
std::vector<std::string> Payloads() {
  std::vector<std::string> out;
  std::mt19937 rng(1234);
  std::uniform_int_distribution<int> byte(0, 255);
  for (size_t size : {0, 1, 3, 4, 5, 127, 128, 255, 256, 1000, 0, 40000, 65536, 70000, 17}) {
    std::string p(size, '\0');
    for (char& c : p) c = static_cast<char>(byte(rng));
    out.push_back(std::move(p));
  }
  return out;
}

std::string Stream(const std::vector<std::string>& payloads) {
  std::string s;
  for (const std::string& p : payloads) AppendFrame(p, &s);
  return s;
}

/// Takes every complete frame out; fails the test on an error.
void Drain(FrameReader& reader, std::vector<std::string>* out) {
  for (;;) {
    StatusOr<std::optional<std::string>> next = reader.Next();
    ASSERT_TRUE(next.ok()) << next.status();
    if (!next->has_value()) return;
    out->push_back(std::move(**next));
  }
}

std::string Header(uint32_t n) {
  std::string h;
  for (size_t i = 0; i < kFrameHeaderBytes; ++i) {
    h.push_back(static_cast<char>((n >> (8 * i)) & 0xff));
  }
  return h;
}

TEST(FrameTest, AppendFrameWritesLittleEndianLength) {
  std::string out = "x";
  AppendFrame(std::string(0x0102, 'a'), &out);
  ASSERT_EQ(out.size(), 1 + kFrameHeaderBytes + 0x0102);
  EXPECT_EQ(out.substr(1, 4), std::string("\x02\x01\x00\x00", 4));
}

TEST(FrameTest, RoundTripOneByteAtATime) {
  const std::vector<std::string> payloads = Payloads();
  const std::string stream = Stream(payloads);
  FrameReader reader;
  std::vector<std::string> got;
  for (char c : stream) {
    reader.Feed(&c, 1);
    Drain(reader, &got);
  }
  EXPECT_EQ(got, payloads);
  EXPECT_EQ(reader.buffered(), 0u);
}

TEST(FrameTest, RoundTripRandomChunks) {
  const std::vector<std::string> payloads = Payloads();
  const std::string stream = Stream(payloads);
  std::mt19937 rng(42);
  for (int trial = 0; trial < 20; ++trial) {
    std::uniform_int_distribution<size_t> chunk(1, 1 + trial * 997);
    FrameReader reader;
    std::vector<std::string> got;
    size_t at = 0;
    while (at < stream.size()) {
      const size_t n = std::min(chunk(rng), stream.size() - at);
      reader.Feed(stream.data() + at, n);
      at += n;
      Drain(reader, &got);
    }
    EXPECT_EQ(got, payloads) << "trial " << trial;
    EXPECT_EQ(reader.buffered(), 0u);
  }
}

TEST(FrameTest, RoundTripProtobufMessages) {
  std::string stream;
  for (uint64_t seq = 0; seq < 50; ++seq) {
    v1::ClientMessage m;
    m.mutable_stroke()->set_client_seq(seq);
    m.mutable_stroke()->set_object("clay");
    ASSERT_TRUE(AppendMessage(m, &stream));
  }
  FrameReader reader;
  reader.Feed(stream.data(), stream.size());
  std::vector<std::string> got;
  Drain(reader, &got);
  ASSERT_EQ(got.size(), 50u);
  for (uint64_t seq = 0; seq < 50; ++seq) {
    v1::ClientMessage m;
    ASSERT_TRUE(m.ParseFromString(got[seq]));
    EXPECT_EQ(m.stroke().client_seq(), seq);
    EXPECT_EQ(m.stroke().object(), "clay");
  }
}

TEST(FrameTest, ZeroLengthPayload) {
  std::string stream;
  AppendFrame("", &stream);
  ASSERT_EQ(stream.size(), kFrameHeaderBytes);
  FrameReader reader;
  reader.Feed(stream.data(), stream.size());
  StatusOr<std::optional<std::string>> next = reader.Next();
  ASSERT_TRUE(next.ok()) << next.status();
  ASSERT_TRUE(next->has_value());
  EXPECT_TRUE((*next)->empty());
  EXPECT_EQ(reader.buffered(), 0u);
}

TEST(FrameTest, HeaderSplitAcrossFeeds) {
  std::string stream;
  AppendFrame("hello", &stream);
  FrameReader reader;
  reader.Feed(stream.data(), 2);
  StatusOr<std::optional<std::string>> next = reader.Next();
  ASSERT_TRUE(next.ok());
  EXPECT_FALSE(next->has_value());
  reader.Feed(stream.data() + 2, 3);  // the header's last two bytes and one payload byte
  next = reader.Next();
  ASSERT_TRUE(next.ok());
  EXPECT_FALSE(next->has_value());
  EXPECT_EQ(reader.buffered(), 5u);
  reader.Feed(stream.data() + 5, stream.size() - 5);
  next = reader.Next();
  ASSERT_TRUE(next.ok());
  ASSERT_TRUE(next->has_value());
  EXPECT_EQ(**next, "hello");
}

TEST(FrameTest, AcceptsFrameOfExactlyMax) {
  constexpr uint32_t kMax = 100;
  std::string stream;
  AppendFrame(std::string(kMax, 'z'), &stream);
  FrameReader reader(kMax);
  reader.Feed(stream.data(), stream.size());
  StatusOr<std::optional<std::string>> next = reader.Next();
  ASSERT_TRUE(next.ok()) << next.status();
  ASSERT_TRUE(next->has_value());
  EXPECT_EQ((*next)->size(), kMax);
}

TEST(FrameTest, RejectsOversizedFrame) {
  const uint32_t max = kDefaultMaxFrameBytes;
  FrameReader reader;
  const std::string header = Header(max + 1);
  reader.Feed(header.data(), header.size());
  StatusOr<std::optional<std::string>> next = reader.Next();
  ASSERT_FALSE(next.ok());
  EXPECT_EQ(next.status().code(), Status::Code::kResourceExhausted);
  EXPECT_EQ(next.status().message(), "frame length=" + std::to_string(max + 1) + " outside [0, " +
                                         std::to_string(max) + "]");
  // Only the header was stored: the declared megabyte was never allocated.
  EXPECT_EQ(reader.buffered(), kFrameHeaderBytes);
  // The error is sticky: the stream cannot be resynchronised.
  EXPECT_FALSE(reader.Next().ok());
}

TEST(FrameTest, RejectsOversizedFrameOfHugeDeclaredLength) {
  FrameReader reader(64);
  const std::string header = Header(0xffffffffu);
  reader.Feed(header.data(), header.size());
  StatusOr<std::optional<std::string>> next = reader.Next();
  ASSERT_FALSE(next.ok());
  EXPECT_EQ(next.status().message(), "frame length=4294967295 outside [0, 64]");
  EXPECT_EQ(reader.buffered(), kFrameHeaderBytes);
}

TEST(FrameTest, PartialFrameStaysBuffered) {
  std::string stream;
  AppendFrame("truncated payload", &stream);
  FrameReader reader;
  reader.Feed(stream.data(), stream.size() - 3);
  StatusOr<std::optional<std::string>> next = reader.Next();
  ASSERT_TRUE(next.ok());
  EXPECT_FALSE(next->has_value());
  // A clean close now would be a truncation the caller can see.
  EXPECT_EQ(reader.buffered(), stream.size() - 3);
}

}  // namespace
}  // namespace sculpt::codec
