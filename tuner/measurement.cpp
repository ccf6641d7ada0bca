#include "tuner/measurement.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>
#include <limits>
#include <sstream>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "base/input_file.h"
#include "base/memory_limit.h"
#include "runtime/recorded_time.h"

namespace skintune::internal {

std::string UtcTimestamp() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  ::gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

namespace {

// Every enumerator, each once, in order: a status added to the enum and not to the list fails here.
constexpr bool ListsEveryStatus() {
  int i = 0;
  for (MeasureStatus s : kAllMeasureStatuses)
    if (static_cast<int>(s) != i++) return false;
  return static_cast<int>(MeasureStatus::kTooImprecise) + 1 == i;  // kTooImprecise: the last enumerator
}
static_assert(ListsEveryStatus(), "kAllMeasureStatuses must list every MeasureStatus once, in enum order");

std::string SystemError() { return std::strerror(errno); }

// Non-finite numbers (an infinite relative error of a kernel that wrote NaN)
// have no JSON form: they are written as the strings "inf", "-inf", "nan".
nlohmann::json Number(double value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  return value;
}

const nlohmann::json* Field(const nlohmann::json& in, const char* name, bool required, const std::string& where) {
  if (!in.contains(name)) {
    if (required) throw Error(where + ": missing field '" + name + "'");
    return nullptr;
  }
  return &in[name];
}

std::string ReadString(const nlohmann::json& in, const char* name, bool required, const std::string& where) {
  const nlohmann::json* value = Field(in, name, required, where);
  if (!value) return {};
  if (!value->is_string()) throw Error(where + ": '" + name + "' must be a string");
  return value->get<std::string>();
}

double ReadNumber(const nlohmann::json& in, const char* name, const std::string& where) {
  const nlohmann::json* value = Field(in, name, false, where);
  if (!value) return 0.0;
  if (value->is_number()) return value->get<double>();
  if (value->is_string()) {
    const std::string text = value->get<std::string>();
    if (text == "inf") return std::numeric_limits<double>::infinity();
    if (text == "-inf") return -std::numeric_limits<double>::infinity();
    if (text == "nan") return std::numeric_limits<double>::quiet_NaN();
  }
  throw Error(where + ": '" + name + "' must be a number");
}

int ReadInt(const nlohmann::json& in, const char* name, const std::string& where) {
  const nlohmann::json* value = Field(in, name, false, where);
  if (!value) return 0;
  constexpr auto kLeast = std::numeric_limits<int>::min(), kMost = std::numeric_limits<int>::max();
  bool in_range = false;
  if (value->is_number_unsigned()) {
    in_range = value->get<std::uint64_t>() <= std::uint64_t{kMost};
  } else if (value->is_number_integer()) {
    const std::int64_t v = value->get<std::int64_t>();
    in_range = v >= kLeast && v <= kMost;
  }
  if (!in_range)
    throw Error(where + ": '" + name + "' must be an integer from " + std::to_string(kLeast) + " to " +
                std::to_string(kMost) + " (got " + Excerpt(value->dump()) + ")");
  return static_cast<int>(value->get<std::int64_t>());
}

// The first impossible count of a timed record's timing, or "".
std::string ImpossibleCounts(const Timing& t) {
  auto at_least = [](const char* name, int value, int least) {
    return value >= least ? std::string()
                          : "'" + std::string(name) + "' is " + std::to_string(value) + ": must be at least " +
                                std::to_string(least);
  };
  for (const std::string& problem :
       {at_least("repetitions", t.repetitions, 1), at_least("warmup", t.warmup, 0),
        at_least("input_sets", t.input_sets, 1), at_least("version", t.version, 1),
        // Frames per burst (per frame-time run from version 5, when one ran); version 1 timed frames alone.
        at_least("burst_frames", t.burst_frames, t.version == 1 || (t.version >= 5 && t.frame_ms == 0.0) ? 0 : 1),
        NotFiniteNonNegative("footprint_bytes", t.footprint_bytes)})
    if (!problem.empty()) return problem;
  return "";
}

// Timing version 5's interval (when recorded) and frame time: low <= median
// <= high within [min, max], a frame time >= 0, a flush >= 0.
std::string ImpossibleInterval(const Timing& t) {
  if (const std::string bad = NotFiniteNonNegative("frame_ms", t.frame_ms); !bad.empty()) return bad;
  if (const std::string bad = NotFiniteNonNegative("flush_bytes", t.flush_bytes); !bad.empty()) return bad;
  if (const std::string bad = NotFiniteNonNegative("sm_clock_mhz", t.sm_clock_mhz); !bad.empty()) return bad;
  if (t.low_ms == 0.0 && t.high_ms == 0.0) return "";
  const bool ordered = t.min_ms <= t.low_ms && t.low_ms <= t.median_ms && t.median_ms <= t.high_ms && t.high_ms <= t.max_ms;
  if (!ordered || !std::isfinite(t.low_ms) || !std::isfinite(t.high_ms))
    return "an interval ['low_ms' " + std::to_string(t.low_ms) + ", 'high_ms' " + std::to_string(t.high_ms) +
           "] that is not min <= low <= median <= high <= max";
  return "";
}

}  // namespace

const char* Name(MeasureStatus status) {
  switch (status) {
    case MeasureStatus::kOk: return "ok";
    case MeasureStatus::kInvalid: return "invalid";
    case MeasureStatus::kCompileFailed: return "compile_failed";
    case MeasureStatus::kLaunchFailed: return "launch_failed";
    case MeasureStatus::kVerifyFailed: return "verify_failed";
    case MeasureStatus::kTimeout: return "timeout";
    case MeasureStatus::kTooImprecise: return "too_imprecise";
  }
  return "unknown";
}

MeasureStatus MeasureStatusFromName(const std::string& name) {
  std::string choices;
  for (MeasureStatus s : kAllMeasureStatuses) {
    if (name == Name(s)) return s;
    choices += (choices.empty() ? "" : ", ") + std::string(Name(s));
  }
  throw Error("unknown status '" + name + "' (expected one of " + choices + ")");
}

std::string ImpossibleFigures(const Measurement& m) {
  if (!IsTimed(m.status)) return "";
  RecordedTime time;
  time.median_ms = m.timing.median_ms;
  time.min_ms = m.timing.min_ms;
  time.max_ms = m.timing.max_ms;
  time.bytes_per_frame = m.bytes_per_frame;
  time.gbps = m.gbps;
  std::string problem = ImpossibleTime(time);
  if (problem.empty()) problem = ImpossibleCounts(m.timing);
  if (problem.empty() && m.timing.version >= 5) problem = ImpossibleInterval(m.timing);
  if (problem.empty()) problem = NotFiniteNonNegative("max_relative_error", m.max_relative_error);
  if (problem.empty() && m.max_relative_error > kMaxTolerance)
    problem = "'max_relative_error' is " + std::to_string(m.max_relative_error) +
              ": over the largest verification tolerance (" + std::to_string(kMaxTolerance) + "), it cannot have passed";
  if (problem.empty()) problem = NotFiniteNonNegative("copy_ms", m.timing.copy_ms);
  if (problem.empty()) problem = NotFiniteNonNegative("x_copy", m.x_copy);
  if (problem.empty() && m.timing.copy_ms > 0.0 &&
      std::abs(m.x_copy - m.timing.median_ms / m.timing.copy_ms) > 1e-6 * (m.x_copy + 1.0))
    problem = "'x_copy' " + std::to_string(m.x_copy) + " is not median_ms / copy_ms (" +
              std::to_string(m.timing.median_ms / m.timing.copy_ms) + ")";
  if (problem.empty() && m.timing.copy_ms == 0.0 && m.x_copy != 0.0)
    problem = "'x_copy' " + std::to_string(m.x_copy) + " without a copy time";
  if (problem.empty()) problem = ImpossibleSourceError(m.source_error);
  return problem.empty() ? "" : "status " + std::string(Name(m.status)) + " with " + problem;
}

void ApplyBudget(Measurement& m, double max_error) {
  if (!IsTimed(m.status) || !m.source_error.known) return;
  if (WithinBudget(m.source_error, max_error)) {
    m.status = MeasureStatus::kOk;
    m.detail.clear();
    return;
  }
  std::ostringstream detail;
  detail.precision(2);
  if (KernelAddsOnlyRounding(m.source_error)) {
    const std::string what = std::string(Name(m.variant.weight)) + " weights" +
                             (MorphHalf(m.variant) ? " and half morph offsets" : "") +
                             (BakeRateOf(m.variant.animation) > 0.0 ? std::string(" and clips ") + Name(m.variant.animation) : "");
    detail << std::scientific << what << " cost " << m.source_error.quantisation_rel
           << " of the bounding-box diagonal, over the budget max_error " << max_error;
  } else {
    detail << std::scientific << "the kernel's output is off the source by " << m.source_error.position_rel
           << " of the bounding-box diagonal, more than its weights cost (" << m.source_error.quantisation_rel
           << ") and " << kKernelRoundingAllowance << " for its rounding";
  }
  m.status = MeasureStatus::kTooImprecise;
  m.detail = detail.str();
}

std::string MeasuredAgainOnResume(const Measurement& m, double tolerance) {
  if (IsTimed(m.status) && !m.source_error.known) return "recorded before the error against the source was measured";
  if (IsTimed(m.status) && m.max_relative_error > tolerance)
    return "its relative error " + std::to_string(m.max_relative_error) + " is over this run's tolerance";
  if (m.detail.rfind(kInterruptedDetail, 0) == 0) return "its measurement was interrupted";
  return "";
}

std::string Measurement::CacheKey() const {
  return device_id + "|" + generator_version + "|timing " + std::to_string(timing.version) + "|" + dataset + "|" +
         variant.Key();
}

void to_json(nlohmann::json& out, const Measurement& m) {
  out = nlohmann::json::object();
  out["device_id"] = m.device_id;
  out["dataset"] = m.dataset;
  out["variant"] = m.variant;
  out["status"] = Name(m.status);
  out["detail"] = m.detail;
  out["timing"] = {{"median_ms", Number(m.timing.median_ms)},
                   {"low_ms", Number(m.timing.low_ms)},
                   {"high_ms", Number(m.timing.high_ms)},
                   {"min_ms", Number(m.timing.min_ms)},
                   {"max_ms", Number(m.timing.max_ms)},
                   {"repetitions", m.timing.repetitions},
                   {"tight", m.timing.tight},
                   {"clock", m.timing.clock},
                   {"flush_bytes", Number(m.timing.flush_bytes)},
                   {"sm_clock_mhz", Number(m.timing.sm_clock_mhz)},
                   {"schedule", m.timing.schedule},
                   {"context", m.timing.context},
                   {"launch_start_ms", Number(m.timing.launch_start_ms)},
                   {"warmup", m.timing.warmup},
                   {"burst_frames", m.timing.burst_frames},
                   {"input_sets", m.timing.input_sets},
                   {"footprint_bytes", Number(m.timing.footprint_bytes)},
                   {"copy_ms", Number(m.timing.copy_ms)},
                   {"frame_ms", Number(m.timing.frame_ms)},
                   {"version", m.timing.version}};
  if (m.timing.palette_kernel_ms > 0.0) out["timing"]["palette_kernel_ms"] = Number(m.timing.palette_kernel_ms);
  out["bytes_per_frame"] = Number(m.bytes_per_frame);
  if (m.least_bytes_per_frame > 0.0) out["least_bytes_per_frame"] = Number(m.least_bytes_per_frame);
  out["gbps"] = Number(m.gbps);
  out["x_copy"] = Number(m.x_copy);
  out["max_relative_error"] = Number(m.max_relative_error);
  if (m.source_error.known) out["source_error"] = SourceErrorJson(m.source_error);
  if (!m.baked_clips.empty()) {
    nlohmann::json& clips = out["baked_clips"] = nlohmann::json::array();
    for (const BakedClipRecord& c : m.baked_clips)
      clips.push_back({{"name", c.name}, {"frames", Number(c.frames)}, {"bytes", Number(c.bytes)}, {"max_error", Number(c.max_error)}});
  }
  out["generator_version"] = m.generator_version;
  out["timestamp"] = m.timestamp;
}

namespace {

// A measurement's 'timing' object into `m.timing`, `where` naming the measurement in errors.
void ReadTiming(const nlohmann::json* timing, const std::string& where, Measurement& m) {
  const std::string t = where + ": 'timing'";
  if (!timing->is_object()) throw Error(t + ": expected an object");
  m.timing.median_ms = ReadNumber(*timing, "median_ms", t);
  m.timing.min_ms = ReadNumber(*timing, "min_ms", t);
  m.timing.max_ms = ReadNumber(*timing, "max_ms", t);
  m.timing.warmup = ReadInt(*timing, "warmup", t);
  m.timing.repetitions = ReadInt(*timing, "repetitions", t);
  m.timing.input_sets = ReadInt(*timing, "input_sets", t);
  m.timing.burst_frames = ReadInt(*timing, "burst_frames", t);
  m.timing.footprint_bytes = ReadNumber(*timing, "footprint_bytes", t);
  m.timing.copy_ms = ReadNumber(*timing, "copy_ms", t);
  // Timing version 5's figures; absent in older records, which no run reuses (their cache key differs).
  if (timing->contains("low_ms")) m.timing.low_ms = ReadNumber(*timing, "low_ms", t);
  if (timing->contains("high_ms")) m.timing.high_ms = ReadNumber(*timing, "high_ms", t);
  if (timing->contains("frame_ms")) m.timing.frame_ms = ReadNumber(*timing, "frame_ms", t);
  if (timing->contains("palette_kernel_ms")) m.timing.palette_kernel_ms = ReadNumber(*timing, "palette_kernel_ms", t);
  if (timing->contains("flush_bytes")) m.timing.flush_bytes = ReadNumber(*timing, "flush_bytes", t);
  // Timing version 7's clock; absent in older records.
  if (timing->contains("sm_clock_mhz")) m.timing.sm_clock_mhz = ReadNumber(*timing, "sm_clock_mhz", t);
  if (timing->contains("schedule")) m.timing.schedule = ReadString(*timing, "schedule", false, t);
  if (timing->contains("context")) m.timing.context = ReadString(*timing, "context", false, t);
  if (timing->contains("launch_start_ms")) m.timing.launch_start_ms = ReadNumber(*timing, "launch_start_ms", t);
  if (timing->contains("clock")) m.timing.clock = ReadString(*timing, "clock", false, t);
  if (const nlohmann::json* tight = Field(*timing, "tight", false, t)) {
    if (!tight->is_boolean()) throw Error(t + ": 'tight' must be true or false");
    m.timing.tight = tight->get<bool>();
  }
  // Lines written before timing versions were recorded are version 1.
  m.timing.version = timing->contains("version") ? ReadInt(*timing, "version", t) : 1;
}

}  // namespace

void from_json(const nlohmann::json& in, Measurement& m) {
  const std::string where = "measurement";
  if (!in.is_object()) throw Error(where + ": expected an object");
  m = Measurement{};
  m.device_id = ReadString(in, "device_id", true, where);
  m.dataset = ReadString(in, "dataset", true, where);
  try {
    m.variant = Field(in, "variant", true, where)->get<Variant>();
  } catch (const Error& e) {
    throw Error(where + ": 'variant': " + e.what());
  }
  const std::string status = ReadString(in, "status", true, where);
  try {
    m.status = MeasureStatusFromName(status);
  } catch (const Error& e) {
    throw Error(where + ": 'status': " + e.what());
  }
  m.detail = ReadString(in, "detail", false, where);
  const nlohmann::json* timing = Field(in, "timing", false, where);
  if (!timing && IsTimed(m.status)) throw Error(where + ": status " + status + " without 'timing'");
  if (timing) ReadTiming(timing, where, m);
  m.bytes_per_frame = ReadNumber(in, "bytes_per_frame", where);
  if (in.contains("least_bytes_per_frame")) m.least_bytes_per_frame = ReadNumber(in, "least_bytes_per_frame", where);
  m.gbps = ReadNumber(in, "gbps", where);
  m.x_copy = ReadNumber(in, "x_copy", where);
  m.max_relative_error = ReadNumber(in, "max_relative_error", where);
  // Absent in records written before skintune measured it (older caches and reports): unknown then.
  if (const nlohmann::json* e = Field(in, "source_error", false, where)) {
    try {
      m.source_error = SourceErrorFromJson(*e);
    } catch (const Error& error) {
      throw Error(where + ": 'source_error': " + error.what());
    }
  }
  if (m.status == MeasureStatus::kTooImprecise && !m.source_error.known)
    throw Error(where + ": status too_imprecise without 'source_error'");
  if (const nlohmann::json* clips = Field(in, "baked_clips", false, where)) {
    if (!clips->is_array()) throw Error(where + ": 'baked_clips' must be a list");
    for (std::size_t i = 0; i < clips->size(); ++i) {
      const std::string c = where + ": 'baked_clips'[" + std::to_string(i) + "]";
      const nlohmann::json& clip = (*clips)[i];
      if (!clip.is_object()) throw Error(c + ": expected an object");
      m.baked_clips.push_back({ReadString(clip, "name", true, c), ReadNumber(clip, "frames", c), ReadNumber(clip, "bytes", c),
                               ReadNumber(clip, "max_error", c)});
    }
  }
  m.generator_version = ReadString(in, "generator_version", true, where);
  m.timestamp = ReadString(in, "timestamp", false, where);
  if (const std::string problem = ImpossibleFigures(m); !problem.empty())
    throw ImpossibleMeasurement(where + ": impossible figures: " + problem);
}

// ------------------------------------------------------------------ MeasurementCache

MeasurementCache::MeasurementCache(const std::string& path) : path_(path) {
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd_ < 0) throw Error(path + ": cannot open the measurement cache for appending (" + SystemError() + ")");
  try {
    Load(ReadLocked());
  } catch (...) {
    ::close(fd_);
    fd_ = -1;
    throw;
  }
}

