// Where data files (tables and scenes) may be read from, for the whole process. A daemon that
// reads files a request names (lgpd with allowed_data_dirs) sets the roots once; every table
// and scene reader then checks the file it has opened, by the descriptor (/proc/self/fd), so
// that neither a link nor a file swapped for a link after an earlier check by path can lead
// outside. Unset (the default, and always in `lgp`): files are read from anywhere.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "lgp/core/status.hpp"

namespace lgp {

// Replaces the roots (made absolute, links resolved); an empty list lifts the restriction.
void setDataRoots(const std::vector<std::filesystem::path>& roots);

// The file open as `fd` (named `shown` in the message) lies inside a root, or no roots are set.
// Error: "<shown>: is outside the allowed data directories" (the real path is not shown).
Status checkDataRoots(int fd, const std::string& shown);

// readInputFile for a data file: the same checks, plus checkDataRoots on the opened file.
Expected<std::string> readDataFile(const std::filesystem::path& path, size_t max_bytes);

}  // namespace lgp
