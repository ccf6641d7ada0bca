#include "tuner/host_lock.h"
#include "tuner/worker.h"

#include <fcntl.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif
#include <poll.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <climits>
#include <cmath>
#include <csignal>
#include <fstream>
#include <iterator>
#include <cstring>
#include <ctime>
#include <iostream>
#include <sstream>
#include <thread>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "generator/emit.h"
#include "tuner/fault_injection.h"
#include "tuner/measure_job.h"
#include "tuner/runner_device.h"
#include "tuner/tune.h"

namespace skintune::internal {

namespace {

// CompileFor's names in the protocol's "for", declared once for both ends.
constexpr std::pair<CompileFor, const char*> kCompileForNames[] = {{CompileFor::kThisProcess, "this process"},
                                                                   {CompileFor::kTheCache, "the cache"}};

const char* NameOf(CompileFor compile_for) {
  for (const auto& [value, name] : kCompileForNames)
    if (value == compile_for) return name;
  return kCompileForNames[0].second;
}

// The CompileFor a request's "for" names; absent, this process.
CompileFor CompileForOf(const nlohmann::json& request) {
  const std::string named = request.value("for", std::string(NameOf(CompileFor::kThisProcess)));
  std::string known;
  for (const auto& [value, name] : kCompileForNames) {
    if (named == name) return value;
    known += std::string(known.empty() ? "" : ", ") + name;
  }
  throw Error("compile_ahead: \"for\" is '" + named + "' (" + known + ")");
}

constexpr std::size_t kStderrTailBytes = 8192;

std::vector<std::string> CopyEnvironment() {
  std::vector<std::string> copy;
  for (char** entry = environ; entry != nullptr && *entry != nullptr; ++entry) copy.emplace_back(*entry);
  return copy;
}

// Taken during static initialisation, before main() and before any driver is
// loaded: some OpenCL ICD loaders tokenise OCL_ICD_FILENAMES in place
// (strtok on getenv's pointer), so after the parent's own clGetPlatformIDs the
// live environment may name only the first ICD, and a worker started with it
// would not see the others (seen on the H100 machine: "libpocl.so.2:
// libnvidia-opencl.so.1" became "libpocl.so.2", and the NVIDIA platform
// vanished from the worker).
const std::vector<std::string> kStartupEnvironment = CopyEnvironment();

std::string Seconds(double s) {
  std::ostringstream out;
  out << s;
  return out.str();
}

TimingOptions TimingFromJson(const nlohmann::json& in) { return TimingOptionsFromJson(in, "timing"); }

void CloseFd(int& fd) {
  if (fd >= 0) ::close(fd);
  fd = -1;
}

std::string StatusText(int status) {
  if (WIFSIGNALED(status)) {
    const int sig = WTERMSIG(status);
    const char* name = ::strsignal(sig);
    return "signal " + std::to_string(sig) + (name ? " (" + std::string(name) + ")" : std::string());
  }
  if (WIFEXITED(status)) return "exit code " + std::to_string(WEXITSTATUS(status));
  return "status " + std::to_string(status);
}

}  // namespace

const std::vector<std::string>& StartupEnvironment() { return kStartupEnvironment; }

// ------------------------------------------------------------------ parent side

std::vector<std::string> WorkerArguments(const DeviceIdentity& device, const std::string& host_lock,
                                         const std::string& chip_lock) {
  std::vector<std::string> args = {"tune-worker", "--device-index", std::to_string(device.index), "--device-id",
                                   device.Id(), "--discover-only", device.backend};
  if (!host_lock.empty()) args.insert(args.end(), {"--host-lock", host_lock});
  if (!chip_lock.empty()) args.insert(args.end(), {"--chip-lock", chip_lock});
  if (device.last_level_cache_bytes)
    args.insert(args.end(), {"--cache-bytes", std::to_string(device.last_level_cache_bytes), "--cache-source",
                             device.last_level_cache_source});
  return args;
}

IsolatedDevice::IsolatedDevice(std::string executable, DeviceIdentity identity, double variant_timeout_s)
    : executable_(std::move(executable)), identity_(std::move(identity)), variant_timeout_s_(variant_timeout_s) {}

IsolatedDevice::~IsolatedDevice() { Stop(); }

void IsolatedDevice::Start() {
  Spawn();
  AwaitGreeting();
}

void IsolatedDevice::Spawn() {
  // A child that died between two requests must not kill us when we write to it.
  std::signal(SIGPIPE, SIG_IGN);
  int in[2], out[2], err[2];
  if (::pipe2(in, O_CLOEXEC) != 0) throw WorkerError("cannot create a pipe (" + std::string(std::strerror(errno)) + ")");
  if (::pipe2(out, O_CLOEXEC) != 0) {
    ::close(in[0]), ::close(in[1]);
    throw WorkerError("cannot create a pipe (" + std::string(std::strerror(errno)) + ")");
  }
  if (::pipe2(err, O_CLOEXEC) != 0) {
    ::close(in[0]), ::close(in[1]), ::close(out[0]), ::close(out[1]);
    throw WorkerError("cannot create a pipe (" + std::string(std::strerror(errno)) + ")");
  }
  // Everything the child needs is prepared before fork: after it, only
  // async-signal-safe calls until exec (the parent may have driver threads).
  // The worker finds its device by identity: the position is only a hint,
  // since a child may enumerate a platform differently from its parent.
  const std::vector<std::string> args = WorkerArguments(identity_, host_lock_, chip_lock_);
  std::vector<char*> argv = {const_cast<char*>(executable_.c_str())};
  for (const std::string& arg : args) argv.push_back(const_cast<char*>(arg.c_str()));
  argv.push_back(nullptr);
  std::vector<char*> envp;
  for (const std::string& entry : kStartupEnvironment) envp.push_back(const_cast<char*>(entry.c_str()));
  envp.push_back(nullptr);
  static const char kExecFailed[] = "skintune: cannot execute the tune worker\n";
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid < 0) {
    for (int fd : {in[0], in[1], out[0], out[1], err[0], err[1]}) ::close(fd);
    throw WorkerError("cannot start a worker process (" + std::string(std::strerror(errno)) + ")");
  }
  if (pid == 0) {
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(1);
    ::signal(SIGPIPE, SIG_DFL);
    ::dup2(in[0], 0);
    ::dup2(out[1], 1);
    ::dup2(err[1], 2);
    ::execve(argv[0], argv.data(), envp.data());
    [[maybe_unused]] const ssize_t n = ::write(2, kExecFailed, sizeof kExecFailed - 1);
    ::_exit(127);
  }
  ::close(in[0]);
  ::close(out[1]);
  ::close(err[1]);
  pid_ = pid;
  to_child_ = in[1];
  from_child_ = out[0];
  child_stderr_ = err[0];
  ::fcntl(from_child_, F_SETFL, ::fcntl(from_child_, F_GETFL) | O_NONBLOCK);
  ::fcntl(child_stderr_, F_SETFL, ::fcntl(child_stderr_, F_GETFL) | O_NONBLOCK);
  out_buffer_.clear();
  err_tail_.clear();
  ++starts_;
  killed_here_ = false;
}

