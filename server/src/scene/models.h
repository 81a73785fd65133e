/// @brief Hyperpatch models as scene objects (issue 7, seed 001 §8.1, §10.4-10.5): a content
/// hash and the model files written beside snapshots. sculpt/codec/model_messages.h decodes the
/// ModelIntent off the wire and sculpt/codec/log_records.h holds its edit-log record; the scene's
/// model path (Scene::EditModel) lives in models.cc.
#ifndef SCULPT_SERVER_SCENE_MODELS_H_
#define SCULPT_SERVER_SCENE_MODELS_H_

#include <cstdint>
#include <string>

#include "sculpt/core/status.h"
#include "sculpt/hetero/composite_model.h"
#include "sculpt/hetero/grid_editor.h"

namespace sculpt::server {

/// FNV-1a over the model's content (materials, coefficient positions and fractions bit for bit,
/// cells' pool indices, corner flags); cell versions are not content and are left out.
uint64_t ModelHash(const hetero::CompositeModel& model);

/// A model as saved beside the snapshots: the edit-log sequence it includes, its version and
/// the model itself (model_io's JSON).
struct SavedModel {
  uint64_t seq = 0;
  uint64_t version = 0;
  hetero::CompositeModel model;
};
/// Writes `path` atomically (temporary file, fsync, rename). Internal on I/O errors.
Status SaveModelFile(const std::string& path, uint64_t seq, uint64_t version,
                     const hetero::CompositeModel& model);
/// Reads what SaveModelFile wrote; NotFound when absent, DataLoss when it does not parse.
StatusOr<SavedModel> LoadModelFile(const std::string& path);

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_MODELS_H_
