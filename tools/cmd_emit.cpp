// skintune emit: one variant's kernel file plus a sidecar JSON describing its
// interface (arguments, formats, strides, launch geometry), so another program
// can bind and launch it without reading skintune's code.
//
//   skintune emit --variant KEY --out DIR [--joints N] [--instances K]
//   skintune emit --db DB.json --device PATTERN --out DIR [--lang L ...] [--joints N]
//                 [--header NAME] [--namespace NS]
//
// The second form emits the winners of a winners database for the matching
// devices (kernel file + sidecar per distinct kernel: single-mesh, crowd
// (instanced) and batch winners) and one generated C++17 header holding all
// of them with packing helpers (tools/emit/embed_header.h,
// docs/RUNTIME.md "Emitting kernels into other builds"). Every file is
// generated in memory first and written (atomically) only when all of them
// were generated.
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <tuple>

#include <nlohmann/json.hpp>

#include "generator/constraints.h"
#include "generator/emit.h"
#include "base/error.h"
#include "reference/mesh_io.h"
#include "runtime/backend_table.h"
#include "runtime/backends/vulkan/vulkan_spirv.h"
#include "tools/emit/embed_header.h"
#include "runtime/winners_db.h"
#include "tools/commands.h"

namespace skintune::internal::tools {

namespace {

struct EmitArgs {
  std::string variant;
  std::string out;
  int joints = 77;
  int instances = 0;  // 0: the plain kernel; K >= 1: instanced, for up to K instances per launch
  int morph_targets = 0;  // the mesh's morph targets: required by a variant that applies them
  // --db mode
  std::string db;
  std::string device;
  std::vector<std::string> langs;
  std::string header = "skintune_kernels.h";
  std::string name_space = "skintune_kernels";
  std::string max_error_text;  // --max-error (ParseMaxError); empty: the default budget
};

// vulkan: the SPIR-V of the kernel (what vkCreateShaderModule takes), as
// bytes for a ".spv" file; "" for the other languages.
std::string SpirvBytes(const KernelSource& source, const Variant& variant) {
  if (source.lang != Lang::kVulkan) return "";
  const std::vector<std::uint32_t> words = vk::CompileSpirv(source.text, "emit " + variant.Key());
  return std::string(reinterpret_cast<const char*>(words.data()), words.size() * 4);
}

// Only a variant's own constraints: device limits are the tuner's business.
DeviceLimits Unlimited() {
  DeviceLimits unlimited;
  unlimited.max_wg_size = 1024;
  unlimited.local_memory_bytes = unlimited.constant_memory_bytes = unlimited.uniform_block_bytes = 1u << 30;
  unlimited.image_buffer_max_texels = 1u << 30;
  return unlimited;
}

void CreateOutputFolder(const std::string& out) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec || !fs::is_directory(out)) throw Error(out + ": cannot create output folder (" + ec.message() + ")");
}

int RunEmit(const EmitArgs& o) {
  const Variant variant = ParseVariantKey(o.variant);
  // Any palette the kernel may be given: rigid ones too (PackPalette refuses a dq palette that is not).
  ProblemShape shape{o.joints, 1, true, std::max(o.instances, 1), true, true};
  shape.morph_targets = o.morph_targets;
  shape.animated = AnimatesOnDevice(variant);  // the skin kernel is the same wherever its palettes are made
  const std::vector<Violation> broken = CheckVariant(variant, Unlimited(), shape);
  if (SkinsMorph(variant) && o.morph_targets == 0)
    throw Error("variant '" + variant.Key() + "' applies morph targets: give the mesh's count with --morph-targets "
                "(it sizes each instance's weights)");
  if (!broken.empty()) {
    throw Error("variant '" + variant.Key() + "' is invalid: " + broken.front().message + " (constraint " +
                Name(broken.front().constraint) + ")");
  }
  EmitOptions options;
  options.instanced = o.instances > 0;
  options.max_instances = o.instances;
  options.morph_targets = o.morph_targets;
  const KernelSource source = Emit(variant, 0, o.joints, options);
  namespace fs = std::filesystem;
  CreateOutputFolder(o.out);
  const std::string base = (fs::path(o.out) / (variant.Key() + (options.instanced ? ".instanced" : ""))).string();
  const std::string kernel_file = base + LanguageOf(variant.lang).extension;
  nlohmann::json sidecar = SidecarJson(source, variant);
  sidecar["source_file"] = fs::path(kernel_file).filename().string();
  const std::string spirv = SpirvBytes(source, variant);
  if (!spirv.empty()) sidecar["spirv_file"] = fs::path(base + ".spv").filename().string();
  WriteFileAtomically(kernel_file, source.text);
  if (!spirv.empty()) WriteFileAtomically(base + ".spv", spirv);
  WriteFileAtomically(base + ".json", sidecar.dump(2) + "\n");
  std::cout << kernel_file << "\n" << (spirv.empty() ? "" : base + ".spv\n") << base << ".json\n";
  return 0;
}