void IsolatedDevice::AwaitGreeting() {
  // Discovery in the child (its device's API alone: WorkerArguments) comes before its greeting.
  const double start_timeout_s = std::max(variant_timeout_s_, 60.0);
  std::string line;
  switch (ReadLine(start_timeout_s, line)) {
    case ReadResult::kTimeout:
      Kill();
      throw WorkerError("worker process did not start within " + Seconds(start_timeout_s) + " s");
    case ReadResult::kEnd:
      throw WorkerError("worker process failed to start: " + DeathDetail());
    case ReadResult::kLine: break;
  }
  nlohmann::json hello;
  try {
    hello = nlohmann::json::parse(line);
  } catch (const nlohmann::json::exception&) {
    Kill();
    throw WorkerError("worker process sent '" + line.substr(0, 200) + "' instead of its greeting");
  }
  if (hello.is_object() && hello.contains("error") && hello["error"].is_string()) {
    Stop();
    throw WorkerError(hello["error"].get<std::string>());
  }
  if (!hello.is_object() || !hello.contains("device_id") || !hello["device_id"].is_string()) {
    Kill();
    throw WorkerError("worker process sent '" + line.substr(0, 200) + "' instead of its greeting");
  }
  if (hello["device_id"].get<std::string>() != identity_.Id()) {
    Stop();
    throw WorkerError("worker process found '" + hello["device_id"].get<std::string>() + "' as device " +
                      std::to_string(identity_.index) + ", not '" + identity_.Id() +
                      "' (the devices changed since discovery)");
  }
}

