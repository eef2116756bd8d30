#include "lgp/io/table_file.hpp"

namespace lgp {

Expected<Table> loadTableFile(const DataConfig& data, const std::filesystem::path& base_dir) {
  if (data.path.empty()) return Status::error("/data/path: no table file named");
  std::filesystem::path p = data.path;
  if (p.is_relative()) p = base_dir / p;
  auto raw = readTableFile(p);
  if (!raw) return raw.status();
  return selectColumns(*raw, data.inputs, data.outputs, data.weights, p.string());
}

}  // namespace lgp
