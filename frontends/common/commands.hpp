// Subcommand registry of the `lgp` CLI. Each frontends/lgp/cmd_*.cpp defines one command and
// registers it with a static LGP_REGISTER_COMMAND, so adding a command touches no other file.
// Commands return the process exit code; exceptions escaping a command are turned into an
// "error: ..." message and exit code 2 by main.
#pragma once

#include <string>
#include <vector>

namespace lgp::cli {

struct Command {
  std::string name;                    // `lgp <name> ...`
  std::string summary;                 // one line for `lgp --help`
  int (*main)(int argc, char** argv);  // argv[0] is "lgp <name>"
};

void registerCommand(const Command& c);
const std::vector<Command>& commands();

struct CommandRegistrar {
  explicit CommandRegistrar(const Command& c) { registerCommand(c); }
};

}  // namespace lgp::cli

#define LGP_REGISTER_COMMAND(var, name, summary, fn) \
  static ::lgp::cli::CommandRegistrar var {          \
    ::lgp::cli::Command {                            \
      name, summary, fn                              \
    }                                                \
  }