// ------------------------------------------------------------------ --db

// The one --device rule (runtime/device_identity.h MatchesDevice) on the entry's recorded device.
bool EntryMatchesDevice(const WinnersEntry& e, const std::string& pattern) {
  DeviceIdentity d;
  d.backend = e.backend;
  d.platform = e.platform;
  d.vendor = e.vendor;
  d.name = e.device_name;
  d.driver_version = e.driver_version;
  d.type = e.device_type;
  return MatchesDevice(pattern, d);
}

std::string Joined(const std::vector<std::string>& items, const char* separator) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : separator) + item;
  return out;
}

// "'<id>' (opencl, cuda), '<id>' (glsl-compute)": what the database holds, for the no-match error.
std::string DevicesOf(const std::vector<WinnersEntry>& entries) {
  std::vector<std::string> ids;
  std::map<std::string, std::vector<std::string>> langs;
  for (const WinnersEntry& e : entries) {
    std::vector<std::string>& l = langs[e.device_id];
    if (l.empty()) ids.push_back(e.device_id);
    if (std::find(l.begin(), l.end(), Name(e.lang)) == l.end()) l.emplace_back(Name(e.lang));
  }
  std::vector<std::string> items;
  for (const std::string& id : ids) items.push_back("'" + id + "' (" + Joined(langs[id], ", ") + ")");
  return items.empty() ? "the database has no entries" : "the database has: " + Joined(items, ", ");
}

// A winner as the sidecar lists it: the database entry (WinnersEntryToJson),
// with the tuned variant as its key and the vendor and type always present.
nlohmann::json WinnerJson(const WinnersEntry& e) {
  nlohmann::json j = WinnersEntryToJson(e);
  j.erase("variant");
  j["tuned_variant"] = e.variant.Key();
  j["vendor"] = e.vendor;
  j["device_type"] = e.device_type;
  return j;
}

// The database keeps a winner per precision class of a row (RowOf,
// runtime/winners_db.h); the header embeds one kernel per row.
using Row = WinnerRow;

void WarnOverBudget(const WinnersEntry& e, double max_error) {
  std::cerr << "skintune: warning: skipping " << Describe(e) << " " << e.variant.Key() << ": ";
  if (e.source_error.known)
    std::cerr << (MorphHalf(e.variant) ? "its weights and half morph offsets cost " : "its weights cost ")
              << e.source_error.quantisation_rel << " of the bounding-box diagonal, over "
              << "--max-error " << max_error << "\n";
  else
    std::cerr << "its quantisation error is not recorded (a database before 1.3.0: tune again)\n";
}

// Of each row's precision classes, the fastest within the budget (f32 always
// is; an entry whose error is not recorded, from a database before 1.3.0,
// never is: warned and skipped, as Selection::Find does).
std::vector<const WinnersEntry*> FastestWithinBudget(const std::vector<const WinnersEntry*>& entries,
                                                     double max_error) {
  std::map<Row, const WinnersEntry*> best;
  std::vector<Row> order;
  for (const WinnersEntry* e : entries) {
    if (!EntryWithinBudget(*e, max_error, {})) {
      WarnOverBudget(*e, max_error);
      continue;
    }
    const Row row = RowOf(*e);
    const auto it = best.find(row);
    if (it == best.end()) order.push_back(row);
    if (it == best.end() || e->median_ms < it->second->median_ms) best[row] = e;
  }
  std::vector<const WinnersEntry*> out;
  for (const Row& row : order) out.push_back(best[row]);
  return out;
}

