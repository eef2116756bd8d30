// The structured accurate end (search.structured): least-squares fits of the parametric
// families that published fits of rendering tables use, built in seconds at the start of a
// search and offered to its archive and its long-program islands, so that the accurate end
// never starts empty and the search refines from there.
//
// Families, per model output, over features that are each input, its square root (an input
// whose table values are all >= 0) or its square (tables of at most two inputs):
//   poly d      a polynomial of total degree d in Horner form (nested over the inputs: one mad
//               per coefficient but the leading ones); "tensor d": degree d in each of two
//               inputs (MaterialX's DFG fit is a ratio of tensor-degree-2 polynomials);
//   rational    P_d / Q_e, Q's constant term 1, fitted by linearised least squares with
//               Sanathanan-Koerner reweighting (Q's magnitude at the previous step), then
//               polished by Levenberg-Marquardt on P / Q - y itself from that fit and from
//               P alone (Q = 1), and kept only where Q keeps one sign with margin over the
//               table's domain box (no pole between grid points);
//   exp2 d      exp2 of a polynomial, fitted to log2(y) weighted by y (an output > 0 on every
//               row).
// Coefficients are fitted in double on the targets as the program sees them (the output's
// transform applied, the row weights), then rounded to float; the search's scorer, fidelity
// rule and constant refinement decide what they are worth. Outputs of one table share the
// family, the degrees and the features: a member is one program.
#pragma once

#include <string>
#include <vector>

#include "lgp/config/config.hpp"
#include "lgp/core/interval.hpp"
#include "lgp/core/program.hpp"
#include "lgp/core/table.hpp"

namespace lgp {

// One fitted program of a family (its outputs the table's, before the run's output layer).
struct StructuredFit {
  std::string family;  // e.g. "rational 4/2 (sqrt mu, r)"
  Program program;
  int coefficients = 0;
};

// Every family of `cfg.search.structured` that fits `shape` (its length, constant slots and
// operators), fitted on `t`; `domain` is the table's (tableDomain), where a denominator must
// keep its sign. Deterministic whatever `threads` (0 = cfg.search.threads, else all cores);
// empty when the config turns it off.
std::vector<StructuredFit> structuredFits(const RunConfig& cfg, const Table& t,
                                          const ProgramShape& shape,
                                          const std::vector<Interval>& domain, int threads = 0);

}  // namespace lgp
