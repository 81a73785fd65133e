/// @brief Material distributions: simplex validation, eq. (4.3) mixing and simplex projection.
#include "sculpt/hetero/material.h"

#include <algorithm>
#include <cmath>
#include <functional>

#include "sculpt/core/check.h"

namespace sculpt::hetero {

Status ValidateFractions(const std::string& field, std::span<const double> a, int materials) {
  if (static_cast<int>(a.size()) != materials) {
    return Outside(field + ".size", std::to_string(a.size()),
                   std::string("[") + std::to_string(materials) + ", " + std::to_string(materials) +
                       "] (one fraction per declared material)");
  }
  double sum = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    SCULPT_RETURN_IF_ERROR(CheckRange(field + "[" + std::to_string(i) + "]", a[i], 0.0, 1.0));
    sum += a[i];
  }
  if (std::abs(sum - 1.0) > kSimplexSumTolerance) {
    return Outside(field + ".sum", FormatNumber(sum),
                   std::string("[") + FormatNumber(1.0 - kSimplexSumTolerance) + ", " +
                       FormatNumber(1.0 + kSimplexSumTolerance) + "] (fractions sum to 1)");
  }
  return Status::Ok();
}

StatusOr<Fractions> Mix(std::span<const double> a, std::span<const double> b, double alpha) {
  SCULPT_RETURN_IF_ERROR(CheckRange("alpha", alpha, 0.0, 1.0));
  const int n = static_cast<int>(a.size());
  SCULPT_RETURN_IF_ERROR(ValidateFractions("a", a, n));
  SCULPT_RETURN_IF_ERROR(ValidateFractions("b", b, n));
  Fractions out(a.size());
  MixUnchecked(a, b, alpha, out);
  return out;
}

void MixUnchecked(std::span<const double> a, std::span<const double> b, double alpha,
                  std::span<double> out) {
  double sum = 0;
  for (size_t i = 0; i < out.size(); ++i) {
    // Rounding can push a 0 fraction to -1e-17; clamp, then renormalise the tiny excess away.
    out[i] = std::clamp(alpha * a[i] + (1.0 - alpha) * b[i], 0.0, 1.0);
    sum += out[i];
  }
  if (sum > 0) {
    for (double& x : out) x /= sum;
  }
}

Fractions ProjectToSimplex(std::span<const double> a) {
  const size_t n = a.size();
  Fractions v(n);
  for (size_t i = 0; i < n; ++i) v[i] = std::isfinite(a[i]) ? a[i] : 0.0;
  if (n == 0) return v;
  // Held & Wolfe / Duchi et al.: find the threshold tau with sum(max(v - tau, 0)) = 1.
  Fractions s = v;
  std::sort(s.begin(), s.end(), std::greater<double>());
  double cumulative = 0, tau = 0;
  for (size_t k = 0; k < n; ++k) {
    cumulative += s[k];
    const double t = (cumulative - 1.0) / static_cast<double>(k + 1);
    if (s[k] - t > 0) tau = t;
  }
  for (double& x : v) x = std::max(x - tau, 0.0);
  return v;
}

Fractions PureMaterial(int index, int materials) {
  Fractions a(static_cast<size_t>(std::max(materials, 0)), 0.0);
  if (index >= 0 && index < materials) a[static_cast<size_t>(index)] = 1.0;
  return a;
}

}  // namespace sculpt::hetero
