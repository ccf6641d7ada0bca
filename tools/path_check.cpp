// The check every option naming a file or folder takes (tools/commands.h).
#include "tools/commands.h"

namespace skintune::internal::tools {

CLI::Validator NonEmptyPath() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        return text.empty() ? "an empty path names no file (an unset variable?)" : "";
      },
      "PATH");
}

}  // namespace skintune::internal::tools
