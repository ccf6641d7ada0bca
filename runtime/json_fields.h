// skintune (internal): reading the fields of parsed JSON files (reports,
// winners databases) with errors that name the element.
//
// Every reader throws Error("missing 'x'") / Error("'x' must be a string")
// ...; At(context, element, read) prefixes such an error (or a nlohmann::json
// exception) with "<context>: <element>: ", so the message names the file and
// the element, e.g. "db.json: entries[3]: 'lang' must be a string".
#pragma once

#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "base/error.h"

namespace skintune::internal::json_fields {

// Runs `read`, prefixing any error with "<context>: <element>: ".
template <typename F>
auto At(const std::string& context, const std::string& element, F&& read) -> decltype(read()) {
  try {
    return read();
  } catch (const nlohmann::json::exception& e) {
    throw Error(context + ": " + element + ": " + e.what());
  } catch (const Error& e) {
    throw Error(context + ": " + element + ": " + e.what());
  }
}

inline const nlohmann::json& Field(const nlohmann::json& object, const char* name) {
  if (!object.contains(name)) throw Error(std::string("missing '") + name + "'");
  return object.at(name);
}

inline std::string String(const nlohmann::json& object, const char* name) {
  const nlohmann::json& v = Field(object, name);
  if (!v.is_string()) throw Error(std::string("'") + name + "' must be a string");
  return v.get<std::string>();
}

// The string field `name`, or "" when the object has none.
inline std::string OptionalString(const nlohmann::json& object, const char* name) {
  return object.contains(name) ? String(object, name) : std::string();
}

inline double Number(const nlohmann::json& object, const char* name) {
  const nlohmann::json& v = Field(object, name);
  if (!v.is_number()) throw Error(std::string("'") + name + "' must be a number");
  return v.get<double>();
}

inline std::int64_t Integer(const nlohmann::json& object, const char* name) {
  const nlohmann::json& v = Field(object, name);
  if (!v.is_number_integer()) throw Error(std::string("'") + name + "' must be an integer");
  return v.get<std::int64_t>();
}

inline bool Boolean(const nlohmann::json& object, const char* name) {
  const nlohmann::json& v = Field(object, name);
  if (!v.is_boolean()) throw Error(std::string("'") + name + "' must be true or false");
  return v.get<bool>();
}

inline const nlohmann::json& Array(const nlohmann::json& object, const char* name) {
  const nlohmann::json& v = Field(object, name);
  if (!v.is_array()) throw Error(std::string("'") + name + "' must be an array");
  return v;
}

// The header of a skintune JSON file: an object whose "schema_version" has
// major version 1 (any 1.x is read) and whose "kind" is `kind`. `written` is
// the version this skintune writes, quoted in the error.
inline void CheckHeader(const nlohmann::json& json, const std::string& context, const char* kind,
                        const char* written) {
  if (!json.is_object()) throw Error(context + ": expected a JSON object");
  const std::string version = At(context, "schema_version", [&] { return String(json, "schema_version"); });
  if (version.substr(0, version.find('.')) != "1") {
    throw Error(context + ": schema_version '" + version + "' is not supported (this skintune reads 1.x, writes " +
                written + ")");
  }
  const std::string actual = At(context, "kind", [&] { return String(json, "kind"); });
  if (actual != kind) throw Error(context + ": kind is '" + actual + "', expected '" + kind + "'");
}

}  // namespace skintune::internal::json_fields
