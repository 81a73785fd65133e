/// @brief Unit tests for ModelBook without a scene: a two-box hyperpatch model opened from its
/// JSON or its saved file, intents checked on a copy and applied, refusals by field and by
/// validity, recovery's replay past a file's sequence, and save and reopen.
#include "scene/models.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

#include "sculpt/hetero/composite_model.h"
#include "sculpt/hetero/construction.h"
#include "sculpt/hetero/hyperpatch.h"
#include "sculpt/hetero/model_io.h"
#include "sculpt/hetero/validity.h"

namespace sculpt::server {
namespace {

namespace fs = std::filesystem;

constexpr const char* kObject = "part";

class ModelBookTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("sculpt_model_book_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    // Two glued 4-unit boxes of two materials.
    auto model =
        hetero::CompositeModel::Create({{"steel", {0.6, 0.6, 0.6}}, {"bronze", {0.8, 0.5, 0.2}}});
    ASSERT_TRUE(model.ok()) << model.status();
    model_ = std::move(model).value();
    hetero::ValidityChecker checker;
    auto a = hetero::LibraryBox({0, 0, 0}, {4, 4, 4}, std::vector<double>{1, 0});
    auto b = hetero::LibraryBox({4, 0, 0}, {8, 4, 4}, std::vector<double>{0, 1});
    ASSERT_TRUE(a.ok() && b.ok());
    for (const auto* p : {&*a, &*b}) {
      auto r = hetero::AddCellChecked(&model_, &checker, *p, hetero::CellSource::kLibrary);
      ASSERT_TRUE(r.ok() && r->added);
    }
    const std::string path = (dir_ / "two_boxes.json").string();
    ASSERT_TRUE(hetero::SaveModel(model_, path, "two boxes").ok());
    ObjectConfig sphere;  // not a model: the book holds nothing for it
    sphere.name = "clay";
    ObjectConfig part;
    part.name = kObject;
    part.primitive = "model";
    part.model = path;
    objects_ = {sphere, part};
    data_dir_ = (dir_ / "data").string();
    ASSERT_TRUE(book_.Open(objects_, data_dir_).ok());
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Pool index of the corner coefficient of `cell` at slot (i, j, k) in {0, 3}.
  uint32_t Corner(int cell, int i, int j, int k) const {
    return model_.cell(cell).coef[static_cast<size_t>(hetero::Hyperpatch::Index(i, j, k))];
  }
  static codec::ModelEdit Intent(uint32_t corner, Vec3 d) {
    codec::ModelEdit e;
    e.client_seq = 1;
    e.object = kObject;
    e.intent.corner = corner;
    e.intent.displacement = d;
    e.intent.cell = -1;
    return e;
  }
  // Prepares and applies `edit` as the commit pipeline does.
  ModelBook::Stamp Apply(ModelBook& book, const codec::ModelEdit& edit) {
    ModelBook::IntentPlan plan;
    const Status st = book.PrepareIntent(edit, &plan);
    EXPECT_TRUE(st.ok()) << st;
    return book.ApplyIntent(std::move(plan));
  }

  fs::path dir_;
  std::string data_dir_;
  hetero::CompositeModel model_{2};
  std::vector<ObjectConfig> objects_;
  ModelBook book_;
};

TEST_F(ModelBookTest, OpensTheModelObjectsFromTheirJson) {
  auto info = book_.Info(kObject);
  ASSERT_TRUE(info.ok()) << info.status();
  EXPECT_EQ(info->version, 0u);
  EXPECT_EQ(info->cells, 2u);
  EXPECT_EQ(info->coefficients, model_.coefficient_count());
  EXPECT_EQ(info->hash, ModelHash(model_));
  const Status sphere = book_.Info("clay").status();
  EXPECT_EQ(sphere.code(), Status::Code::kNotFound);
  EXPECT_NE(sphere.message().find("clay"), std::string::npos) << sphere;
  EXPECT_FALSE(book_.StampOf("clay").has_value());
}

TEST_F(ModelBookTest, RejectsAModelJsonThatDoesNotLoad) {
  std::vector<ObjectConfig> objects = objects_;
  objects[1].model = (dir_ / "missing.json").string();
  ModelBook book;
  const Status st = book.Open(objects, data_dir_);
  EXPECT_FALSE(st.ok());
  EXPECT_NE(st.message().find("scene.objects part.model="), std::string::npos) << st;
}

TEST_F(ModelBookTest, AnAppliedIntentChangesTheModelHashAndVersion) {
  const uint64_t before = book_.Info(kObject)->hash;
  ModelBook::IntentPlan plan;
  ASSERT_TRUE(book_.PrepareIntent(Intent(Corner(0, 0, 0, 0), {-0.3, 0, 0}), &plan).ok());
  EXPECT_GE(plan.moved, 1u);
  EXPECT_EQ(plan.version, 1u);
  EXPECT_EQ(book_.Info(kObject)->hash, before);  // prepared on a copy: nothing changed yet
  const ModelBook::Stamp stamp = book_.ApplyIntent(std::move(plan));
  EXPECT_EQ(stamp.version, 1u);
  EXPECT_NE(stamp.hash, before);
  EXPECT_EQ(book_.Info(kObject)->hash, stamp.hash);
  EXPECT_EQ(book_.StampOf(kObject)->hash, stamp.hash);
  EXPECT_EQ(book_.StampOf(kObject)->version, 1u);
}

TEST_F(ModelBookTest, RejectsIntentOnAnUnknownModelObject) {
  codec::ModelEdit e = Intent(0, {0.1, 0, 0});
  e.object = "clay";
  ModelBook::IntentPlan plan;
  const Status st = book_.PrepareIntent(e, &plan);
  EXPECT_EQ(st.code(), Status::Code::kNotFound);
  ASSERT_NE(st.violation(), nullptr);
  EXPECT_EQ(st.violation()->field, "ModelIntent.object");
  EXPECT_EQ(st.violation()->value, "clay");
  EXPECT_FALSE(plan.rejection.has_value());
}

TEST_F(ModelBookTest, RejectsCornerAndCellOutOfRange) {
  ModelBook::IntentPlan plan;
  const uint32_t n = static_cast<uint32_t>(model_.coefficient_count());
  const Status corner = book_.PrepareIntent(Intent(n, {0.1, 0, 0}), &plan);
  EXPECT_EQ(corner.code(), Status::Code::kInvalidArgument);
  ASSERT_NE(corner.violation(), nullptr);
  EXPECT_EQ(corner.violation()->field, "ModelIntent.corner");
  EXPECT_EQ(corner.violation()->allowed_range, "[0, " + std::to_string(n - 1) + "]");
  codec::ModelEdit e = Intent(Corner(0, 0, 0, 0), {0.1, 0, 0});
  e.intent.cell = 2;
  const Status cell = book_.PrepareIntent(e, &plan);
  ASSERT_NE(cell.violation(), nullptr);
  EXPECT_EQ(cell.violation()->field, "ModelIntent.cell");
  EXPECT_EQ(cell.violation()->allowed_range, "[-1, 1]");
}

TEST_F(ModelBookTest, RejectsAnIntentThatFoldsACellWithTheReason) {
  const uint64_t before = book_.Info(kObject)->hash;
  ModelBook::IntentPlan plan;
  // The first box's corner pushed through the opposite face (x = 4).
  const Status st = book_.PrepareIntent(Intent(Corner(0, 0, 0, 0), {6, 0, 0}), &plan);
  EXPECT_EQ(st.code(), Status::Code::kFailedPrecondition);
  ASSERT_NE(st.violation(), nullptr);
  EXPECT_EQ(st.violation()->field, "ModelIntent");
  ASSERT_TRUE(plan.rejection.has_value());
  EXPECT_GE(plan.rejection->cell, 0);
  EXPECT_EQ(plan.now.version, 0u);
  EXPECT_EQ(plan.now.hash, before);
  EXPECT_EQ(book_.Info(kObject)->hash, before);
}

TEST_F(ModelBookTest, SaveAndLoadRoundTrip) {
  const ModelBook::Stamp stamp = Apply(book_, Intent(Corner(1, 3, 3, 3), {0.2, 0.2, 0.2}));
  ASSERT_TRUE(book_.Save(12));
  ModelBook reopened;
  ASSERT_TRUE(reopened.Open(objects_, data_dir_).ok());
  auto info = reopened.Info(kObject);
  ASSERT_TRUE(info.ok()) << info.status();
  EXPECT_EQ(info->version, 1u);
  EXPECT_EQ(info->hash, stamp.hash);
  EXPECT_EQ(info->json, book_.Info(kObject)->json);
  auto saved = LoadModelFile((fs::path(data_dir_) / "models" / "part.json").string());
  ASSERT_TRUE(saved.ok()) << saved.status();
  EXPECT_EQ(saved->seq, 12u);
}

TEST_F(ModelBookTest, ReplaySkipsIntentsItsFileHoldsAndAppliesLaterOnes) {
  ASSERT_TRUE(book_.Save(10));
  ModelBook reopened;
  ASSERT_TRUE(reopened.Open(objects_, data_dir_).ok());
  const uint64_t before = reopened.Info(kObject)->hash;
  codec::ModelRecord rec;
  rec.edit = Intent(Corner(0, 0, 0, 0), {-0.3, 0, 0});
  rec.model_version = 1;
  reopened.Replay(10, rec);  // at the file's seq: already in it
  EXPECT_EQ(reopened.Info(kObject)->hash, before);
  EXPECT_EQ(reopened.Info(kObject)->version, 0u);
  reopened.Replay(11, rec);
  EXPECT_NE(reopened.Info(kObject)->hash, before);
  EXPECT_EQ(reopened.Info(kObject)->version, 1u);
  // The same as the live path.
  EXPECT_EQ(reopened.Info(kObject)->hash, Apply(book_, rec.edit).hash);
  // Refused live, refused on replay: nothing changes.
  codec::ModelRecord fold = rec;
  fold.edit = Intent(Corner(0, 0, 0, 0), {6, 0, 0});
  fold.model_version = 2;
  const uint64_t after = reopened.Info(kObject)->hash;
  reopened.Replay(12, fold);
  EXPECT_EQ(reopened.Info(kObject)->hash, after);
  EXPECT_EQ(reopened.Info(kObject)->version, 1u);
}

}  // namespace
}  // namespace sculpt::server
