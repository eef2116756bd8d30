// `lgp <command> [args]`: dispatches to the registered subcommands (see commands.hpp).
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <iostream>
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
// A command's standard output must have reached its file: on a full disk (or /dev/full) the
// buffered text fails only at the flush, and an exit status of 0 would claim the output is
// complete. An error here turns a success into exit 1 with a message.
int checkStdout(int code) {
  std::cout.flush();
  bool failed = !std::cout;
  int err = 0;
  if (std::fflush(stdout) != 0) failed = true, err = errno;
  if (std::ferror(stdout)) failed = true;
  // (stdout stays open: a static destructor may still print.)
  if (!failed) return code;
  std::fprintf(stderr, "error: cannot write the output (standard output)%s%s\n", err ? ": " : "",
               err ? std::strerror(err) : "");
  return code == 0 ? 1 : code;
}

}  // namespace

int main(int argc, char** argv) {
  lgp::cli::ensurePassiveOpenMpWaits(argv);
  if (argc < 2 || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h")) {
    usage(argc < 2 ? stderr : stdout);
    return checkStdout(argc < 2 ? 2 : 0);
  }
  const std::string name = argv[1];
  for (const auto& c : lgp::cli::commands()) {
    if (c.name != name) continue;
    std::string prog = "lgp " + name;
    argv[1] = prog.data();
    try {
      return checkStdout(c.main(argc - 1, argv + 1));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "error: %s\n", e.what());
      return 2;
    }
  }
  std::fprintf(stderr, "error: unknown command '%s'\n\n", name.c_str());
  usage(stderr);
  return 2;
}
