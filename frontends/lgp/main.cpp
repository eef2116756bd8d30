// `lgp <command> [args]`: dispatches to the registered subcommands (see commands.hpp).
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>

#include "commands.hpp"
#include "omp_env.hpp"

namespace {
void usage(FILE* f) {
  std::fprintf(f, "usage: lgp <command> [options]\n\ncommands:\n");
  for (const auto& c : lgp::cli::commands())
    std::fprintf(f, "  %-10s %s\n", c.name.c_str(), c.summary.c_str());
  std::fprintf(f, "\n`lgp <command> --help` describes a command.\n");
}
}  // namespace

int main(int argc, char** argv) {
  lgp::cli::ensurePassiveOpenMpWaits(argv);
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