// The entries of the devices and languages asked for; throws naming what the
// database holds when none matches.
std::vector<const WinnersEntry*> MatchingEntries(const std::vector<WinnersEntry>& entries, const EmitArgs& o,
                                                 const std::string& asked) {
  std::vector<const WinnersEntry*> matched;
  for (const WinnersEntry& e : entries) {
    const bool lang_ok = o.langs.empty() || std::find(o.langs.begin(), o.langs.end(), Name(e.lang)) != o.langs.end();
    if (lang_ok && EntryMatchesDevice(e, o.device)) matched.push_back(&e);
  }
  if (matched.empty()) throw Error(o.db + ": no winner matches " + asked + " (" + DevicesOf(entries) + ")");
  return matched;
}

// The palette sizes --joints accepts; a batch's kernel (its meshes' palettes together) is held to it too.
constexpr int kMaxPaletteJoints = 65536;

// "300 joints", "3 meshes x 300 joints", "300 joints x 64 instances": what a winner's kernel is emitted for.
std::string EmittedFor(const WinnersEntry& e, int joints) {
  const std::string each = std::to_string(joints) + " joints";
  if (e.shape == SceneKind::kBatch) return std::to_string(e.meshes) + " meshes x " + each;
  if (e.shape == SceneKind::kInstances) return each + " x " + std::to_string(e.instances) + " instances";
  return each;
}

// A winner's kernel as the header embeds it: its padded variant (a bucketed
// winner's padded twin keeps mesh order in one launch) specialised for
// `joints` palette entries; a crowd's winner instanced for its K instances
// (max_instances K), a batch's for its meshes' palettes together (meshes x
// `joints`); a morph winner for `morph_targets` targets (0: the count it was
// tuned on). Warns and returns nothing when the variant cannot take them.
std::optional<EmbeddedKernel> EmbedWinner(const WinnersEntry& e, int joints, int morph_targets) {
  Variant variant = e.variant;
  variant.mixed = MixedCounts::kPadded;
  const long long palette = e.shape == SceneKind::kBatch ? static_cast<long long>(joints) * e.meshes : joints;
  const int instances = e.shape == SceneKind::kInstances ? e.instances : 1;
  const int targets = SkinsMorph(variant) ? (morph_targets > 0 ? morph_targets : e.morph_targets) : 0;
  ProblemShape shape{static_cast<int>(palette), 1, true, instances, true, true};
  shape.morph_targets = targets;
  shape.animated = AnimatesOnDevice(variant);  // its skin kernel; the header's user supplies the palettes
  std::string broken;
  if (palette > kMaxPaletteJoints) {
    broken = "more than " + std::to_string(kMaxPaletteJoints) + " palette entries";
  } else if (const std::vector<Violation> v = CheckVariant(variant, Unlimited(), shape); !v.empty()) {
    broken = v.front().message + " (constraint " + Name(v.front().constraint) + ")";
  }
  if (!broken.empty()) {
    std::cerr << "skintune: warning: skipping " << Describe(e) << ": " << variant.Key() << " cannot be emitted for "
              << EmittedFor(e, joints) << ": " << broken << "\n";
    return std::nullopt;
  }
  EmitOptions options;
  options.instanced = e.shape == SceneKind::kInstances;
  options.max_instances = options.instanced ? instances : 0;
  options.morph_targets = targets;
  return EmbeddedKernel{e, variant, Emit(variant, 0, static_cast<int>(palette), options)};
}

