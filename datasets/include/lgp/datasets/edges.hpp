// Edge rows: a scene's declared domain reaches beyond its training grid (a shader evaluates n.v
// down to 1e-4 and roughness down to 0.01; a grid usually starts at 1/64), and a search scored
// on the grid alone is free to explode between the grid's first point and the domain's edge.
// The edge scene adds, per axis with a declared domain, values between the grid and that edge;
// its rows with at least one such value are the edge rows a run appends to its table
// (DataConfig::edges).
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

#include "lgp/config/config.hpp"
#include "lgp/core/status.hpp"
#include "lgp/core/table.hpp"
#include "lgp/datasets/scene.hpp"

namespace lgp::datasets {

// The values one axis adds over [lo, hi] beyond its sorted training values `train`: below the
// first training point, the geometric midpoints lo*2^(k+1/2) (lo > 0; n.v 1.41e-4, 2.83e-4, ...
// for lo = 1e-4), or lo + {0.5e-3, 0.5e-2}*(hi - lo) (lo = 0); above the last, the midpoint to
// hi. Neither end itself: a held-out set that checks the ends (bench/scoreboard) keeps them.
std::vector<double> edgeValues(const std::vector<double>& train, double lo, double hi);

// Whether `domain` (input -> [lo, hi]) adds an edge value to some axis of the scene's grid;
// inputs that are not axes, and ranges with lo >= hi, add none. A board runs a table whose
// grid spans its domain without edge rows; edgeScene refuses it.
bool domainBeyondGrid(const Scene& s,
                      const std::map<std::string, std::pair<double, double>>& domain);

// The scene over its training values and the edge values of every axis `domain` names
// (input -> [lo, hi]). Errors name the input: one that is not an axis of the scene, lo >= hi,
// or a domain that adds no value (domainBeyondGrid).
Expected<Scene> edgeScene(const Scene& s,
                          const std::map<std::string, std::pair<double, double>>& domain,
                          const std::string& origin);

// Appends to `t` (the training scene's table, columns selected with `weights_column`) the rows
// of `edge_table` (the edge scene's table, every column) off the training grid. Each weighs
// e.weight times the training rows' mean weight (times its own weight where the table has a
// weight column); t.meta["edges"] says how many rows and where.
Status appendEdgeRows(Table& t, const Scene& train, RawTable edge_table, const EdgeConfig& e,
                      const std::string& weights_column, const std::string& origin);

// Per row of the edge scene's table (inputs in the scene's order, one column per axis): true
// where some input is not one of the training scene's values on its axis.
std::vector<bool> edgeRowMask(const Scene& train, const std::vector<std::vector<double>>& inputs);

}  // namespace lgp::datasets
