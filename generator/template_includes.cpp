#include "generator/template_includes.h"

#include <algorithm>
#include <cstdio>
#include <map>
#include <vector>

#include "base/error.h"

namespace skintune::internal {
namespace {

constexpr const char* kBlanks = " \t\r";

// Whether `line` is a preprocessor #include; `rest` gets the text after the word.
bool IsInclude(const std::string& line, std::string& rest) {
  std::size_t at = line.find_first_not_of(kBlanks);
  if (at == std::string::npos || line[at] != '#') return false;
  at = line.find_first_not_of(kBlanks, at + 1);
  if (at == std::string::npos || line.compare(at, 7, "include") != 0) return false;
  rest = line.substr(at + 7);
  return true;
}

// FILE of `"FILE"` followed by nothing but blanks or a // comment; "" for any other form.
std::string QuotedFile(const std::string& rest) {
  const std::size_t open = rest.find_first_not_of(kBlanks);
  if (open == std::string::npos || rest[open] != '"') return "";
  const std::size_t close = rest.find('"', open + 1);
  if (close == std::string::npos) return "";
  const std::size_t after = rest.find_first_not_of(kBlanks, close + 1);
  if (after != std::string::npos && rest.compare(after, 2, "//") != 0) return "";
  return rest.substr(open + 1, close - open - 1);
}

std::string Trimmed(const std::string& s) {
  const std::size_t begin = s.find_first_not_of(kBlanks);
  if (begin == std::string::npos) return "";
  return s.substr(begin, s.find_last_not_of(kBlanks) - begin + 1);
}

class Expander {
 public:
  Expander(const TemplateLookup& lookup, bool glsl) : lookup_(lookup), glsl_(glsl) {}

  // Appends `text` (file `name`, GLSL source string `source`) to the output,
  // its includes expanded.
  void Expand(const std::string& name, const std::string& text, int source) {
    int line_number = 0;
    std::string resume;  // the #line back into this file after an include, written before its next line
    for (std::size_t begin = 0; begin < text.size();) {
      const std::size_t end = text.find('\n', begin);
      const std::string line = text.substr(begin, end == std::string::npos ? std::string::npos : end - begin);
      begin = end == std::string::npos ? text.size() : end + 1;
      ++line_number;
      std::string rest;
      if (!IsInclude(line, rest)) {
        out_ += resume;
        resume.clear();
        out_ += line;
        if (end != std::string::npos) out_ += '\n';
        continue;
      }
      const std::string where = name + ":" + std::to_string(line_number);
      const std::string chain = Chain();
      const std::string file = QuotedFile(rest);
      if (file.empty())
        throw Error(where + ": '" + Trimmed(line) + "': a template may only #include \"FILE\", a file of templates/" +
                    chain);
      const auto previous = included_at_.find(file);
      if (previous != included_at_.end())
        throw Error(where + ": #include \"" + file + "\": already included (" + previous->second +
                    "); its text would be compiled twice" + chain);
      const std::optional<std::string> included = lookup_(file);
      if (!included) throw Error(where + ": #include \"" + file + "\": no such file in templates/" + chain);
      included_at_[file] = "at " + where;
      const int included_source = next_source_++;
      out_ += LineDirective(1, file, included_source);
      from_.push_back(where);
      Expand(file, *included, included_source);
      from_.pop_back();
      if (!out_.empty() && out_.back() != '\n') out_ += '\n';
      resume = LineDirective(line_number + 1, name, source);
    }
  }

  void MarkRoot(const std::string& name) { included_at_[name] = "it is the file being expanded"; }
  std::string Take() { return std::move(out_); }

 private:
  // " (included from b:5, from a:3)": the includes that led to the current file.
  std::string Chain() const {
    std::string chain;
    for (auto at = from_.rbegin(); at != from_.rend(); ++at)
      chain += (chain.empty() ? " (included from " : ", from ") + *at;
    return chain.empty() ? "" : chain + ")";
  }

  std::string LineDirective(int line, const std::string& file, int source) const {
    if (glsl_) return "#line " + std::to_string(line) + " " + std::to_string(source) + "  // " + file + "\n";
    return "#line " + std::to_string(line) + " \"" + file + "\"\n";
  }

  const TemplateLookup& lookup_;
  const bool glsl_;
  std::map<std::string, std::string> included_at_;  // file -> where it was included
  std::vector<std::string> from_;                    // the includes being expanded, outermost first
  int next_source_ = 1;                              // GLSL source-string numbers; 0 is the root
  std::string out_;
};

}  // namespace

std::string ExpandIncludes(const std::string& name, const std::string& text, const TemplateLookup& lookup) {
  Expander expander(lookup, text.rfind("#version", 0) == 0);
  expander.MarkRoot(name);
  expander.Expand(name, text, 0);
  return expander.Take();
}

std::string GlslSourceStrings(const std::string& expanded) {
  std::map<int, std::string> files;  // source-string number -> file
  for (std::size_t begin = 0; begin < expanded.size();) {
    const std::size_t end = std::min(expanded.find('\n', begin), expanded.size());
    const std::string line = expanded.substr(begin, end - begin);
    begin = end + 1;
    if (line.rfind("#line ", 0) != 0) continue;
    const std::size_t comment = line.find("  // ");
    if (comment == std::string::npos) continue;
    int number = 0, source = -1;
    if (std::sscanf(line.c_str(), "#line %d %d", &number, &source) != 2 || source < 0) continue;
    files.emplace(source, Trimmed(line.substr(comment + 5)));
  }
  std::string legend;
  for (const auto& [source, file] : files) legend += (legend.empty() ? " (source strings: " : ", ") + std::to_string(source) + " " + file;
  return legend.empty() ? "" : legend + ")";
}

}  // namespace skintune::internal
