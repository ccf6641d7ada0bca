// Reading the JSON files the commands take (configs, reports, databases), with
// errors that name the file.
#include <fstream>
#include <sstream>

#include "reference/error.h"
#include "tools/commands.h"

namespace skintune::internal::tools {

nlohmann::json ParseJson(const std::string& text, const std::string& name) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    throw Error(name + ": not valid JSON (" + e.what() + ")");
  }
}

nlohmann::json ReadJsonFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path + ": cannot open file");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw Error(path + ": cannot read file");
  return ParseJson(text.str(), path);
}

}  // namespace skintune::internal::tools
