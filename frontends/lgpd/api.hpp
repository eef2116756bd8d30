// The HTTP JSON API of lgpd (routes in README.md) and the inspection page at `/`.
//
// Safety rules the routes keep:
//  1. Run ids must be 16 lowercase hex digits (isValidRunId) before they touch the store;
//     anything else is a 400, so "../" or SQL never reaches a path or a statement.
//  2. Bodies above max_body_bytes get 413 (httplib's payload limit); malformed JSON and bad
//     config fields get 400 naming the JSON path; unknown runs or members get 404.
//  3. With a token configured, every /api/ route but /api/v1/health needs
//     "Authorization: Bearer <token>" (constant-time compare); the page itself is static
//     and asks for the token.
//  4. Handlers only read SQLite and signal jobs, so the API stays responsive while searches
//     run; nothing from a request reaches a shell.
#pragma once

#include <httplib.h>

#include "jobs.hpp"
#include "store.hpp"

namespace lgpd {

// Registers every route, the error handlers and the limits on `server`.
void installApi(httplib::Server& server, Store& store, JobManager& jobs);

}  // namespace lgpd
