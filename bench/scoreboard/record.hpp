// A table's record on disk (<out>/tables/<name>.json): everything the report shows of one table
// run, so a board can be run table by table (one invocation, or one session, per table) and its
// report rebuilt from every record in the folder.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "board.hpp"

namespace lgp::board {

// The resources one table took (its share of the report's wall and CPU time).
struct RecordTiming {
  std::string cpu;  // the CPU model
  double wall_s = 0, cpu_s = 0;
};

// A formula's held-out figures as JSON (records and summary.json); NaN is null, infinity "inf".
nlohmann::json scoredJson(const Scored& s);

struct Record {
  Settings settings;
  RecordTiming timing;
  TableRun run;  // without the tables, fronts and config: what the report reads
};

// Writes <dir>/tables/<name>.json and the front of every budget beside it
// (<name>.front.<minutes>min.json, lgp-front/1 with measured costs: `lgp front` reads it).
void writeRecord(const TableRun& r, const Settings& s, const RecordTiming& t,
                 const std::filesystem::path& dir);
// The fronts writeRecord wrote beside r's record (one per snapshot), into r.snaps[].front.
Status readFronts(TableRun& r, const Settings& s, const std::filesystem::path& dir);
// Every record in <dir>/tables; a file that is not a record is reported (`skipped`) and left out.
std::vector<Record> readRecords(const std::filesystem::path& dir,
                                std::vector<std::string>& skipped);

}  // namespace lgp::board
