// skintune: generates, verifies and autotunes GPU skinning kernels.
// Exit codes: 0 success, 1 bad input or failed operation (one line on
// stderr), 2 bad command line or a setting that cannot work (UsageError).
#include <iostream>
#include <new>
#include <vector>

#include "base/error.h"
#include "tools/commands.h"

#ifndef SKINTUNE_VERSION
#define SKINTUNE_VERSION "unknown"
#endif

int main(int argc, char** argv) {
  namespace tools = skintune::internal::tools;
  CLI::App app{"skintune: generates, verifies and autotunes GPU skinning kernels (linear blend skinning)",
               "skintune"};
  app.set_version_flag("--version", std::string("skintune ") + SKINTUNE_VERSION);
  app.require_subcommand(1);
  const std::vector<tools::Command> commands = {tools::RegisterRun(app), tools::RegisterDevices(app),
                                                tools::RegisterSkin(app), tools::RegisterVariants(app),
                                                tools::RegisterEmit(app),
                                                tools::RegisterTune(app), tools::RegisterTuneWorker(app),
                                                tools::RegisterDb(app), tools::RegisterReport(app),
                                                tools::RegisterPaper(app, argc, argv)};
  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {
    return app.exit(e);  // --help, --version
  } catch (const CLI::ParseError& e) {
    std::cerr << "skintune: " << skintune::internal::OneLine(e.what()) << " (try --help)\n";
    return 2;
  }
  try {
    for (const tools::Command& command : commands) {
      if (command.subcommand->parsed()) return command.run();
    }
  } catch (const skintune::internal::UsageError& e) {
    std::cerr << "skintune: error: " << skintune::internal::OneLine(e.what()) << "\n";
    return 2;
  } catch (const skintune::internal::Error& e) {
    std::cerr << "skintune: error: " << skintune::internal::OneLine(e.what()) << "\n";
    return 1;
  } catch (const std::bad_alloc&) {  // every input is sized before it is read: a fallback
    std::cerr << "skintune: error: out of memory\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "skintune: internal error: " << e.what() << "\n";
    return 1;
  }
  return 2;
}
