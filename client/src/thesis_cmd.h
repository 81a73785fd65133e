/// @brief `sculpt thesis`: reruns the thesis's 2D experiments (seed 000 §6.2, §6.3) and prints
/// measured against published numbers as JSON.
#ifndef SCULPT_CLIENT_THESIS_CMD_H_
#define SCULPT_CLIENT_THESIS_CMD_H_

#include <string>

namespace sculpt::client {

/// Returns the JSON document (pretty-printed).
std::string RunThesisReproduction();

}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_THESIS_CMD_H_