std::string IsolatedDevice::Reap(bool block) {
  if (pid_ < 0) return "not running";
  int status = 0;
  pid_t r = 0;
  if (!block) {
    // The child closed its output: it is exiting. Give it a moment, then make sure.
    for (int i = 0; i < 500; ++i) {
      do {
        r = ::waitpid(pid_, &status, WNOHANG);
      } while (r < 0 && errno == EINTR);
      if (r != 0) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    if (r == 0) {
      ::kill(pid_, SIGKILL);
      killed_here_ = true;
    }
  }
  if (block || r == 0) {
    do {
      r = ::waitpid(pid_, &status, 0);
    } while (r < 0 && errno == EINTR);
  }
  pid_ = -1;
  reaped_status_ = r < 0 ? 0 : status;
  return r < 0 ? "unknown status (" + std::string(std::strerror(errno)) + ")" : StatusText(status);
}

bool IsolatedDevice::KilledFromOutside() const {
  if (killed_here_ || !WIFSIGNALED(reaped_status_)) return false;
  const int sig = WTERMSIG(reaped_status_);
  return sig == SIGKILL || sig == SIGTERM || sig == SIGINT || sig == SIGHUP || sig == SIGQUIT;
}

bool IsolatedDevice::Stopped() const {
  if (pid_ < 0) return false;
  std::ifstream stat("/proc/" + std::to_string(pid_) + "/stat");
  std::string text((std::istreambuf_iterator<char>(stat)), std::istreambuf_iterator<char>());
  const std::size_t name_end = text.rfind(')');  // "pid (comm) S ...": the name may hold spaces
  return name_end != std::string::npos && name_end + 2 < text.size() &&
         (text[name_end + 2] == 'T' || text[name_end + 2] == 't');
}

void IsolatedDevice::Kill() {
  if (pid_ >= 0) {
    killed_here_ = true;
    ::kill(pid_, SIGKILL);
    Reap(true);
  }
  CloseFd(to_child_);
  CloseFd(from_child_);
  CloseFd(child_stderr_);
}

void IsolatedDevice::EndInput() { CloseFd(to_child_); }

void IsolatedDevice::Stop() {
  if (pid_ < 0) return;
  CloseFd(to_child_);  // end of input: the worker returns
  Reap(false);
  CloseFd(from_child_);
  CloseFd(child_stderr_);
}

std::string IsolatedDevice::DeathDetail() {
  CloseFd(to_child_);
  const std::string how = Reap(false);
  // Whatever the child wrote on stderr before it died is in the pipe now.
  char chunk[4096];
  while (child_stderr_ >= 0) {
    const ssize_t n = ::read(child_stderr_, chunk, sizeof chunk);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    err_tail_.append(chunk, static_cast<std::size_t>(n));
    if (err_tail_.size() > kStderrTailBytes) err_tail_.erase(0, err_tail_.size() - kStderrTailBytes);
  }
  CloseFd(from_child_);
  CloseFd(child_stderr_);
  const std::string tail = StderrTail();
  return how + (tail.empty() ? "" : "; its last stderr line: " + tail);
}

std::string IsolatedDevice::StderrTail() const {
  std::size_t end = err_tail_.find_last_not_of(" \t\r\n");
  if (end == std::string::npos) return {};
  const std::size_t begin = err_tail_.rfind('\n', end);
  std::string line = err_tail_.substr(begin == std::string::npos ? 0 : begin + 1, end + 1 - (begin == std::string::npos ? 0 : begin + 1));
  if (line.size() > 300) line = line.substr(0, 300) + "...";
  return line;
}

bool IsolatedDevice::Send(const std::string& line) {
  const std::string text = line + "\n";
  std::size_t sent = 0;
  while (sent < text.size()) {
    const ssize_t n = ::write(to_child_, text.data() + sent, text.size() - sent);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;  // EPIPE: the child is gone
    sent += static_cast<std::size_t>(n);
  }
  return true;
}

IsolatedDevice::ReadResult IsolatedDevice::ReadLine(double timeout_s, std::string& line) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point deadline =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(timeout_s));
  char chunk[65536];
  for (;;) {
    const std::size_t newline = out_buffer_.find('\n');
    if (newline != std::string::npos) {
      line = out_buffer_.substr(0, newline);
      out_buffer_.erase(0, newline + 1);
      return ReadResult::kLine;
    }
    const Clock::time_point now = Clock::now();
    if (now >= deadline) return ReadResult::kTimeout;
    const double left_ms = std::chrono::duration<double, std::milli>(deadline - now).count();
    const int wait_ms = static_cast<int>(std::min(std::ceil(left_ms), static_cast<double>(INT_MAX)));
    pollfd fds[2] = {{from_child_, POLLIN, 0}, {child_stderr_, POLLIN, 0}};
    const int r = ::poll(fds, child_stderr_ >= 0 ? 2 : 1, wait_ms);
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) throw Error(std::string("poll on the worker's pipes failed (") + std::strerror(errno) + ")");
    if (child_stderr_ >= 0 && (fds[1].revents & (POLLIN | POLLHUP | POLLERR))) {
      const ssize_t n = ::read(child_stderr_, chunk, sizeof chunk);
      if (n == 0) {
        CloseFd(child_stderr_);
      } else if (n > 0) {
        err_tail_.append(chunk, static_cast<std::size_t>(n));
        if (err_tail_.size() > kStderrTailBytes) err_tail_.erase(0, err_tail_.size() - kStderrTailBytes);
      }
    }
    if (fds[0].revents & (POLLIN | POLLHUP | POLLERR)) {
      const ssize_t n = ::read(from_child_, chunk, sizeof chunk);
      if (n == 0) return ReadResult::kEnd;
      if (n < 0 && (errno == EAGAIN || errno == EINTR)) continue;
      if (n < 0) return ReadResult::kEnd;
      out_buffer_.append(chunk, static_cast<std::size_t>(n));
    }
  }
}