// "<key>", "<key>.x64" (a crowd's instanced kernel), "<key>.batch3": the
// name of a kernel's files without extension; the same name, the same text.
std::string FileBase(const EmbeddedKernel& k) {
  const std::string key = k.variant.Key();
  if (k.entry.shape == SceneKind::kInstances) return key + ".x" + std::to_string(k.entry.instances);
  if (k.entry.shape == SceneKind::kBatch) return key + ".batch" + std::to_string(k.entry.meshes);
  return key;
}

constexpr const char* kBucketedNote =
    "tuned as 'bucketed' (vertices grouped by influence count, one launch per count); emitted as its 'padded' "
    "twin: one launch, outputs in mesh order";

// Per distinct kernel (FileBase, in order of first appearance): its source
// file, its SPIR-V (vulkan) and its sidecar naming every winner it serves and
// the budget they were chosen under: file name in --out, contents.
std::vector<std::pair<std::string, std::string>> KernelFiles(const std::vector<EmbeddedKernel>& kernels,
                                                             double max_error) {
  std::map<std::string, nlohmann::json> sidecars;
  std::vector<const EmbeddedKernel*> distinct;
  for (const EmbeddedKernel& k : kernels) {
    const std::string base = FileBase(k);
    auto [at, added] = sidecars.emplace(base, nlohmann::json());
    if (added) {
      distinct.push_back(&k);
      at->second = SidecarJson(k.source, k.variant);
      at->second["source_file"] = base + LanguageOf(k.variant.lang).extension;
      if (k.variant.lang == Lang::kVulkan) at->second["spirv_file"] = base + ".spv";
      at->second["max_error"] = max_error;  // the budget the winners were chosen under
      at->second["winners"] = nlohmann::json::array();
    }
    at->second["winners"].push_back(WinnerJson(k.entry));
    if (k.entry.variant.mixed == MixedCounts::kBucketed) at->second["note"] = kBucketedNote;
  }
  std::vector<std::pair<std::string, std::string>> files;
  for (const EmbeddedKernel* k : distinct) {
    const std::string base = FileBase(*k);
    files.emplace_back(base + LanguageOf(k->variant.lang).extension, k->source.text);
    if (k->variant.lang == Lang::kVulkan) files.emplace_back(base + ".spv", SpirvBytes(k->source, k->variant));
    files.emplace_back(base + ".json", sidecars[base].dump(2) + "\n");
  }
  return files;
}

int RunEmitDb(const EmitArgs& o) {
  const std::vector<WinnersEntry> entries = WinnersDbFromJson(ReadJsonFile(o.db), o.db);
  const std::string asked =
      "--device '" + o.device + "'" + (o.langs.empty() ? "" : " and --lang " + Joined(o.langs, ", "));
  const std::vector<const WinnersEntry*> candidates = MatchingEntries(entries, o, asked);
  const double max_error = o.max_error_text.empty() ? kDefaultBudget : ParseMaxError(o.max_error_text, "--max-error");
  const std::vector<const WinnersEntry*> matched = FastestWithinBudget(candidates, max_error);
  if (matched.empty())
    throw Error(o.db + ": no winner matching " + asked + " is within the error budget (see the warnings above; "
                       "--max-error sets a larger one)");

  // Everything is generated before anything is written.
  std::vector<EmbeddedKernel> kernels;
  for (const WinnersEntry* e : matched) {
    if (std::optional<EmbeddedKernel> k = EmbedWinner(*e, o.joints, o.morph_targets)) kernels.push_back(std::move(*k));
  }
  if (kernels.empty()) {
    throw Error(o.db + ": none of the " + std::to_string(matched.size()) + " winner(s) matching " + asked +
                " can be emitted for " + std::to_string(o.joints) + " joints (see the warnings above)");
  }
  std::vector<std::pair<std::string, std::string>> files = KernelFiles(kernels, max_error);
  for (const auto& [name, text] : files) {
    if (name == o.header) throw Error("--header '" + o.header + "' is also the name of a kernel file");
  }
  namespace fs = std::filesystem;
  EmbedHeaderOptions options;
  options.name_space = o.name_space;
  options.database = fs::path(o.db).filename().string();
  options.device_pattern = o.device;
  options.langs = o.langs;
  options.max_error = max_error;
  files.emplace_back(o.header, EmbedHeader(kernels, options));

  CreateOutputFolder(o.out);
  for (const auto& [name, text] : files) WriteFileAtomically((fs::path(o.out) / name).string(), text);
  for (const auto& [name, text] : files) std::cout << (fs::path(o.out) / name).string() << "\n";
  return 0;
}

}  // namespace