std::string MeasurementCache::ReadLocked() {
  struct stat info {};
  if (::fstat(fd_, &info) != 0) throw Error(path_ + ": cannot stat (" + SystemError() + ")");
  if (!S_ISREG(info.st_mode)) throw Error(path_ + ": not a regular file");
  if (static_cast<std::uint64_t>(info.st_size) > kMeasurementCacheInput.bytes)
    throw Error(path_ + ": is " + FormatBytes(static_cast<std::uint64_t>(info.st_size)) + ", more than the " +
                FormatBytes(kMeasurementCacheInput.bytes) + " " + kMeasurementCacheInput.what + " may have");
  // One writer at a time: a second `skintune tune` on the same cache would
  // measure the same variants twice. The lock goes with the process.
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    if (errno == EWOULDBLOCK) throw Error(path_ + ": in use by another skintune tune (locked)");
    throw Error(path_ + ": cannot lock (" + SystemError() + ")");
  }
  std::string data;
  data.resize(static_cast<std::size_t>(info.st_size));
  std::size_t got = 0;
  while (got < data.size()) {
    const ssize_t n = ::pread(fd_, data.data() + got, data.size() - got, static_cast<off_t>(got));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw Error(path_ + ": cannot read (" + SystemError() + ")");
    if (n == 0) break;
    got += static_cast<std::size_t>(n);
  }
  data.resize(got);
  return data;
}