// A worker that lost its device (DeviceLostIn: a GL context the driver reset,
// whether this kernel hung or another process's work did) has answered and
// exited: the variant is measured once more in a fresh one, so a reset caused
// elsewhere costs no variant, and the variants after it never run on a dead
// context.
Measurement IsolatedDevice::Measure(const Variant& variant, const TuningDataset& dataset,
                                     const TimingOptions& options) {
  bool lost = false;
  Measurement m = MeasureOnce(variant, dataset, options, &lost);
  if (!lost) return m;
  const std::string first = m.detail;
  Stop();
  bool lost_again = false;
  m = MeasureOnce(variant, dataset, options, &lost_again);
  if (lost_again) {
    Stop();
    m.detail += " (the device was lost in two fresh worker processes, one after the other)";
  } else {
    m.detail += std::string(m.detail.empty() ? "" : "; ") + "measured in a fresh worker process: the first lost the device (" +
                first + ")";
  }
  return m;
}

Measurement IsolatedDevice::MeasureOnce(const Variant& variant, const TuningDataset& dataset,
                                         const TimingOptions& options, bool* lost) {
  Measurement result;
  result.device_id = identity_.Id();
  result.dataset = dataset.key;
  result.variant = variant;
  result.generator_version = kGeneratorVersion;
  result.timestamp = UtcTimestamp();

  const std::string request =
      nlohmann::json{{"variant", variant}, {"dataset", dataset.key}, {"timing", ToJson(options)}}.dump();
  if (pid_ < 0) Start();
  // A death or a timeout the variant did not cause is recorded as
  // interrupted, so that a resumed run measures it again.
  auto died = [&] {
    const std::string how = DeathDetail();
    result.status = MeasureStatus::kLaunchFailed;
    result.detail = (KilledFromOutside() ? kInterruptedDetail : "") + std::string("worker process died: ") + how;
    return result;
  };
  if (!Send(request)) {
    // The previous child died after its last answer: a fresh one takes the request.
    DeathDetail();
    Start();
    if (!Send(request)) return died();
  }
  std::string line;
  switch (ReadLine(variant_timeout_s_, line)) {
    case ReadResult::kTimeout: {
      const bool stopped = Stopped();
      Kill();
      result.status = MeasureStatus::kTimeout;
      result.detail = (stopped ? std::string(kInterruptedDetail) + "the worker process was stopped; " : "") +
                      "no result within " + Seconds(variant_timeout_s_) + " s";
      return result;
    }
    case ReadResult::kEnd: return died();
    case ReadResult::kLine: break;
  }
  nlohmann::json answer;
  try {
    answer = nlohmann::json::parse(line);
  } catch (const nlohmann::json::exception&) {
    Kill();
    throw WorkerError("worker process sent a malformed line: '" + line.substr(0, 200) + "'");
  }
  if (answer.is_object() && answer.contains("error")) {
    Kill();
    throw WorkerError(answer["error"].is_string() ? answer["error"].get<std::string>() : answer["error"].dump());
  }
  if (answer.is_object() && answer.contains("device_lost")) {
    *lost = answer["device_lost"] == true;
    answer.erase("device_lost");
  }
  Measurement m;
  try {
    m = answer.get<Measurement>();
  } catch (const ImpossibleMeasurement& e) {
    // A timer or driver that reports an impossible time (0 ms, NaN, min above
    // max...) fails this variant, never the run: it is recorded, never ranked.
    result.status = MeasureStatus::kLaunchFailed;
    result.detail = std::string("the device reported ") + e.what();
    return result;
  } catch (const Error& e) {
    Kill();
    throw WorkerError(std::string("worker process sent a malformed measurement: ") + e.what());
  }
  // What identifies the measurement is the parent's, so the cache key is
  // exactly the one looked up.
  m.device_id = result.device_id;
  m.dataset = result.dataset;
  m.variant = variant;
  m.generator_version = result.generator_version;
  if (m.timestamp.empty()) m.timestamp = result.timestamp;
  return m;
}

