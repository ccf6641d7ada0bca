// The parent side of the worker protocol (tuner/worker.h), against fake
// workers (shell scripts): answers, hangs, crashes, exits, errors, restarts.
// No device needed; the real worker is exercised by tune_cli_test.
#include "tuner/worker.h"

#include "generator/emit.h"  // kGeneratorVersion

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <thread>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "tests/common/scratch_dir.h"
#include "tuner/device_tuning.h"

namespace skintune::internal {
namespace {

namespace fs = std::filesystem;

fs::path Scratch() { return skintune::internal::testing::ScratchDir("skintune_worker_test"); }

DeviceIdentity FakeDevice() {
  DeviceIdentity d;
  d.backend = "opencl";
  d.index = 3;
  d.platform = "Fake";
  d.name = "dev";
  d.driver_version = "1";
  return d;
}

const char* kAnswer =
    R"({"device_id":"elsewhere","dataset":"x","variant":{"lang":"cuda"},"status":"ok","generator_version":"9",)"
    R"("timing":{"median_ms":1.5,"min_ms":1.0,"max_ms":2.0,"warmup":1,"repetitions":3,"input_sets":2},"gbps":7.5,)"
    R"("bytes_per_frame":11250000})";

// A fake `skintune`: greets as FakeDevice(), then runs `body` (sh) with the
// arguments it was started with in "$@" and its directory in $DIR.
std::string FakeWorker(const fs::path& dir, const std::string& body, const std::string& device_id = "") {
  const fs::path script = dir / "fake-skintune";
  std::ofstream out(script);
  out << "#!/bin/sh\nDIR='" << dir.string() << "'\necho \"$@\" > \"$DIR/args\"\n"
      << "echo '{\"ready\": true, \"device_id\": \"" << (device_id.empty() ? FakeDevice().Id() : device_id)
      << "\"}'\n"
      << body << "\n";
  out.close();
  ::chmod(script.c_str(), 0755);
  return script.string();
}

const Variant kVariant = ParseVariantKey("opencl.b2.soa.global.wg64");
const TuningDataset kDataset{"5000-b2"};

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const WorkerError& e) {
    return e.what();
  }
  return "(no error)";
}

