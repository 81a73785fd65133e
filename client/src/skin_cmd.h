/// @brief `sculpt skin`: builds the skin of a chain of oriented balls read from JSON, prints the
/// per-section validation report and writes the point lists (JSON and the binary contour form).
#ifndef SCULPT_CLIENT_SKIN_CMD_H_
#define SCULPT_CLIENT_SKIN_CMD_H_

#include <CLI/CLI.hpp>
#include <string>

namespace sculpt::client {

struct SkinCmdOptions {
  std::string balls;     // JSON file
  std::string method;    // empty: the file's, else hybrid
  double tolerance = 0;  // <= 0: the file's, else 1e-3 of the smallest radius
  std::string out_json, out_bin;
};

/// The ball file format, shown by `sculpt skin --help`.
extern const char* const kSkinFileHelp;

/// Adds the `skin` subcommand to `app`, filling `o`.
CLI::App* AddSkinCommand(CLI::App& app, SkinCmdOptions& o);

/// Runs it: 0 on success (whether or not every section is total: the report says), 1 for a file
/// that cannot be read or written, 2 for bad input (the message names the field).
int RunSkin(const SkinCmdOptions& o);

}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_SKIN_CMD_H_
