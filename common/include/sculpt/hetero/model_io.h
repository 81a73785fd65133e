/// @brief Composite models as JSON files (seed 001 §9.2.4 "file"; §10.5's concise form: a pool
/// of coefficients plus 64 indices per cell and per-corner flags). Every field read is validated.
#ifndef SCULPT_HETERO_MODEL_IO_H_
#define SCULPT_HETERO_MODEL_IO_H_

#include <string>

#include "sculpt/core/status.h"
#include "sculpt/hetero/composite_model.h"

namespace sculpt::hetero {

/// The document's "format" value.
inline constexpr const char* kModelFormat = "sculpt-hetero-model";

/// Serialises a model (format, version 1, materials, coefficients [x, y, z, a0..an-1], cells,
/// corner flags). `name` and `description` are stored for people.
std::string ModelToJson(const CompositeModel& model, const std::string& name = "",
                        const std::string& description = "");

/// Parses and validates a model. InvalidArgument naming the JSON path, the value and the allowed
/// range for anything malformed (wrong format, too many materials, non-finite coordinates,
/// fractions outside V, cell indices out of range, more than `max_cells` cells).
StatusOr<CompositeModel> ModelFromJson(const std::string& text, size_t max_cells = 100000);

/// File forms. NotFound / DataLoss on I/O failure.
Status SaveModel(const CompositeModel& model, const std::string& path,
                 const std::string& name = "", const std::string& description = "");
StatusOr<CompositeModel> LoadModel(const std::string& path, size_t max_cells = 100000);

}  // namespace sculpt::hetero

#endif  // SCULPT_HETERO_MODEL_IO_H_
