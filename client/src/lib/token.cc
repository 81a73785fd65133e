/// @brief Token files and the environment as the clients' only sources of secrets.
#include "sculpt/client/token.h"

#include <sys/stat.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>

namespace sculpt::client {

StatusOr<std::string> ReadTokenFile(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return NotFound("token file " + path + " does not exist");
    return FailedPrecondition("token file " + path + ": " + std::strerror(errno));
  }
  if (!S_ISREG(st.st_mode)) return FailedPrecondition("token file " + path + " is not a file");
  // A secret others can read is a secret given away; a file others can write lets them choose
  // which server account this client speaks for.
  if ((st.st_mode & 077) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
    return FailedPrecondition("token file " + path + " has mode " + mode +
                              ": it must not be readable or writable by group or others "
                              "(chmod 600 " +
                              path + ")");
  }
  std::ifstream in(path);
  if (!in) {
    return FailedPrecondition("token file " + path + " is not readable: " + std::strerror(errno));
  }
  std::string line;
  std::getline(in, line);
  const char* blanks = " \t\r\n";
  const size_t begin = line.find_first_not_of(blanks);
  if (begin == std::string::npos) {
    return InvalidArgument("token file " + path + ": the first line is empty (it holds the token)");
  }
  const size_t end = line.find_last_not_of(blanks);
  return line.substr(begin, end - begin + 1);
}

StatusOr<std::string> ResolveToken(const std::string& file, const char* env_var,
                                   std::string fallback) {
  if (!file.empty()) return ReadTokenFile(file);
  if (const char* v = std::getenv(env_var); v != nullptr && *v != '\0') return std::string(v);
  return fallback;
}

std::string TokenFlagRefusal(std::string_view flag, std::string_view file_flag,
                             std::string_view env_var) {
  std::string m(flag);
  m += " is refused: a command line is visible to every local user. Put the token in a file "
       "readable by you only and pass ";
  m += file_flag;
  m += " PATH, or set the environment variable ";
  m += env_var;
  return m;
}

}  // namespace sculpt::client