std::string ReadAll(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// A parameterised test's scratch folder ("Name/param") is one folder in the
// temporary directory: a folder in a folder left the outer one behind.
class ScratchOfAParameterisedTest : public ::testing::TestWithParam<int> {};
TEST_P(ScratchOfAParameterisedTest, IsOneFolderInTheTemporaryDirectory) {
  const fs::path dir = Scratch();
  EXPECT_EQ(dir.parent_path(), fs::temp_directory_path());
  EXPECT_TRUE(fs::is_directory(dir));
  EXPECT_NE(dir.filename().string().find("IsOneFolderInTheTemporaryDirectory_"), std::string::npos) << dir;
}
INSTANTIATE_TEST_SUITE_P(Params, ScratchOfAParameterisedTest, ::testing::Values(1));

// docs/INPUTS.md "Measurements: one rule for every time": a device (its timer, its driver) that reports an
// impossible time fails that variant, never the run, and never ranks.
TEST(IsolatedDevice, AnImpossibleTimeFromTheWorkerIsLaunchFailedAndTheWorkerStays) {
  const fs::path dir = Scratch();
  std::string zero = kAnswer;
  zero.replace(zero.find("\"median_ms\":1.5"), 15, "\"median_ms\":0.0");
  const std::string exe = FakeWorker(dir, "while read line; do echo '" + zero + "'; done");
  IsolatedDevice worker(exe, FakeDevice(), 30);
  for (int i = 0; i < 2; ++i) {
    const Measurement m = worker.Measure(kVariant, kDataset, TimingOptions{});
    EXPECT_EQ(m.status, MeasureStatus::kLaunchFailed);
    EXPECT_EQ(m.detail.rfind("the device reported measurement: impossible figures: status ok with 'median_ms' is 0", 0),
              0u)
        << m.detail;
    EXPECT_EQ(m.variant, kVariant);
  }
  EXPECT_EQ(worker.starts(), 1);
}

TEST(IsolatedDevice, SendsOneRequestPerLineAndReadsTheMeasurement) {
  const fs::path dir = Scratch();
  const std::string exe =
      FakeWorker(dir, std::string("while read line; do echo \"$line\" >> \"$DIR/requests\"; echo '") + kAnswer +
                          "'; done");
  IsolatedDevice worker(exe, FakeDevice(), 30);
  TimingOptions timing;
  timing.repetitions = 3;
  for (int i = 0; i < 2; ++i) {
    const Measurement m = worker.Measure(kVariant, kDataset, timing);
    EXPECT_EQ(m.status, MeasureStatus::kOk);
    EXPECT_EQ(m.timing.median_ms, 1.5);
    EXPECT_EQ(m.gbps, 7.5);
    // What identifies the measurement is the parent's.
    EXPECT_EQ(m.device_id, FakeDevice().Id());
    EXPECT_EQ(m.dataset, "5000-b2");
    EXPECT_EQ(m.variant, kVariant);
    EXPECT_EQ(m.generator_version, kGeneratorVersion);
  }
  EXPECT_EQ(worker.starts(), 1);
  // The worker selects its device by identity; the index is only a hint.
  EXPECT_EQ(ReadAll(dir / "args"), "tune-worker --device-index 3 --device-id " + FakeDevice().Id() + " --discover-only opencl\n");
  std::ifstream requests(dir / "requests");
  std::string line;
  ASSERT_TRUE(std::getline(requests, line));
  const nlohmann::json request = nlohmann::json::parse(line);
  EXPECT_EQ(request.at("variant").get<Variant>(), kVariant);
  EXPECT_EQ(request.at("dataset"), "5000-b2");
  EXPECT_EQ(request.at("timing").at("repetitions"), 3);
  EXPECT_EQ(request.at("timing").at("warmup"), timing.warmup);
  EXPECT_EQ(request.at("timing").at("max_input_sets"), timing.max_input_sets);
  EXPECT_EQ(request.at("timing").at("tolerance"), timing.tolerance);
}

TEST(IsolatedDevice, HangIsATimeoutAndAFreshWorkerServesTheNextVariant) {
  const fs::path dir = Scratch();
  // The first worker hangs on its request; the ones after it answer.
  const std::string exe = FakeWorker(
      dir, std::string("if [ ! -e \"$DIR/hung\" ]; then : > \"$DIR/hung\"; read line; exec sleep 600; fi\n") +
               "while read line; do echo '" + kAnswer + "'; done");
  IsolatedDevice worker(exe, FakeDevice(), 0.5);
  const auto start = std::chrono::steady_clock::now();
  const Measurement hung = worker.Measure(kVariant, kDataset, {});
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 10.0);
  EXPECT_EQ(hung.status, MeasureStatus::kTimeout);
  EXPECT_EQ(hung.detail, "no result within 0.5 s");
  EXPECT_EQ(hung.variant, kVariant);
  EXPECT_EQ(hung.device_id, FakeDevice().Id());
  const Measurement next = worker.Measure(kVariant, kDataset, {});
  EXPECT_EQ(next.status, MeasureStatus::kOk);
  EXPECT_EQ(worker.starts(), 2);
}

TEST(IsolatedDevice, CrashIsALaunchFailureNamingTheSignal) {
  const fs::path dir = Scratch();
  const std::string exe = FakeWorker(
      dir, std::string("if [ ! -e \"$DIR/crashed\" ]; then : > \"$DIR/crashed\"; read line; ") +
               "echo 'about to crash' >&2; kill -ABRT $$; fi\nwhile read line; do echo '" + kAnswer + "'; done");
  IsolatedDevice worker(exe, FakeDevice(), 30);
  const Measurement crashed = worker.Measure(kVariant, kDataset, {});
  EXPECT_EQ(crashed.status, MeasureStatus::kLaunchFailed);
  EXPECT_EQ(crashed.detail, "worker process died: signal 6 (Aborted); its last stderr line: about to crash");
  EXPECT_EQ(worker.Measure(kVariant, kDataset, {}).status, MeasureStatus::kOk);
  EXPECT_EQ(worker.starts(), 2);
}

