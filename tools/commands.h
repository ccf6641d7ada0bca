// skintune command-line tool: one file per subcommand. Each Register* adds
// its subcommand and options to the CLI11 app and returns the action to run
// when that subcommand was chosen. Actions throw skintune::internal::Error for bad
// input; main() prints it as one line and exits 1.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "model/asset.h"
#include "base/input_file.h"  // ParseJson, ReadJsonFile: the JSON files the commands take

namespace skintune::internal::tools {

struct Command {
  CLI::App* subcommand;
  std::function<int()> run;
};

Command RegisterRun(CLI::App& app);
Command RegisterDevices(CLI::App& app);
Command RegisterSkin(CLI::App& app);
Command RegisterVariants(CLI::App& app);
Command RegisterEmit(CLI::App& app);
Command RegisterTune(CLI::App& app);
Command RegisterTuneWorker(CLI::App& app);
Command RegisterDb(CLI::App& app);
Command RegisterReport(CLI::App& app);
// `paper` records its own command line in the result it writes.
Command RegisterPaper(CLI::App& app, int argc, char** argv);

// How a command names its input mesh: a synthetic dataset key or a glTF file.
struct MeshSource {
  std::string dataset;    // key (see model/synthetic.h), or empty
  std::string mesh_file;  // .gltf / .glb, or empty
  std::string mesh_name;  // node/mesh name inside the file, or empty
  bool strict = false;    // reject glTF weights that do not sum to 1
  bool normals = false;   // import/generate normals
  bool tangents = false;  // import TANGENT (glTF only: every primitive must have it)
};

// Every option naming a file or folder: '' is a command-line error naming
// the option ("--config: an empty path names no file ..."), never "not given".
CLI::Validator NonEmptyPath();

// --budget of tune and paper: a whole number 0..kMaxBudget (tuner/tune.h),
// refused as a command-line error otherwise ("-3" is not wrapped around).
CLI::Validator BudgetCheck();

// --max-error of tune and emit: a finite number >= 0 (runtime/source_error.h
// BadMaxError); Error("<flag> '<text>': ...") naming the flag otherwise.
double ParseMaxError(const std::string& text, const std::string& flag);

// Adds --dataset / --mesh / --mesh-name / --strict to `sub`.
void AddMeshSourceOptions(CLI::App& sub, MeshSource& source);
// Loads the asset, printing import warnings on stderr ("skintune: warning: ...").
// A synthetic dataset is first checked to fit in memory with
// `work_bytes_per_vertex` more per vertex for what the command does with it
// (`work` names it in the error, e.g. "reference output").
SkinnedAsset LoadAsset(const MeshSource& source, std::uint64_t work_bytes_per_vertex = 0, const std::string& work = "");

}  // namespace skintune::internal::tools
