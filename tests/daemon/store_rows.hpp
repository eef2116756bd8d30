// Editing lgpd's database behind its back, as a tampering user or a broken tool would (tests of
// what lgpd reads back from its own store). Link SQLite::SQLite3.
#pragma once

#include <sqlite3.h>

#include "daemon_harness.hpp"

namespace lgpd_test {

// Runs `sql` on lgpd's database with one text or blob bound to ?1 and the run id to ?2.
inline ::testing::AssertionResult execSql(const fs::path& state, const std::string& sql,
                                          const std::string& value, const std::string& id,
                                          bool blob = false) {
  sqlite3* db = nullptr;
  if (sqlite3_open((state / "lgpd.sqlite3").c_str(), &db) != SQLITE_OK)
    return ::testing::AssertionFailure() << "cannot open the database";
  sqlite3_busy_timeout(db, 5000);
  sqlite3_stmt* st = nullptr;
  int rc = sqlite3_prepare_v2(db, sql.c_str(), -1, &st, nullptr);
  if (rc == SQLITE_OK) {
    if (blob)
      sqlite3_bind_blob(st, 1, value.data(), static_cast<int>(value.size()), SQLITE_TRANSIENT);
    else
      sqlite3_bind_text(st, 1, value.data(), static_cast<int>(value.size()), SQLITE_TRANSIENT);
    sqlite3_bind_text(st, 2, id.c_str(), -1, SQLITE_TRANSIENT);
    rc = sqlite3_step(st);
  }
  const std::string err = sqlite3_errmsg(db);
  const int changed = sqlite3_changes(db);
  sqlite3_finalize(st);
  sqlite3_close(db);
  if (rc != SQLITE_DONE) return ::testing::AssertionFailure() << sql << ": " << err;
  if (changed != 1) return ::testing::AssertionFailure() << sql << ": " << changed << " rows";
  return ::testing::AssertionSuccess();
}

// The checkpoint row of a run, decoded.
inline json storedCheckpoint(const fs::path& state, const std::string& id) {
  sqlite3* db = nullptr;
  json out;
  if (sqlite3_open_v2((state / "lgpd.sqlite3").c_str(), &db, SQLITE_OPEN_READONLY, nullptr) !=
      SQLITE_OK)
    return out;
  sqlite3_stmt* st = nullptr;
  if (sqlite3_prepare_v2(db, "SELECT state FROM checkpoints WHERE run_id = ?1", -1, &st, nullptr) ==
      SQLITE_OK) {
    sqlite3_bind_text(st, 1, id.c_str(), -1, SQLITE_TRANSIENT);
    if (sqlite3_step(st) == SQLITE_ROW) {
      const auto* p = static_cast<const uint8_t*>(sqlite3_column_blob(st, 0));
      out = json::from_cbor(std::vector<uint8_t>(p, p + sqlite3_column_bytes(st, 0)));
    }
  }
  sqlite3_finalize(st);
  sqlite3_close(db);
  return out;
}

// 100k nested one-element arrays around 0, as CBOR and as JSON text.
inline std::string deepCbor() {
  return std::string(100000, '\x81') + std::string(1, '\0');
}
inline std::string deepText() {
  return std::string(100000, '[') + "0" + std::string(100000, ']');
}

}  // namespace lgpd_test
