/// @brief Unit tests for decoding ModelIntent: each refusal names field, value and range.
#include "sculpt/codec/model_messages.h"

#include <gtest/gtest.h>

#include <limits>
#include <string>

#include "unit/codec/field_violation.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {
namespace {

using testing::IsViolation;

v1::ModelIntent MakeIntent() {
  v1::ModelIntent m;
  m.set_client_seq(3);
  m.set_object("part");
  m.set_corner(17);
  for (int o : {1, 0, -1}) m.add_offset(o);
  m.set_displacement_x(-0.02);
  m.set_displacement_y(0.5);
  m.set_displacement_z(0);
  m.set_cell(-1);
  return m;
}

class DecodeModelIntentTest : public ::testing::Test {};

TEST_F(DecodeModelIntentTest, AcceptsAnIntent) {
  auto e = DecodeModelIntent(MakeIntent());
  ASSERT_TRUE(e.ok()) << e.status();
  EXPECT_EQ(e->client_seq, 3u);
  EXPECT_EQ(e->object, "part");
  EXPECT_EQ(e->intent.corner, 17u);
  EXPECT_EQ(e->intent.offset, (std::array<int, 3>{1, 0, -1}));
  EXPECT_EQ(e->intent.displacement.x, -0.02);
  EXPECT_EQ(e->intent.displacement.y, 0.5);
  EXPECT_EQ(e->intent.cell, -1);
  EXPECT_FALSE(e->intent.set_flags.has_value());
}

TEST_F(DecodeModelIntentTest, CarriesFlagsOnlyWhenSet) {
  v1::ModelIntent m = MakeIntent();
  m.set_geometry_c1(true);
  auto unset = DecodeModelIntent(m);
  ASSERT_TRUE(unset.ok()) << unset.status();
  EXPECT_FALSE(unset->intent.set_flags.has_value());
  m.set_set_flags(true);
  auto set = DecodeModelIntent(m);
  ASSERT_TRUE(set.ok()) << set.status();
  ASSERT_TRUE(set->intent.set_flags.has_value());
  EXPECT_TRUE(set->intent.set_flags->geometry_c1);
  EXPECT_FALSE(set->intent.set_flags->material_c1);
}

TEST_F(DecodeModelIntentTest, EncodeDecodesBackToTheSameIntent) {
  v1::ModelIntent m = MakeIntent();
  m.set_set_flags(true);
  m.set_material_c1(true);
  m.set_cell(4);
  auto e = DecodeModelIntent(m);
  ASSERT_TRUE(e.ok()) << e.status();
  EXPECT_EQ(EncodeModelIntent(*e).SerializeAsString(), m.SerializeAsString());
  const ModelEdit back = ModelEditFromRecord(EncodeModelIntent(*e));
  EXPECT_EQ(back.intent.corner, e->intent.corner);
  EXPECT_EQ(back.intent.cell, 4);
  EXPECT_EQ(back.intent.set_flags, e->intent.set_flags);
}

TEST_F(DecodeModelIntentTest, RejectsObjectEmpty) {
  v1::ModelIntent m = MakeIntent();
  m.set_object("");
  EXPECT_TRUE(IsViolation(DecodeModelIntent(m).status(), "ModelIntent.object", "",
                          "names of 1..64 bytes"));
}

TEST_F(DecodeModelIntentTest, RejectsObjectTooLong) {
  v1::ModelIntent m = MakeIntent();
  const std::string name(65, 'p');
  m.set_object(name);
  EXPECT_TRUE(IsViolation(DecodeModelIntent(m).status(), "ModelIntent.object", name,
                          "names of 1..64 bytes"));
}

TEST_F(DecodeModelIntentTest, RejectsOffsetSizeNotThree) {
  v1::ModelIntent m = MakeIntent();
  m.add_offset(0);
  EXPECT_TRUE(
      IsViolation(DecodeModelIntent(m).status(), "ModelIntent.offset size", "4", "{3}"));
}

TEST_F(DecodeModelIntentTest, RejectsOffsetOutsideUnitStep) {
  v1::ModelIntent m = MakeIntent();
  m.set_offset(2, -2);
  EXPECT_TRUE(
      IsViolation(DecodeModelIntent(m).status(), "ModelIntent.offset[2]", "-2", "[-1, 1]"));
}

TEST_F(DecodeModelIntentTest, RejectsDisplacementXNan) {
  v1::ModelIntent m = MakeIntent();
  m.set_displacement_x(std::numeric_limits<double>::quiet_NaN());
  EXPECT_TRUE(IsViolation(DecodeModelIntent(m).status(), "ModelIntent.displacement_x", "nan",
                          "finite [-1e+06, 1e+06]"));
}

TEST_F(DecodeModelIntentTest, RejectsDisplacementYAboveMaximum) {
  v1::ModelIntent m = MakeIntent();
  m.set_displacement_y(2e6);
  EXPECT_TRUE(IsViolation(DecodeModelIntent(m).status(), "ModelIntent.displacement_y", "2e+06",
                          "finite [-1e+06, 1e+06]"));
}

TEST_F(DecodeModelIntentTest, RejectsDisplacementZBelowMinimum) {
  v1::ModelIntent m = MakeIntent();
  m.set_displacement_z(-1.5e6);
  EXPECT_TRUE(IsViolation(DecodeModelIntent(m).status(), "ModelIntent.displacement_z",
                          "-1.5e+06", "finite [-1e+06, 1e+06]"));
}

TEST_F(DecodeModelIntentTest, RejectsCellBelowNone) {
  v1::ModelIntent m = MakeIntent();
  m.set_cell(-2);
  EXPECT_TRUE(IsViolation(DecodeModelIntent(m).status(), "ModelIntent.cell", "-2",
                          "-1 (none) or a cell index >= 0"));
}

}  // namespace
}  // namespace sculpt::codec
