/// @brief Where the clients' secrets come from: a token file or an environment variable, never a
/// command-line flag (a command line is visible to every local user in `ps`).
#ifndef SCULPT_CLIENT_TOKEN_H_
#define SCULPT_CLIENT_TOKEN_H_

#include <string>
#include <string_view>

#include "sculpt/core/status.h"

namespace sculpt::client {

/// Reads a token file: its first line without the line end and surrounding blanks. NotFound when
/// the file is missing; FailedPrecondition when it is not a regular file, is unreadable, or is
/// readable or writable by group or others (the message gives the mode and the chmod to run, as
/// sculptd says of a users file); InvalidArgument when the first line is empty.
StatusOr<std::string> ReadTokenFile(const std::string& path);

/// The token to present: read from `file` when it is not empty (errors as ReadTokenFile), else the
/// value of the environment variable `env_var` when set and not empty, else `fallback` (the
/// development token, which sculptd accepts on loopback only).
StatusOr<std::string> ResolveToken(const std::string& file, const char* env_var,
                                   std::string fallback);

/// The refusal of a token given on the command line as `flag`, saying where to put it instead:
/// the file option `file_flag` or the environment variable `env_var`.
std::string TokenFlagRefusal(std::string_view flag, std::string_view file_flag,
                             std::string_view env_var);

}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_TOKEN_H_