// A worker killed from outside (kill -9 by a user, the OOM killer) or
// stopped until its time ran out says nothing about the variant: recorded
// as interrupted, which a resumed run measures again, unlike a crash.
TEST(IsolatedDevice, AWorkerKilledOrStoppedFromOutsideIsRecordedAsInterrupted) {
  const fs::path dir = Scratch();
  const std::string exe = FakeWorker(
      dir, std::string("read line; case \"$(ls \"$DIR\" | grep -c '^seen')\" in\n") +
               "0) : > \"$DIR/seen1\"; kill -KILL $$;;\n"   // as `kill -9 <worker>` from a shell
               "1) : > \"$DIR/seen2\"; kill -STOP $$;;\n"   // as a debugger or `kill -STOP`
               "esac\nwhile :; do echo '" + kAnswer + "'; read line || exit 0; done");
  IsolatedDevice worker(exe, FakeDevice(), 1.0);
  const Measurement killed = worker.Measure(kVariant, kDataset, {});
  EXPECT_EQ(killed.status, MeasureStatus::kLaunchFailed);
  EXPECT_EQ(killed.detail, std::string(kInterruptedDetail) + "worker process died: signal 9 (Killed)");
  EXPECT_NE(MeasuredAgainOnResume(killed, 1e-5), "");
  const Measurement stopped = worker.Measure(kVariant, kDataset, {});
  EXPECT_EQ(stopped.status, MeasureStatus::kTimeout);
  EXPECT_EQ(stopped.detail, std::string(kInterruptedDetail) + "the worker process was stopped; no result within 1 s");
  EXPECT_NE(MeasuredAgainOnResume(stopped, 1e-5), "");
  EXPECT_EQ(worker.Measure(kVariant, kDataset, {}).status, MeasureStatus::kOk);
}

// A worker whose device was lost answers with "device_lost" and exits; the
// variant is measured again in a fresh worker, whose answer is kept, with the
// first one's detail.
const char* kLostAnswer =
    R"({"device_id":"elsewhere","dataset":"x","variant":{"lang":"cuda"},"status":"launch_failed",)"
    R"("generator_version":"9","detail":"GL lost: the driver reset the GL context","device_lost":true})";

TEST(IsolatedDevice, ALostDeviceIsMeasuredAgainInAFreshWorker) {
  const fs::path dir = Scratch();
  const std::string exe = FakeWorker(
      dir, std::string("if [ ! -e \"$DIR/lost\" ]; then : > \"$DIR/lost\"; read line; echo '") + kLostAnswer +
               "'; exit 0; fi\nwhile read line; do echo '" + kAnswer + "'; done");
  IsolatedDevice worker(exe, FakeDevice(), 30);
  const Measurement m = worker.Measure(kVariant, kDataset, {});
  EXPECT_EQ(m.status, MeasureStatus::kOk);
  EXPECT_EQ(m.detail,
            "measured in a fresh worker process: the first lost the device (GL lost: the driver reset the GL context)");
  EXPECT_EQ(worker.starts(), 2);
  // The fresh worker serves the next variant.
  EXPECT_EQ(worker.Measure(kVariant, kDataset, {}).status, MeasureStatus::kOk);
  EXPECT_EQ(worker.starts(), 2);
}

TEST(IsolatedDevice, ADeviceLostTwiceIsRecordedAndTheNextVariantGetsAThirdWorker) {
  const fs::path dir = Scratch();
  const std::string exe = FakeWorker(
      dir, std::string("n=$(ls \"$DIR\" | grep -c '^lost') ; if [ \"$n\" -lt 2 ]; then : > \"$DIR/lost$n\"; read line; echo '") +
               kLostAnswer + "'; exit 0; fi\nwhile read line; do echo '" + kAnswer + "'; done");
  IsolatedDevice worker(exe, FakeDevice(), 30);
  const Measurement m = worker.Measure(kVariant, kDataset, {});
  EXPECT_EQ(m.status, MeasureStatus::kLaunchFailed);
  EXPECT_EQ(m.detail,
            "GL lost: the driver reset the GL context (the device was lost in two fresh worker processes, one after the other)");
  EXPECT_EQ(worker.starts(), 2);
  EXPECT_EQ(worker.Measure(kVariant, kDataset, {}).status, MeasureStatus::kOk);
  EXPECT_EQ(worker.starts(), 3);
}

TEST(IsolatedDevice, ExitIsALaunchFailureNamingTheExitCode) {
  const fs::path dir = Scratch();
  const std::string exe = FakeWorker(dir, "read line; exit 3");
  IsolatedDevice worker(exe, FakeDevice(), 30);
  const Measurement m = worker.Measure(kVariant, kDataset, {});
  EXPECT_EQ(m.status, MeasureStatus::kLaunchFailed);
  EXPECT_EQ(m.detail, "worker process died: exit code 3");
}

TEST(IsolatedDevice, SetUpErrorOfTheDeviceIsAWorkerError) {
  const fs::path dir = Scratch();
  IsolatedDevice worker(FakeWorker(dir, "read line; echo '{\"error\": \"device lost\"}'"), FakeDevice(), 30);
  EXPECT_EQ(ErrorOf([&] { worker.Measure(kVariant, kDataset, {}); }), "device lost");
}