std::size_t IsolatedDevice::CompileAhead(const std::vector<Variant>& variants, const TuningDataset& dataset,
                                         CompileFor compile_for) {
  if (variants.empty()) return 0;
  const std::string request =
      nlohmann::json{{"compile_ahead", variants}, {"dataset", dataset.key}, {"for", NameOf(compile_for)}}.dump();
  if (pid_ < 0) Start();
  if (!Send(request)) {
    DeathDetail();
    return 0;  // the next request starts a fresh child
  }
  std::string line;
  switch (ReadLine(variant_timeout_s_ * static_cast<double>(variants.size()), line)) {
    case ReadResult::kTimeout: Kill(); return 0;
    case ReadResult::kEnd: DeathDetail(); return 0;
    case ReadResult::kLine: break;
  }
  try {
    const nlohmann::json answer = nlohmann::json::parse(line);
    if (answer.is_object() && answer.contains("compiled") && answer["compiled"].is_number_unsigned())
      return answer["compiled"].get<std::size_t>();
  } catch (const nlohmann::json::exception&) {
  }
  Kill();  // an answer out of protocol: a fresh child serves the next request
  return 0;
}

bool IsolatedDevice::Exchange(const std::string& request, double timeout_s, std::string& line, std::string& why) {
  if (pid_ < 0) Start();
  if (!Send(request)) {
    DeathDetail();
    Start();
    if (!Send(request)) {
      why = "worker process died: " + DeathDetail();
      return false;
    }
  }
  switch (ReadLine(timeout_s, line)) {
    case ReadResult::kTimeout:
      Kill();
      why = "no result within " + Seconds(timeout_s) + " s";
      return false;
    case ReadResult::kEnd:
      why = "worker process died: " + DeathDetail();
      return false;
    case ReadResult::kLine: break;
  }
  return true;
}

std::optional<std::vector<std::vector<double>>> IsolatedDevice::Race(const std::vector<Variant>& variants,
                                                                        const TuningDataset& dataset,
                                                                        const TimingOptions& options, std::string* why_not) {
  auto fail = [&](const std::string& why) -> std::optional<std::vector<std::vector<double>>> {
    if (why_not) *why_not = why;
    return std::nullopt;
  };
  if (variants.empty()) return std::vector<std::vector<double>>{};
  const std::string request =
      nlohmann::json{{"race", variants}, {"dataset", dataset.key}, {"timing", ToJson(options)}}.dump();
  std::string line, why;
  if (!Exchange(request, variant_timeout_s_ * static_cast<double>(variants.size()), line, why)) return fail(why);
  try {
    const nlohmann::json answer = nlohmann::json::parse(line);
    if (answer.is_object() && answer.contains("race_error") && answer["race_error"].is_string())
      return fail(answer["race_error"].get<std::string>());
    if (answer.is_object() && answer.contains("race") && answer["race"].is_array() && answer["race"].size() == variants.size()) {
      auto samples = answer["race"].get<std::vector<std::vector<double>>>();
      for (const std::vector<double>& s : samples)
        for (const double ms : s)
          if (!(ms > 0.0) || !std::isfinite(ms)) return fail("impossible race sample " + std::to_string(ms) + " ms");
      return samples;
    }
  } catch (const nlohmann::json::exception&) {
  }
  Kill();  // an answer out of protocol: a fresh child serves the next request
  return fail("worker process sent a malformed race answer: '" + line.substr(0, 200) + "'");
}

