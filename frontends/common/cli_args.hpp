// Shared option parsing for the `lgp` subcommands (cxxopts).
#pragma once

#include <cstdio>
#include <cxxopts.hpp>
#include <iostream>
#include <string>
#include <variant>

namespace lgp::cli {

// Parses argv. Returns the parse result, or the exit code the command should return at once:
// 0 after printing --help, 2 after a parse error or when the required positional option is
// missing (the message then names what is missing).
inline std::variant<cxxopts::ParseResult, int> parseArgs(cxxopts::Options& opts, int argc,
                                                         char** argv, const std::string& required,
                                                         const std::string& missing_message) {
  cxxopts::ParseResult args;
  try {
    args = opts.parse(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  }
  if (args.count("help")) {
    std::cout << opts.help() << "\n";
    return 0;
  }
  if (!required.empty() && !args.count(required)) {
    std::fprintf(stderr, "error: %s\n%s\n", missing_message.c_str(), opts.help().c_str());
    return 2;
  }
  return args;
}

}  // namespace lgp::cli