TEST(IsolatedDevice, WorkerOfAnotherDeviceIsAWorkerError) {
  const fs::path dir = Scratch();
  IsolatedDevice worker(FakeWorker(dir, "cat > /dev/null", "gl:EGL/other/2"), FakeDevice(), 30);
  EXPECT_EQ(ErrorOf([&] { worker.Measure(kVariant, kDataset, {}); }),
            "worker process found 'gl:EGL/other/2' as device 3, not '" + FakeDevice().Id() +
                "' (the devices changed since discovery)");
}

TEST(IsolatedDevice, WorkerThatCannotStartIsAWorkerError) {
  const fs::path dir = Scratch();
  const fs::path script = dir / "broken";
  std::ofstream(script) << "#!/bin/sh\necho 'no device here' >&2\nexit 1\n";
  ::chmod(script.c_str(), 0755);
  IsolatedDevice worker(script.string(), FakeDevice(), 30);
  EXPECT_EQ(ErrorOf([&] { worker.Measure(kVariant, kDataset, {}); }),
            "worker process failed to start: exit code 1; its last stderr line: no device here");
  IsolatedDevice missing((dir / "does-not-exist").string(), FakeDevice(), 30);
  EXPECT_EQ(ErrorOf([&] { missing.Measure(kVariant, kDataset, {}); }),
            "worker process failed to start: exit code 127; its last stderr line: skintune: cannot execute the tune "
            "worker");
}

TEST(IsolatedDevice, CopyBandwidthAnswerOrReason) {
  const fs::path dir = Scratch();
  IsolatedDevice worker(
      FakeWorker(dir, "read line; echo '{\"copy_bandwidth_gbps\": 12.5}'; read line; "
                      "echo '{\"copy_bandwidth_error\": \"no copy kernel\"}'; read line; exit 4"),
      FakeDevice(), 30);
  std::string why;
  EXPECT_EQ(worker.CopyBandwidthGBps(1 << 20, &why), 12.5);
  EXPECT_EQ(worker.CopyBandwidthGBps(1 << 20, &why), std::nullopt);
  EXPECT_EQ(why, "no copy kernel");
  EXPECT_EQ(worker.CopyBandwidthGBps(1 << 20, &why), std::nullopt);
  EXPECT_EQ(why, "worker process died: exit code 4");
}

// The host lock and the chip lock (tuner/host_lock.h) reach every worker as
// --host-lock and --chip-lock.
TEST(IsolatedDevice, WorkersAreToldTheHostAndChipLocks) {
  const fs::path dir = Scratch();
  for (const bool with_lock : {false, true}) {
    IsolatedDevice worker(FakeWorker(dir, "read line; echo '{\"copy_bandwidth_gbps\": 12.5}'"), FakeDevice(), 30);
    if (with_lock) worker.UseHostLock("/tmp/the-host-lock");
    if (with_lock) worker.UseChipLock("/tmp/the-chip-lock");
    EXPECT_EQ(worker.CopyBandwidthGBps(1 << 20), 12.5);
    const std::string args = ReadAll(dir / "args");
    EXPECT_EQ(args.find("--host-lock /tmp/the-host-lock") != std::string::npos, with_lock) << args;
    EXPECT_EQ(args.find("--chip-lock /tmp/the-chip-lock") != std::string::npos, with_lock) << args;
  }
}

// Every worker looks for its own API's devices alone and is given the cache
// figure its parent resolved across every API's view of the chip (NVIDIA's
// OpenCL alone would say 4.3 MB of a 50 MB L2).
TEST(IsolatedDevice, AWorkerDiscoversItsApiAloneWithItsParentsCacheFigure) {
  const fs::path dir = Scratch();
  for (const char* type : {"gpu", "cpu"}) {
    DeviceIdentity device = FakeDevice();
    device.type = type;
    device.last_level_cache_bytes = 52428800;
    device.last_level_cache_source = "cuda L2 of the same chip";
    IsolatedDevice worker(FakeWorker(dir, "read line; echo '{\"copy_bandwidth_gbps\": 12.5}'"), device, 30);
    EXPECT_EQ(worker.CopyBandwidthGBps(1 << 20), 12.5);
    const std::string args = ReadAll(dir / "args");
    EXPECT_NE(args.find("--discover-only opencl"), std::string::npos) << args;
    EXPECT_NE(args.find("--cache-bytes 52428800 --cache-source cuda L2 of the same chip"), std::string::npos) << args;
  }
  DeviceIdentity unknown = FakeDevice();  // no figure: the worker's own discovery says
  const std::vector<std::string> args = WorkerArguments(unknown, "", "");
  EXPECT_EQ(args, (std::vector<std::string>{"tune-worker", "--device-index", "3", "--device-id", unknown.Id(),
                                            "--discover-only", "opencl"}));
}