std::optional<double> IsolatedDevice::CopyBandwidthGBps(std::size_t bytes, std::string* why_not) {
  auto fail = [&](const std::string& why) -> std::optional<double> {
    if (why_not) *why_not = why;
    return std::nullopt;
  };
  const std::string request = nlohmann::json{{"copy_bandwidth", bytes}}.dump();
  std::string line, why;
  if (!Exchange(request, variant_timeout_s_, line, why)) return fail(why);
  nlohmann::json answer;
  try {
    answer = nlohmann::json::parse(line);
  } catch (const nlohmann::json::exception&) {
    Kill();
    throw WorkerError("worker process sent a malformed line: '" + line.substr(0, 200) + "'");
  }
  if (answer.is_object() && answer.contains("copy_bandwidth_gbps") && answer["copy_bandwidth_gbps"].is_number()) {
    const double gbps = answer["copy_bandwidth_gbps"].get<double>();
    if (!(std::isfinite(gbps) && gbps > 0.0)) return fail("impossible copy bandwidth " + answer["copy_bandwidth_gbps"].dump() + " GB/s");
    return gbps;
  }
  if (answer.is_object() && answer.contains("copy_bandwidth_error") && answer["copy_bandwidth_error"].is_string()) {
    return fail(answer["copy_bandwidth_error"].get<std::string>());
  }
  Kill();
  if (answer.is_object() && answer.contains("error") && answer["error"].is_string()) {
    throw WorkerError(answer["error"].get<std::string>());
  }
  throw WorkerError("worker process sent '" + line.substr(0, 200) + "' for a copy bandwidth request");
}

// ------------------------------------------------------------------ child side

namespace {

// A measurement allocates and frees buffers of hundreds of MB on a large mesh
// (6400k-b4: the poisoned outputs, the read-backs, their unpacking, the
// drivers' host copies). glibc maps every block over 32 MB afresh and unmaps
// it when freed, so each measurement paid the kernel's zeroing of every new
// page again (27% of a 6400k measurement's process time under perf). From the
// heap instead, kept once freed: the worker's memory stays at its largest
// measurement's, and a 6400k-b4 measurement's "run" phase went from ~275 to
// ~80 ms on PoCL (docs/PERFORMANCE.md "The cost of a tuning run").
void KeepLargeBlocks() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_MAX, 0);
  mallopt(M_TRIM_THRESHOLD, INT_MAX);
#endif
}

// Writes one protocol line, whole, on `fd` (the original stdout); ends the
// process when the parent is gone.
void WriteLine(int fd, const nlohmann::json& answer) {
  const std::string text = answer.dump() + "\n";
  std::size_t sent = 0;
  while (sent < text.size()) {
    const ssize_t n = ::write(fd, text.data() + sent, text.size() - sent);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) std::_Exit(1);  // the parent is gone
    sent += static_cast<std::size_t>(n);
  }
}

// The device the worker serves: the one whose id is `device_id` when given
// (the parent's numbering may differ from this process's), else number
// `index`; nullptr with `why` when there is none.
TunedDevice* ServedDevice(const Discovery& discovery, int index, const std::string& device_id, std::string& why) {
  if (!device_id.empty()) {
    std::string found;
    for (const std::unique_ptr<TunedDevice>& d : discovery.devices) {
      if (d->identity().Id() == device_id) return d.get();
      found += (found.empty() ? "" : ", ") + d->identity().Id();
    }
    why = "device '" + device_id + "' not found by the worker (it found: " + found + ")";
    return nullptr;
  }
  if (index < 0 || static_cast<std::size_t>(index) >= discovery.devices.size()) {
    why = "no device " + std::to_string(index) + " (" + std::to_string(discovery.devices.size()) + " found)";
    return nullptr;
  }
  return discovery.devices[static_cast<std::size_t>(index)].get();
}

TuningDataset DatasetOf(const nlohmann::json& request) { return {request.at("dataset").get<std::string>()}; }

