/// @brief Unit tests for the contour frames: each frame decodes back to what was encoded, and is
/// the frame the scene built before from the wire message.
#include "sculpt/codec/contour_frames.h"

#include <gtest/gtest.h>

#include <string>

#include "sculpt/codec/frame.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {
namespace {

v1::ServerMessage Parse(const SharedFrame& frame) {
  FrameReader reader;
  reader.Feed(frame->data(), frame->size());
  auto next = reader.Next();
  EXPECT_TRUE(next.ok() && next->has_value());
  v1::ServerMessage m;
  if (next.ok() && next->has_value()) {
    EXPECT_TRUE(m.ParseFromString(**next));
  }
  EXPECT_EQ(reader.buffered(), 0u) << "one frame, nothing after it";
  return m;
}

class ContourFramesTest : public ::testing::Test {};

TEST_F(ContourFramesTest, SkinUpdateCarriesTheChainOfBalls) {
  ContourUpdateFrame u;
  u.skin = "outline";
  u.data = std::string("\x01\x02\x00\x03", 4);
  u.sections = 2;
  u.skin_version = 7;
  u.balls = {{0, 0, 1, 0}, {2.5, -1, 0.5, 0.125}};
  const SharedFrame f = EncodeContourUpdate(u);
  const v1::ServerMessage m = Parse(f);
  ASSERT_TRUE(m.has_contour());
  const v1::ContourUpdate& c = m.contour();
  EXPECT_EQ(c.skin(), "outline");
  EXPECT_EQ(c.object(), "");
  EXPECT_EQ(c.data(), u.data);
  EXPECT_EQ(c.sections(), 2u);
  EXPECT_EQ(c.skin_version(), 7u);
  EXPECT_EQ(c.global_seq(), 0u);
  ASSERT_EQ(c.balls_size(), 2);
  EXPECT_EQ(c.balls(1).x(), 2.5);
  EXPECT_EQ(c.balls(1).y(), -1);
  EXPECT_EQ(c.balls(1).r(), 0.5);
  EXPECT_EQ(c.balls(1).theta(), 0.125);

  // The frame the scene built from the message before.
  v1::ServerMessage before;
  v1::ContourUpdate* b = before.mutable_contour();
  b->set_skin("outline");
  b->set_data(u.data);
  b->set_sections(2);
  b->set_skin_version(7);
  for (const SkinBall& o : u.balls) {
    v1::SkinBall* w = b->add_balls();
    w->set_x(o.x);
    w->set_y(o.y);
    w->set_r(o.r);
    w->set_theta(o.theta);
  }
  std::string want;
  ASSERT_TRUE(AppendMessage(before, &want));
  EXPECT_EQ(*f, want);
}

TEST_F(ContourFramesTest, SliceNamesItsObjectAndSequence) {
  ContourUpdateFrame u;
  u.object = "clay";
  u.data = "contours";
  u.sections = 3;
  u.global_seq = 123456789012;
  const v1::ServerMessage m = Parse(EncodeContourUpdate(u));
  ASSERT_TRUE(m.has_contour());
  EXPECT_EQ(m.contour().skin(), "");
  EXPECT_EQ(m.contour().object(), "clay");
  EXPECT_EQ(m.contour().data(), "contours");
  EXPECT_EQ(m.contour().sections(), 3u);
  EXPECT_EQ(m.contour().global_seq(), 123456789012u);
  EXPECT_EQ(m.contour().balls_size(), 0);
}

}  // namespace
}  // namespace sculpt::codec