void MeasurementCache::Load(const std::string& data) {
  std::size_t start = 0;
  std::size_t line_number = 0;
  while (start < data.size()) {
    const std::size_t end = data.find('\n', start);
    ++line_number;
    if (end == std::string::npos) {
      // A torn last line: the run was killed while writing it. Cut it off so
      // the next append starts on a line of its own.
      if (::ftruncate(fd_, static_cast<off_t>(start)) != 0) {
        throw Error(path_ + ": cannot cut off the incomplete last line " + std::to_string(line_number) + " (" +
                    SystemError() + ")");
      }
      break;
    }
    const std::string line = data.substr(start, end - start);
    start = end + 1;
    if (line.find_first_not_of(" \t\r") != std::string::npos) LoadLine(line, line_number);
  }
}

void MeasurementCache::LoadLine(const std::string& line, std::size_t line_number) {
  const std::string at = path_ + ":" + std::to_string(line_number) + ": ";
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(line);
  } catch (const nlohmann::json::exception& e) {
    throw Error(at + "malformed measurement (" + e.what() + ")");
  }
  std::optional<std::pair<std::string, RaceRecord>> race;
  try {
    race = CachedRaceOf(j);
  } catch (const Error& e) {
    throw Error(at + e.what());
  }
  if (race) {
    races_[race->first] = std::move(race->second);
    return;
  }
  Measurement m;
  try {
    m = j.get<Measurement>();
  } catch (const nlohmann::json::exception& e) {
    throw Error(at + "malformed measurement (" + e.what() + ")");
  } catch (const ImpossibleMeasurement& e) {
    throw Error(at + e.what() + " (never used; delete the line to measure the variant again)");
  } catch (const Error& e) {
    throw Error(at + "malformed " + e.what());
  }
  Keep(std::move(m));
}

