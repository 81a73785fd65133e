/// @brief The token options shared by the `sculpt` subcommands that connect and by
/// sculpt-loadgen: a refused --token style flag, its --token-file and its environment variable.
#ifndef SCULPT_CLIENT_TOKEN_FLAGS_H_
#define SCULPT_CLIENT_TOKEN_FLAGS_H_

#include <CLI/CLI.hpp>
#include <string>

#include "sculpt/client/token.h"
#include "sculpt/core/status.h"

namespace sculpt::client {

/// One secret's options. `flag` is accepted only to be refused with directions.
struct TokenFlags {
  std::string flag = "--token";
  std::string file_flag = "--token-file";
  std::string env = "SCULPT_TOKEN";
  std::string fallback;  // the development token
  std::string given;     // a value passed to `flag` (never used)
  std::string file;
  CLI::Option* flag_option = nullptr;
};

/// Adds `t->flag` and `t->file_flag` to `cmd`; `what` names the secret ("Viewer token"). `t` must
/// outlive parsing.
inline void AddTokenFlags(CLI::App& cmd, TokenFlags* t, const std::string& what) {
  t->flag_option = cmd.add_option(
      t->flag, t->given,
      "Refused: secrets do not go on the command line (see " + t->file_flag + ", " + t->env + ")");
  cmd.add_option(t->file_flag, t->file,
                 what + ": file whose first line is the token, mode 0600 (default: $" + t->env +
                     ", else the development token " + t->fallback + ", loopback only)");
}

/// The token after parsing: FailedPrecondition with directions when `flag` was given, else as
/// ResolveToken (file, environment, development token).
inline StatusOr<std::string> ResolveTokenFlags(const TokenFlags& t) {
  if (t.flag_option != nullptr && t.flag_option->count() > 0) {
    return FailedPrecondition(TokenFlagRefusal(t.flag, t.file_flag, t.env));
  }
  return ResolveToken(t.file, t.env.c_str(), t.fallback);
}

}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_TOKEN_FLAGS_H_
