/// @brief Unit tests for decoding PaintEdit: each refusal names field, value and range.
#include "sculpt/codec/paint_messages.h"

#include <gtest/gtest.h>

#include <limits>
#include <string>

#include "unit/codec/field_violation.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::codec {
namespace {

using testing::IsViolation;

constexpr int kMaterials = 3;

/// A 0.5-voxel object in [0, 40]^3; positions may reach 8 beyond it.
StrokeLimits Limits() {
  StrokeLimits limits;
  limits.voxel_size = 0.5;
  limits.bounds = {{0, 0, 0}, {40, 40, 40}};
  limits.bounds_margin = 8;
  return limits;
}

v1::PaintEdit MakePaint(v1::ToolKind tool = v1::TOOL_KIND_ELLIPSOID) {
  v1::PaintEdit e;
  e.set_client_seq(11);
  e.set_object("clay");
  e.set_tool(tool);
  e.mutable_tool_size()->set_x(2);
  e.mutable_tool_size()->set_y(3);
  e.mutable_tool_size()->set_z(4);
  e.mutable_position()->set_x(10);
  e.mutable_position()->set_y(20);
  e.mutable_position()->set_z(30);
  e.set_material(2);
  e.set_weight(0.5);
  return e;
}

class DecodePaintEditTest : public ::testing::Test {};

TEST_F(DecodePaintEditTest, AcceptsAPaint) {
  auto p = DecodePaintEdit(MakePaint(), Limits(), kMaterials);
  ASSERT_TRUE(p.ok()) << p.status();
  EXPECT_EQ(p->client_seq, 11u);
  EXPECT_EQ(p->object, "clay");
  EXPECT_EQ(p->tool, levelset::ToolKind::kEllipsoid);
  EXPECT_EQ(p->tool_size.z, 4);
  EXPECT_EQ(p->position.y, 20);
  EXPECT_EQ(p->material, 2u);
  EXPECT_EQ(p->weight, 0.5);
  EXPECT_TRUE(p->fractions.empty());
  EXPECT_EQ(p->Tool().kind, levelset::ToolKind::kEllipsoid);
}

TEST_F(DecodePaintEditTest, AcceptsAFillWithoutMaterialOrWeight) {
  v1::PaintEdit e = MakePaint(v1::TOOL_KIND_SPHERE);
  e.mutable_tool_size()->set_y(std::numeric_limits<float>::quiet_NaN());  // unused by a sphere
  e.set_weight(7);  // unused by a fill
  for (double f : {0.25, 0.25, 0.5}) e.add_fractions(f);
  auto p = DecodePaintEdit(e, Limits(), kMaterials);
  ASSERT_TRUE(p.ok()) << p.status();
  EXPECT_EQ(p->fractions, (std::vector<double>{0.25, 0.25, 0.5}));
  EXPECT_EQ(p->weight, 0);
  EXPECT_EQ(p->material, 0u);
  EXPECT_EQ(p->tool_size.y, 0);
}

TEST_F(DecodePaintEditTest, EncodeThenRecordGivesTheSamePaint) {
  v1::PaintEdit e = MakePaint(v1::TOOL_KIND_BOX);
  e.mutable_tool_size()->set_x(0.7f);  // not exact in binary: must survive float -> double
  auto p = DecodePaintEdit(e, Limits(), kMaterials);
  ASSERT_TRUE(p.ok()) << p.status();
  const Paint back = PaintFromRecord(EncodePaintEdit(*p));
  EXPECT_EQ(back.client_seq, p->client_seq);
  EXPECT_EQ(back.object, p->object);
  EXPECT_EQ(back.tool, p->tool);
  EXPECT_EQ(back.tool_size.x, p->tool_size.x);
  EXPECT_EQ(back.position.z, p->position.z);
  EXPECT_EQ(back.material, p->material);
  EXPECT_EQ(back.weight, p->weight);
  EXPECT_EQ(EncodePaintEdit(back).SerializeAsString(), EncodePaintEdit(*p).SerializeAsString());
}

TEST_F(DecodePaintEditTest, RejectsObjectEmpty) {
  v1::PaintEdit e = MakePaint();
  e.set_object("");
  EXPECT_TRUE(IsViolation(DecodePaintEdit(e, Limits(), kMaterials).status(), "PaintEdit.object",
                          "", "names of 1..64 bytes"));
}

TEST_F(DecodePaintEditTest, RejectsObjectWithoutMaterials) {
  EXPECT_TRUE(IsViolation(DecodePaintEdit(MakePaint(), Limits(), 0).status(), "PaintEdit.object",
                          "clay", "scenes that declare materials (this one declares none)",
                          Status::Code::kFailedPrecondition));
}

TEST_F(DecodePaintEditTest, RejectsToolCapsule) {
  EXPECT_TRUE(IsViolation(DecodePaintEdit(MakePaint(v1::TOOL_KIND_CAPSULE), Limits(), kMaterials)
                              .status(),
                          "PaintEdit.tool", "4", "{1 (SPHERE), 2 (ELLIPSOID), 3 (BOX)}"));
}

TEST_F(DecodePaintEditTest, RejectsToolSizeXBelowHalfAVoxel) {
  v1::PaintEdit e = MakePaint();
  e.mutable_tool_size()->set_x(0.1f);
  EXPECT_TRUE(IsViolation(DecodePaintEdit(e, Limits(), kMaterials).status(),
                          "PaintEdit.tool_size.x", "0.1", "[0.25, 64]"));
}

TEST_F(DecodePaintEditTest, RejectsToolSizeZAboveMaximum) {
  v1::PaintEdit e = MakePaint(v1::TOOL_KIND_BOX);
  e.mutable_tool_size()->set_z(65);
  EXPECT_TRUE(IsViolation(DecodePaintEdit(e, Limits(), kMaterials).status(),
                          "PaintEdit.tool_size.z", "65", "[0.25, 64]"));
}

TEST_F(DecodePaintEditTest, RejectsPositionNan) {
  v1::PaintEdit e = MakePaint();
  e.mutable_position()->set_y(std::numeric_limits<float>::quiet_NaN());
  EXPECT_TRUE(IsViolation(DecodePaintEdit(e, Limits(), kMaterials).status(), "PaintEdit.position",
                          "(10, nan, 30)", "finite numbers"));
}

TEST_F(DecodePaintEditTest, RejectsPositionOutsideBounds) {
  v1::PaintEdit e = MakePaint();
  e.mutable_position()->set_x(-9);
  EXPECT_TRUE(IsViolation(DecodePaintEdit(e, Limits(), kMaterials).status(),
                          "PaintEdit.position.x", "-9", "[-8, 48]"));
}

TEST_F(DecodePaintEditTest, RejectsMaterialBeyondTheScenes) {
  v1::PaintEdit e = MakePaint();
  e.set_material(3);
  EXPECT_TRUE(IsViolation(DecodePaintEdit(e, Limits(), kMaterials).status(), "PaintEdit.material",
                          "3", "[0, 2]"));
}

TEST_F(DecodePaintEditTest, RejectsWeightAboveOne) {
  v1::PaintEdit e = MakePaint();
  e.set_weight(1.5);
  EXPECT_TRUE(IsViolation(DecodePaintEdit(e, Limits(), kMaterials).status(), "PaintEdit.weight",
                          "1.5", "[0, 1]"));
}

TEST_F(DecodePaintEditTest, RejectsFractionsSizeNotTheMaterialCount) {
  v1::PaintEdit e = MakePaint();
  e.add_fractions(1);
  EXPECT_TRUE(IsViolation(DecodePaintEdit(e, Limits(), kMaterials).status(),
                          "PaintEdit.fractions.size", "1",
                          "[3, 3] (one fraction per declared material)"));
}

TEST_F(DecodePaintEditTest, RejectsFractionNegative) {
  v1::PaintEdit e = MakePaint();
  for (double f : {0.5, -0.25, 0.75}) e.add_fractions(f);
  EXPECT_TRUE(IsViolation(DecodePaintEdit(e, Limits(), kMaterials).status(),
                          "PaintEdit.fractions[1]", "-0.25", "[0, 1]"));
}

TEST_F(DecodePaintEditTest, RejectsFractionsSumOffOne) {
  v1::PaintEdit e = MakePaint();
  for (double f : {0.5, 0.25, 0.5}) e.add_fractions(f);
  EXPECT_TRUE(IsViolation(DecodePaintEdit(e, Limits(), kMaterials).status(),
                          "PaintEdit.fractions.sum", "1.25",
                          "[0.999999, 1.000001] (fractions sum to 1)"));
}

}  // namespace
}  // namespace sculpt::codec
