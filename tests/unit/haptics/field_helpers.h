/// @brief Analytic signed distance scenes sampled onto DenseSdf nodes for the haptics tests.
#ifndef SCULPT_TESTS_UNIT_HAPTICS_FIELD_HELPERS_H_
#define SCULPT_TESTS_UNIT_HAPTICS_FIELD_HELPERS_H_

#include <memory>

#include "sculpt/haptics/penalty.h"
#include "sculpt/levelset/dense_field.h"

namespace sculpt::haptics::testing {

/// A DenseSdf that owns its field: phi(x) sampled at origin + (i, j, k) h, dims n.
class OwnedDenseSdf : public DenseSdf {
 public:
  template <typename F>
  OwnedDenseSdf(Vec3 o, double spacing, levelset::Int3 n, F phi)
      : storage_(std::make_unique<levelset::DenseField>(levelset::Int3{0, 0, 0}, n, 0.0f)) {
    for (int k = 0; k < n.z; ++k)
      for (int j = 0; j < n.y; ++j)
        for (int i = 0; i < n.x; ++i)
          storage_->at(i, j, k) = static_cast<float>(phi(o + Vec3{double(i), double(j), double(k)} * spacing));
    field = storage_.get();
    origin = o;
    h = spacing;
  }

 private:
  std::unique_ptr<levelset::DenseField> storage_;
};

/// Material below the plane z = height (phi = z - height), on [-n/2, n/2]^3 with h = 1.
inline std::shared_ptr<const OwnedDenseSdf> Floor(double height, int n = 40) {
  const double o = -n / 2.0;
  return std::make_shared<const OwnedDenseSdf>(Vec3{o, o, o}, 1.0, levelset::Int3{n + 1, n + 1, n + 1},
                                               [height](const Vec3& p) { return p.z - height; });
}

/// Nothing: phi = +10 everywhere.
inline std::shared_ptr<const OwnedDenseSdf> Empty(int n = 40) {
  const double o = -n / 2.0;
  return std::make_shared<const OwnedDenseSdf>(Vec3{o, o, o}, 1.0, levelset::Int3{n + 1, n + 1, n + 1},
                                               [](const Vec3&) { return 10.0; });
}

}  // namespace sculpt::haptics::testing

#endif  // SCULPT_TESTS_UNIT_HAPTICS_FIELD_HELPERS_H_