// Some OpenCL ICD loaders tokenise OCL_ICD_FILENAMES in place (strtok on
// getenv's pointer) during the parent's own discovery; the worker must still
// get the variable as the process started with it. ctest sets
// SKINTUNE_TEST_ICD_LIST=first.so:second.so for this binary.
TEST(IsolatedDevice, WorkerGetsTheStartupEnvironmentEvenAfterALibraryEditedItInPlace) {
  char* live = std::getenv("SKINTUNE_TEST_ICD_LIST");
  if (live == nullptr) GTEST_SKIP() << "SKINTUNE_TEST_ICD_LIST is not set (ctest sets it)";
  ASSERT_STREQ(live, "first.so:second.so");
  std::strtok(live, ":");  // what such a loader does
  ASSERT_STREQ(std::getenv("SKINTUNE_TEST_ICD_LIST"), "first.so");
  const fs::path dir = Scratch();
  IsolatedDevice worker(
      FakeWorker(dir, "read line; echo \"{\\\"copy_bandwidth_error\\\": \\\"$SKINTUNE_TEST_ICD_LIST\\\"}\""),
      FakeDevice(), 30);
  std::string why;
  EXPECT_EQ(worker.CopyBandwidthGBps(1 << 20, &why), std::nullopt);
  EXPECT_EQ(why, "first.so:second.so");
}

}  // namespace
}  // namespace skintune::internal

