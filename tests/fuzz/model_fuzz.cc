/// @brief libFuzzer target for hetero::ModelFromJson (the hyperpatch model JSON).
#include <cstddef>
#include <cstdint>
#include <string>

#include "sculpt/hetero/model_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  auto model = sculpt::hetero::ModelFromJson(text, /*max_cells=*/4096);
  if (model.ok()) {
    // What loaded must save and load again.
    auto again = sculpt::hetero::ModelFromJson(sculpt::hetero::ModelToJson(*model), 4096);
    (void)again;
  }
  return 0;
}