// The answer to one request (worker.h's protocol); *lost: the device is lost
// for this process (DeviceLostIn), which then answers and exits.
nlohmann::json Answer(TunedDevice& device, const nlohmann::json& request, bool* lost) {
  if (request.contains("compile_ahead")) {
    const std::vector<Variant> variants = request.at("compile_ahead").get<std::vector<Variant>>();
    return {{"compiled", device.CompileAhead(variants, DatasetOf(request), CompileForOf(request))}};
  }
  if (request.contains("race")) {
    try {
      const std::vector<Variant> variants = request.at("race").get<std::vector<Variant>>();
      const TuningDataset dataset = DatasetOf(request);
      return {{"race", device.Race(variants, dataset, TimingFromJson(request.at("timing")))}};
    } catch (const Error& e) {
      return {{"race_error", e.what()}};
    }
  }
  if (request.contains("copy_bandwidth")) {
    try {
      return {{"copy_bandwidth_gbps", device.CopyBandwidthGBps(request.at("copy_bandwidth").get<std::size_t>())}};
    } catch (const Error& e) {
      return {{"copy_bandwidth_error", e.what()}};
    }
  }
  const Variant variant = request.at("variant").get<Variant>();
  const TuningDataset dataset = DatasetOf(request);
  const Measurement m = device.Measure(variant, dataset, TimingFromJson(request.at("timing")));
  nlohmann::json answer = m;
  // Nothing this process measures from now on can be trusted: it answers,
  // then exits, and the parent starts a fresh worker.
  *lost = tuner_internal::DeviceLostIn(m.detail);
  if (*lost) answer["device_lost"] = true;
  return answer;
}

// Answers every request line on stdin until its end, or until the device is lost.
void Serve(TunedDevice& device, int protocol) {
  std::string line;
  while (std::getline(std::cin, line)) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    nlohmann::json answer;
    bool lost = false;
    try {
      answer = Answer(device, nlohmann::json::parse(line), &lost);
    } catch (const Error& e) {
      answer = {{"error", e.what()}};
    } catch (const std::exception& e) {
      answer = {{"error", std::string("tune-worker: internal error: ") + e.what()}};
    }
    WriteLine(protocol, answer);
    if (lost) return;
  }
}

}  // namespace

int RunTuneWorker(const TuneWorkerArgs& args) {
  KeepLargeBlocks();
  try {
    if (!args.host_lock.empty()) tuner_internal::UseHostLock(args.host_lock);
    if (!args.chip_lock.empty()) tuner_internal::UseChipLock(args.chip_lock);
  } catch (const Error& e) {
    std::cerr << "skintune: tune-worker: " << e.what() << "\n";
    return 1;
  }
  // Protocol lines go to the original stdout only; anything a library prints
  // on stdout goes to stderr instead, where the parent keeps it for details.
  const int protocol = ::fcntl(1, F_DUPFD_CLOEXEC, 3);
  if (protocol < 0 || ::dup2(2, 1) < 0) {
    std::cerr << "skintune: tune-worker: cannot set up its output (" << std::strerror(errno) << ")\n";
    return 1;
  }
  Discovery discovery;
  try {
    // The failure tests' hook: $SKINTUNE_INJECT_FAULT breaks one variant on every device (fault_injection.h).
    const tuner_internal::ExecutorDecorator faults = tuner_internal::FaultsFromEnvironment();
    try {
      const auto start = std::chrono::steady_clock::now();
      const char* only = args.discover_only.empty() ? nullptr : args.discover_only.c_str();
      const tuner_internal::GivenCache given{args.device_id, args.cache_bytes, args.cache_source};
      {
        // The APIs' contexts opened to discover: untimed work on the chip, which a race there waits for.
        const tuner_internal::ChipQuiet landing(tuner_internal::ChipQuiet::Mode::kLanding);
        discovery = tuner_internal::DiscoverTunedDevices(faults, only, args.cache_bytes ? &given : nullptr);
      }
      TimingLog([&] {
        return "tune-worker " + args.device_id + ": " +
               (only ? args.discover_only + "'s" : std::string("every API's")) +
               " devices found in " +
               std::to_string(std::lround(
                   std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count())) +
               " ms (pid " + std::to_string(::getpid()) + ")";
      });
    } catch (const std::exception& e) {
      throw Error(std::string("device discovery failed: ") + e.what());
    }
  } catch (const Error& e) {
    WriteLine(protocol, {{"error", e.what()}});
    return 1;
  }
  std::string why;
  TunedDevice* device = ServedDevice(discovery, args.device_index, args.device_id, why);
  if (!device) {
    WriteLine(protocol, {{"error", why}});
    return 1;
  }
  WriteLine(protocol, {{"ready", true}, {"device_id", device->identity().Id()}});
  Serve(*device, protocol);
  return 0;
}

}  // namespace skintune::internal
