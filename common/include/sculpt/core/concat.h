/// @brief One-allocation string joining for error messages.
#ifndef SCULPT_CORE_CONCAT_H_
#define SCULPT_CORE_CONCAT_H_

#include <initializer_list>
#include <string>
#include <string_view>

namespace sculpt {

/// Joins the parts into one string with one allocation. Used for messages instead of chains of
/// `"[" + s + "]"`: g++ 12 reports a false -Wrestrict (GCC bug 105329) on
/// `const char* + std::string&&`.
std::string Concat(std::initializer_list<std::string_view> parts);

}  // namespace sculpt

#endif  // SCULPT_CORE_CONCAT_H_