void MeasurementCache::Keep(Measurement m) {
  const std::string key = m.CacheKey();
  const auto found = index_.find(key);
  if (found != index_.end()) {
    measurements_[found->second] = std::move(m);  // the later record wins
  } else {
    index_.emplace(key, measurements_.size());
    measurements_.push_back(std::move(m));
  }
}

MeasurementCache::~MeasurementCache() {
  if (fd_ >= 0) ::close(fd_);
}

const Measurement* MeasurementCache::Find(const std::string& cache_key) const {
  const auto found = index_.find(cache_key);
  return found == index_.end() ? nullptr : &measurements_[found->second];
}

void MeasurementCache::AppendLine(const std::string& line, const char* what) {
  // One write() on an O_APPEND descriptor: the record lands whole at the end
  // of the file or (killed mid-way, disk full) as a torn line the next open cuts.
  ssize_t n;
  do {
    n = ::write(fd_, line.data(), line.size());
  } while (n < 0 && errno == EINTR);
  if (n < 0) throw Error(path_ + ": cannot append " + what + " (" + SystemError() + ")");
  if (static_cast<std::size_t>(n) != line.size()) {
    throw Error(path_ + ": short write appending " + what + " (" + std::to_string(n) + " of " +
                std::to_string(line.size()) + " bytes; disk full?)");
  }
  if (::fsync(fd_) != 0) throw Error(path_ + ": fsync failed (" + SystemError() + ")");
}

const RaceRecord* MeasurementCache::FindRace(const std::string& race_key) const {
  const auto found = races_.find(race_key);
  return found == races_.end() ? nullptr : &found->second;
}

void MeasurementCache::AppendRace(const std::string& race_key, const RaceRecord& race) {
  AppendLine(CachedRaceLine(race_key, race).dump() + "\n", "a race");
  races_[race_key] = race;
}

void MeasurementCache::Append(const Measurement& m) {
  AppendLine(nlohmann::json(m).dump() + "\n", "a measurement");
  Keep(m);
}

}  // namespace skintune::internal