namespace skintune::internal {
namespace {

// A fake worker that appends a line to $DIR/starts when it starts and each
// request to $DIR/requests, and answers every request as a compile ahead of
// `compiled` kernels.
std::string CompilingWorker(const fs::path& dir, int compiled) {
  return FakeWorker(dir, "echo started >> \"$DIR/starts\"\n"
                         "while read line; do echo \"$line\" >> \"$DIR/requests\"; "
                         "echo '{\"compiled\": " + std::to_string(compiled) + "}'; done");
}

// Compile helpers (tuner/device_tuning.h) stay the same processes from one
// compile ahead to the next: each is driven from a thread that lives as long
// as it does. One started from a thread that then ended would be killed with
// it (PR_SET_PDEATHSIG), its next share lost and a fresh one started after.
TEST(CompileHelpers, EachHelperStaysOneProcessAndGetsItsShare) {
  const fs::path dir = Scratch();
  const std::string exe = CompilingWorker(dir, 1);
  const WorkerSetup workers{exe, 30, ""};
  const DeviceIdentity device = FakeDevice();
  CompileHelpers helpers(workers, device);
  const std::vector<Variant> variants = {ParseVariantKey("opencl.b2.soa.global.wg64"),
                                         ParseVariantKey("opencl.b2.soa.global.wg128"),
                                         ParseVariantKey("opencl.b2.soa.constant.wg64"),
                                         ParseVariantKey("opencl.b2.soa.local.wg64")};
  const std::size_t expected = std::min<std::size_t>(CompileHelpers::Count(), variants.size());
  for (int call = 0; call < 3; ++call) helpers.CompileAhead(variants, kDataset);
  EXPECT_EQ(helpers.starts(), static_cast<int>(expected));
  std::size_t started = 0, requested = 0;
  std::ifstream starts(dir / "starts"), requests(dir / "requests");
  for (std::string line; std::getline(starts, line);) ++started;
  std::size_t variants_sent = 0;
  for (std::string line; std::getline(requests, line);) {
    ++requested;
    const nlohmann::json request = nlohmann::json::parse(line);
    variants_sent += request.at("compile_ahead").size();
    // Helpers never measure: their compiles are for the program cache alone.
    EXPECT_EQ(request.value("for", ""), "the cache") << line;
  }
  EXPECT_EQ(started, expected) << "helper processes started";
  EXPECT_EQ(requested, 3 * expected) << "one request per helper per call";
  EXPECT_EQ(variants_sent, 3 * variants.size()) << "every variant in one share per call";
}

// A later device's precompile (PrecompileDevice) leaves its worker for the
// device's turn (HeadStarts) when it is done first: the turn's requests go
// to the process that compiled ahead. Not when the turn came first (it has
// a worker of its own). Under the chip's lock it compiles for itself (its
// context chosen ahead, between the measuring API's jobs); without, for the
// program cache only.
TEST(HeadStarts, APrecompileDoneBeforeTheTurnLeavesItsWorkerToIt) {
  const fs::path dir = Scratch();
  const std::string exe = CompilingWorker(dir, 2);
  const std::vector<Variant> variants = {ParseVariantKey("opencl.b2.soa.global.wg64"),
                                         ParseVariantKey("opencl.b2.soa.constant.wg64")};
  TuningPlan plan;
  plan.datasets.emplace_back().info.key = kDataset.key;
  plan.devices.push_back({FakeDevice(), {}, {Lang::kOpenCl}});
  Task& task = plan.tasks.emplace_back();
  task.candidates = variants;
  MeasurementCache cache((dir / "cache.jsonl").string());
  TuningLedger ledger(cache, 0, {});
  HeadStarts head_starts;
  WorkerSetup workers{exe, 30, "", "", &head_starts};
  PrecompileDevice(plan, 0, workers, ledger, [] { return false; });
  std::unique_ptr<IsolatedDevice> left = head_starts.Take(0);
  ASSERT_NE(left, nullptr);
  EXPECT_EQ(head_starts.Take(0), nullptr) << "taken once";
  EXPECT_EQ(left->CompileAhead(variants, kDataset), 2u);
  EXPECT_EQ(left->starts(), 1) << "the turn's request went to a fresh process";
  std::vector<std::string> compile_for;
  std::ifstream requests(dir / "requests");
  for (std::string line; std::getline(requests, line);)
    compile_for.push_back(nlohmann::json::parse(line).value("for", ""));
  EXPECT_EQ(compile_for, (std::vector<std::string>{"the cache", "this process"}));
  // The turn came before it compiled anything: it leaves nothing.
  int asked = 0;
  PrecompileDevice(plan, 0, workers, ledger, [&] { return asked++ > 0; });
  EXPECT_EQ(asked, 2);
  EXPECT_EQ(head_starts.Take(0), nullptr);
  // The turn came first: it does not begin.
  fs::remove(dir / "requests");
  PrecompileDevice(plan, 0, workers, ledger, [] { return true; });
  EXPECT_FALSE(fs::exists(dir / "requests"));
  EXPECT_EQ(head_starts.Take(0), nullptr);
  // Under the chip's lock, which it takes too.
  fs::remove(dir / "requests");
  workers.chip_lock = (dir / "chip").string();
  PrecompileDevice(plan, 0, workers, ledger, [] { return false; });
  left = head_starts.Take(0);
  ASSERT_NE(left, nullptr);
  std::ifstream locked(dir / "requests");
  std::string line;
  ASSERT_TRUE(std::getline(locked, line));
  EXPECT_EQ(nlohmann::json::parse(line).value("for", ""), "this process");
  EXPECT_NE(ReadAll(dir / "args").find("--chip-lock " + workers.chip_lock), std::string::npos) << ReadAll(dir / "args");
}

// A turn's kernels compiled one task ahead (OneTaskAhead): task 0's at once,
// task i's only once task i - 1 has begun, and a task begins only once its
// own are compiled; ended early, it compiles no further task.
TEST(OneTaskAhead, CompilesExactlyOneTaskAheadOfTheTaskBegun) {
  std::mutex mutex;
  std::vector<std::size_t> started, ended;
  const auto compile = [&](std::size_t i) {
    {
      const std::lock_guard<std::mutex> lock(mutex);
      started.push_back(i);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
    const std::lock_guard<std::mutex> lock(mutex);
    ended.push_back(i);
  };
  const auto seen = [&](const std::vector<std::size_t>& list) {
    const std::lock_guard<std::mutex> lock(mutex);
    return list;
  };
  {
    OneTaskAhead ahead(3, compile);
    std::this_thread::sleep_for(std::chrono::milliseconds(150));
    EXPECT_EQ(seen(started), std::vector<std::size_t>{0}) << "no task begun: only the first";
    ahead.Begin(0);
    EXPECT_EQ(seen(ended).front(), 0u);
    for (int wait = 0; wait < 500 && seen(ended).size() < 2; ++wait)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    std::this_thread::sleep_for(std::chrono::milliseconds(100));  // time enough for task 2's to start, were it let
    EXPECT_EQ(seen(started), (std::vector<std::size_t>{0, 1})) << "task 0 begun: task 1 compiled, not task 2";
    ahead.Begin(1);
    ahead.Begin(2);
    EXPECT_EQ(seen(ended), (std::vector<std::size_t>{0, 1, 2})) << "each task begins once its own are compiled";
  }
  started.clear();
  ended.clear();
  {
    OneTaskAhead ahead(3, compile);
    ahead.Begin(0);
  }  // ended while task 1 compiles, or before it starts
  EXPECT_LE(seen(ended).size(), 2u);
  EXPECT_EQ(std::count(ended.begin(), ended.end(), 2u), 0) << "no task after the one under way";
}

// A task past those compiled for (none here) begins at once: it has no
// compile to wait for. A turn whose tasks were counted as none once waited
// for ever at its first task.
TEST(OneTaskAhead, ATaskPastThoseCompiledForBeginsAtOnce) {
  std::size_t compiled = 0;
  {
    OneTaskAhead none(0, [&](std::size_t) { ++compiled; });
    none.Begin(0);
    none.Begin(1);
  }
  {
    OneTaskAhead one(1, [&](std::size_t) { ++compiled; });
    one.Begin(0);
    one.Begin(1);
  }
  EXPECT_EQ(compiled, 1u);
}

// Workers whose input was ended together exit side by side, each reaped
// after (IsolatedDevice::EndInput): three that take 0.6 s to exit are gone
// in about 0.6 s, where stopping each in turn takes 1.8. A turn ends its
// processes so before the chip's next turn starts.
TEST(IsolatedDevice, WorkersWhoseInputWasEndedTogetherExitSideBySide) {
  const fs::path dir = Scratch();
  const std::string exe = FakeWorker(dir, "while read line; do echo '{\"compiled\": 1}'; done; sleep 0.6");
  std::vector<std::unique_ptr<IsolatedDevice>> workers;
  for (int i = 0; i < 3; ++i) {
    workers.push_back(std::make_unique<IsolatedDevice>(exe, FakeDevice(), 30));
    ASSERT_EQ(workers.back()->CompileAhead({kVariant}, kDataset), 1u);
  }
  const auto start = std::chrono::steady_clock::now();
  for (const auto& w : workers) w->EndInput();
  workers.clear();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_GE(seconds, 0.5) << "each was reaped once it had exited";
  EXPECT_LT(seconds, 1.5) << "three exits of 0.6 s one after another";
}

// A turn of NVIDIA's OpenCL (its kernels compiled in helper processes, one
// task ahead: CompileEachTaskAhead) runs every task to its end, each data
// set's kernels compiled for the program cache, no step's batch compiled
// for the measuring process. A turn that counted its tasks as none once
// waited for ever at its first.
TEST(OneTaskAhead, ATurnCompilingInHelpersRunsEveryTask) {
  const fs::path dir = Scratch();
  ::setenv("SKINTUNE_CACHE_DIR", (dir / "programs").c_str(), 1);  // helpers need a program cache
  DeviceIdentity nvidia = FakeDevice();
  nvidia.platform = "NVIDIA CUDA";
  nvidia.name = "gpu";
  ASSERT_TRUE(CompilesAheadInProcesses(nvidia));
  const std::string exe = FakeWorker(dir,
                                     std::string("while read line; do echo \"$line\" >> \"$DIR/requests\"; "
                                                 "case \"$line\" in "
                                                 "'{\"compile_ahead\":'*) echo '{\"compiled\": 1}';; "
                                                 "'{\"copy_bandwidth\":'*) echo '{\"copy_bandwidth_gbps\": 1000}';; "
                                                 "*'\"race\":['*) echo '{\"race_error\": \"no race here\"}';; "
                                                 "*) echo '") + kAnswer + "';; esac; done",
                                     nvidia.Id());
  TuningPlan plan;
  plan.devices.push_back({nvidia, {}, {Lang::kOpenCl}});
  for (const std::string key : {"5000-b2", "6000-b2"}) {
    plan.datasets.emplace_back().info.key = key;
    Task& task = plan.tasks.emplace_back();
    task.dataset = plan.datasets.size() - 1;
    task.candidates = {ParseVariantKey("opencl.b2.soa.global.wg64"), ParseVariantKey("opencl.b2.soa.constant.wg64")};
    task.planned = task.candidates.size();
  }
  MeasurementCache cache((dir / "cache.jsonl").string());
  TuningLedger ledger(cache, 4, {});
  DeviceResult result;
  result.planned = 4;
  const WorkerSetup workers{exe, 30, ""};
  TuneDevice(plan, 0, TuneConfig{}, workers, ledger, result);
  ::unsetenv("SKINTUNE_CACHE_DIR");
  EXPECT_FALSE(result.given_up) << *result.given_up;
  std::map<std::string, int> compiled, measured;  // data set: requests
  std::ifstream requests(dir / "requests");
  for (std::string line; std::getline(requests, line);) {
    const nlohmann::json request = nlohmann::json::parse(line);
    if (request.contains("compile_ahead")) {
      EXPECT_EQ(request.value("for", ""), "the cache") << line;
      ++compiled[request.value("dataset", "")];
    } else if (request.contains("variant")) {
      ++measured[request.value("dataset", "")];
    }
  }
  for (const std::string key : {"5000-b2", "6000-b2"}) {
    EXPECT_GE(compiled[key], 1) << key;
    EXPECT_GE(measured[key], 2) << key;
  }
}

// A turn that comes while its device's precompile is under way waits for
// it to end (the data set being compiled), then takes what it left; a
// precompile the turn came before does not begin.
TEST(HeadStarts, ATurnWaitsForThePrecompileUnderWay) {
  HeadStarts head_starts;
  ASSERT_TRUE(head_starts.Begin(1, [] { return false; }));
  const auto start = std::chrono::steady_clock::now();
  std::thread precompile([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    head_starts.Leave(1, nullptr);
  });
  EXPECT_EQ(head_starts.Take(1), nullptr);
  EXPECT_GE(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 0.15);
  precompile.join();
  EXPECT_FALSE(head_starts.Begin(2, [] { return true; }));
  EXPECT_EQ(head_starts.Take(2), nullptr) << "nothing under way: at once";
}

// A precompile's setting: a fake compiling worker in a scratch folder, and
// FakeDevice() with a task of two kernels on each of two data sets.
struct TwoDataSetPrecompile {
  TwoDataSetPrecompile() {
    plan.devices.push_back({FakeDevice(), {}, {Lang::kOpenCl}});
    for (const char* key : {"100k-b1", "100k-b2"}) {
      plan.datasets.emplace_back().info.key = key;
      Task& task = plan.tasks.emplace_back();
      task.dataset = plan.datasets.size() - 1;
      task.candidates = {ParseVariantKey("opencl.b2.soa.global.wg64"), ParseVariantKey("opencl.b2.soa.constant.wg64")};
    }
  }
  const fs::path dir = Scratch();
  const std::string exe = CompilingWorker(dir, 2);
  TuningPlan plan;
  MeasurementCache cache{(dir / "cache.jsonl").string()};
  TuningLedger ledger{cache, 0, {}};
  HeadStarts head_starts;
};

// A precompile overtaken after its first data set leaves its worker to the
// turn, that data set compiled, and compiles no more.
TEST(HeadStarts, APrecompileOvertakenLeavesItsWorkerAsItIs) {
  TwoDataSetPrecompile p;
  WorkerSetup workers{p.exe, 30, "", "", &p.head_starts};
  int asked = 0;  // Begin, the first data set, then the turn has come
  PrecompileDevice(p.plan, 0, workers, p.ledger, [&] { return asked++ > 1; });
  std::unique_ptr<IsolatedDevice> left = p.head_starts.Take(0);
  ASSERT_NE(left, nullptr);
  std::size_t requests = 0;
  std::ifstream lines(p.dir / "requests");
  for (std::string line; std::getline(lines, line);) ++requests;
  EXPECT_EQ(requests, 1u) << "the first data set only";
}

// A worker started ahead under the chip's lock compiles for the program
// cache only until the chip's first turn has started (ChipStart), choosing
// no context, whose probes would take the chip from that start; the data
// sets after it, for itself. Either way it is left to the turn.
TEST(HeadStarts, AWorkerStartedAheadChoosesNoContextBeforeTheChipsFirstTurnStarted) {
  TwoDataSetPrecompile p;
  ChipStart chip_start;
  WorkerSetup workers{p.exe, 30, "", (p.dir / "chip").string(), &p.head_starts, &chip_start};
  const auto compile_for = [&] {
    std::vector<std::string> all;
    std::ifstream requests(p.dir / "requests");
    for (std::string line; std::getline(requests, line);) all.push_back(nlohmann::json::parse(line).value("for", ""));
    fs::remove(p.dir / "requests");
    return all;
  };
  PrecompileDevice(p.plan, 0, workers, p.ledger, [] { return false; });
  EXPECT_EQ(compile_for(), (std::vector<std::string>{"the cache", "the cache"}));
  EXPECT_NE(p.head_starts.Take(0), nullptr) << "left to the turn all the same";
  chip_start.Open();
  PrecompileDevice(p.plan, 0, workers, p.ledger, [] { return false; });
  EXPECT_EQ(compile_for(), (std::vector<std::string>{"this process", "this process"}));
  EXPECT_NE(p.head_starts.Take(0), nullptr);
}

}  // namespace
}  // namespace skintune::internal
