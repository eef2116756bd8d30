// The HTTP JSON API of lgpd (routes in README.md) and the inspection page at `/`.
//
// Safety rules the routes keep:
//  1. Run ids must be 16 lowercase hex digits (isValidRunId) before they touch the store;
//     anything else is a 400, so "../" or SQL never reaches a path or a statement.
//  2. The framing of a body, the site, the token and a POST's content type are checked
//     before any of the body is read (Content-Length a number, not both framings, a length
//     or a chunked body on a POST); bodies above max_body_bytes get 413 from the server,
//     chunked ones too; JSON goes through lgp::parseJson (depth 64, numbers, duplicate keys);
//     malformed JSON and bad config fields get 400 naming the JSON path; unknown runs or members
//     get 404. Status codes per route: README.md.
//  3. With a token configured, every /api/ route but /api/v1/health needs
//     "Authorization: Bearer <token>" (constant-time compare); the page itself is static
//     and asks for the token.
//  4. Handlers only read SQLite and signal jobs, so the API stays responsive while searches
//     run: loading a table and scoring references run on the JobManager's background thread
//     (a request waits a bounded time, then gets 503 with Retry-After, or the references
//     marked pending). Nothing from a request reaches a shell. Slow clients are bounded by
//     HttpServer (http_server.hpp).
#pragma once

#include "http_server.hpp"
#include "jobs.hpp"
#include "store.hpp"

namespace lgpd {

// The checks before the body and the routes, for HttpServer.
HttpHandlers makeApi(Store& store, JobManager& jobs);

}  // namespace lgpd
