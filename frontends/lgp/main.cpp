// `lgp <command> [args]`: dispatches to the registered subcommands (see commands.hpp).
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>

#include "commands.hpp"

namespace {
void usage(FILE* f) {
  std::fprintf(f, "usage: lgp <command> [options]\n\ncommands:\n");
  for (const auto& c : lgp::cli::commands())
    std::fprintf(f, "  %-10s %s\n", c.name.c_str(), c.summary.c_str());
  std::fprintf(f, "\n`lgp <command> --help` describes a command.\n");
}
}  // namespace

int main(int argc, char** argv) {
  // Each generation runs a few short parallel regions; libgomp's default spin-waiting makes
  // threads burn their partners' time slices on a shared machine (measured 4.8x slower with 2
  // threads under load). libgomp reads the policy when it loads, before main, so set it and
  // re-execute once. An explicit OMP_WAIT_POLICY from the user is respected.
  if (!std::getenv("OMP_WAIT_POLICY")) {
    setenv("OMP_WAIT_POLICY", "passive", 1);
    execv("/proc/self/exe", argv);  // on failure, just continue with the default policy
  }
  if (argc < 2 || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h")) {
    usage(argc < 2 ? stderr : stdout);
    return argc < 2 ? 2 : 0;
  }
  const std::string name = argv[1];
  for (const auto& c : lgp::cli::commands()) {
    if (c.name != name) continue;
    std::string prog = "lgp " + name;
    argv[1] = prog.data();
    try {
      return c.main(argc - 1, argv + 1);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "error: %s\n", e.what());
      return 2;
    }
  }
  std::fprintf(stderr, "error: unknown command '%s'\n\n", name.c_str());
  usage(stderr);
  return 2;
}