Command RegisterEmit(CLI::App& app) {
  auto o = std::make_shared<EmitArgs>();
  auto* sub = app.add_subcommand(
      "emit", "write one variant's kernel source and its interface (sidecar JSON), or a winners database's kernels "
              "with a generated C++ header (--db)");
  auto* variant = sub->add_option("--variant", o->variant,
                                  "variant key (see skintune variants --list and docs/VARIANTS.md)");
  auto* db = sub->add_option("--db", o->db,
                             "winners database (skintune tune / skintune db merge): emit the winners of the devices "
                             "matching --device, and one C++17 header holding them (--header)")
                 ->check(NonEmptyPath());
  variant->excludes(db);
  sub->add_option("--out", o->out, "output folder (created if missing)")->required()->check(NonEmptyPath());
  sub->add_option("--joints", o->joints,
                  "palette size the kernel is specialised for (default 77; with --db, a batch winner's kernel holds "
                  "that many per mesh)")
      ->check(CLI::Range(1, kMaxPaletteJoints));
  auto* instances =
      sub->add_option("--instances", o->instances,
                      "emit the instanced kernel for up to K instances per launch (docs/VARIANTS.md \"Instancing\"); "
                      "files are named <key>.instanced.*")
          ->check(CLI::Range(1, 1 << 20));
  instances->excludes(db);
  sub->add_option("--morph-targets", o->morph_targets,
                  "the mesh's morph targets, for a variant that applies them (docs/VARIANTS.md \"Morph targets\"); "
                  "with --db, what the morph winners' kernels are specialised for (default: the count each was "
                  "tuned on)")
      ->check(CLI::Range(1, kMaxMorphTargets));
  auto* device = sub->add_option("--device", o->device,
                                 "with --db: entries of the devices this matches, as every --device: a "
                                 "case-insensitive substring of the id '<backend>:<platform>/<name>/<driver>', "
                                 "vendor, type or platform short name (pocl); \"\" takes every device");
  auto* lang = sub->add_option("--lang", o->langs, "with --db: only these languages (repeatable)")
                   ->check(CLI::IsMember(LanguageNames()));
  auto* header =
      sub->add_option("--header", o->header, "with --db: the header's file name in --out (default skintune_kernels.h)")
          ->check(CLI::Validator(
              [](std::string& name) -> std::string {
                if (name.empty() || name == "." || name == ".." || name.find_first_of("/\\") != std::string::npos)
                  return "'" + name + "' is not a file name";
                return "";
              },
              "NAME"));
  auto* name_space =
      sub->add_option("--namespace", o->name_space, "with --db: the header's C++ namespace (default skintune_kernels)")
          ->check(CLI::Validator(
              [](std::string& name) -> std::string {
                return IsCppNamespaceName(name) ? "" : "'" + name + "' is not a C++ namespace name";
              },
              "NS"));
  auto* max_error = sub->add_option(
      "--max-error", o->max_error_text,
      "with --db: the error budget, relative to the bounding-box diagonal (default 1e-4): per device, language, B and "
      "vertex count, the fastest precision class within it");
  db->needs(device);
  for (CLI::Option* option : {device, lang, header, name_space, max_error}) option->needs(db);
  sub->callback([variant, db] {
    if (variant->count() == 0 && db->count() == 0)
      throw CLI::ValidationError("emit", "give --variant KEY or --db DB.json");
  });
  return {sub, [o, db] { return db->count() > 0 ? RunEmitDb(*o) : RunEmit(*o); }};
}

}  // namespace skintune::internal::tools
