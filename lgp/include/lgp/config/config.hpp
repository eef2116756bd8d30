// Run configuration: plain structs with defaults, one comment per field, and validation that
// names the offending JSON path. The JSON mapping (parseRunConfig / toJson) is the only place
// that knows the JSON spelling; the CLI, the daemon and tests all go through it.
//
// Example (every key optional except data.path or data.scene):
// {
//   "data": {"path": "table.csv", "inputs": ["mu", "r"], "outputs": ["A"],
//            "weights": "w", "transforms": {"A": "log"}},
//   "program": {"max_length": 32, "constants": 8, "output_mode": "last",
//               "ops": ["add", "sub", "mul", "div", "mad", "exp2", "min", "max"]},
//   "objectives": {"error": "rmse", "combine": "mean", "cost_model": "gpu-generic",
//                  "cost_overrides": {"div": 3}, "discontinuity_weights": {"abs": 0.5}},
//   "search": {"population": 400, "generations": 200, "max_evaluations": 0,
//              "wall_time_s": 0, "seed": 1, "threads": 0},
//   "output": {"front_json": "front.json", "front_csv": "front.csv"}
// }
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/core/ops.hpp"
#include "lgp/core/program.hpp"
#include "lgp/eval/discontinuity.hpp"
#include "lgp/eval/objectives.hpp"
#include "lgp/search/levenberg_marquardt.hpp"
#include "lgp/search/migration.hpp"
#include "lgp/search/nelder_mead.hpp"
#include "lgp/search/pareto.hpp"

namespace lgp {

// data.cache_dir "-": generate the scene's table without reading or writing a cache (as
// `lgp data --no-cache` and lgp.data(cache_dir="-")).
inline constexpr const char* kNoCache = "-";

struct DataConfig {
  std::string path;                  // CSV or JSON table; relative to the config file
  std::string scene;                 // or a scene JSON for the datasets/ generators
  std::vector<std::string> inputs;   // input column names; empty = the file's declared inputs
  std::vector<std::string> outputs;  // output column names; empty = the file's declared outputs
  std::string weights;               // per-row weight column; empty = file weights or uniform
  std::map<std::string, TargetTransform> transforms;  // fit T(y) for these outputs
  std::string cache_dir;  // generated-table cache (scene only); empty = default, "-" = none
};

struct ProgramConfig {
  // Room for the accurate end (30-64 GPU instructions, ~30 fitted coefficients); the default
  // island profiles keep most islands at 32 opcodes and 8 slots for the cheap end.
  int max_length = 96;                        // opcodes per program (1..255)
  int num_constants = 48;                     // constant slots per program (0..255)
  OutputMode output_mode = OutputMode::Last;  // last k opcodes, or designated slots
  std::vector<Op> ops;                        // allowed operators; empty = kDefaultOps
  int init_min_length = 2;                    // random initial programs: length range
  int init_max_length = 12;
  double const_min = -2.0;  // initial constants and mutation resets: uniform in [min, max]
  double const_max = 2.0;
  // Genes per output of the output layer (needs search.linear_scaling): each output is the
  // least-squares combination b + sum_g a_g f_g of `genes` program results, fitted in closed
  // form at every evaluation (eval/objectives.hpp). 1 = the plain a*f + b.
  int genes = 1;
};

// A derived signal the error is measured on: sum over outputs of weight * output, against the
// same sum of targets. E.g. {"name": "F0=0.04", "weights": {"A": 0.04, "B": 1}} measures the
// split-sum DFG where it is used, F0*A + B, rather than A and B separately.
struct ChannelConfig {
  std::string name;
  std::map<std::string, double> weights;  // output name -> weight; missing outputs weigh 0
};

// Measured GPU cost (emit/gpu_cost.hpp): emitted code compiled to AMD ISA on RADV's null device.
struct MeasuredCostConfig {
  // Families measured for every final front member and reference ("cost_measured"); empty =
  // none. Where the backend is missing the front says why and the run goes on.
  std::vector<GpuFamily> families = allGpuFamilies();
  // Archive members are measured (the first family's instructions, cached) as they enter the
  // archive, which then keeps only members non-dominated in measured cost; the populations
  // still select on the model. Needs the backend: a run without it fails at the start.
  bool in_search = false;
};

struct ObjectiveConfig {
  ErrorMetric metric = ErrorMetric::Rmse;       // the error objective
  OutputCombine combine = OutputCombine::Mean;  // across outputs (or channels)
  std::vector<ChannelConfig> channels;          // empty = the error of each output
  double rel_floor = 1e-6;                      // denominator floor of mean_rel
  CostTarget cost_model = CostTarget::GpuGeneric;
  std::map<Op, double> cost_overrides;         // per-operator cost replacing the model's
  std::map<Op, double> discontinuity_weights;  // per-operator weight replacing the default
  MeasuredCostConfig measured_cost;
};

struct VariationConfig {
  double crossover_rate = 0.6;  // offspring made by two-segment crossover, then mutated
  double macro_rate = 0.3;      // chance of an insertion or deletion
  double micro_rate = 0.9;      // chance of 1..micro_max micro mutations
  int micro_max = 2;            // micro mutations per offspring, at most
  double constant_sigma = 0.2;  // relative Gaussian step of a constant mutation
  double effective_bias = 0.9;  // chance a micro mutation targets an effective opcode
  double wrap_share = 0.5;      // chance an inserted opcode wraps the operand it replaces
  // Chance an offspring gets a weight (weightMutate: x becomes mul(c, x) with c = 1, a
  // coefficient of its own); such offspring are always refined, so constant fitting moves it.
  double weight_rate = 0.25;
  // Offspring with fewer effective opcodes than this get no weight: the cheap end searches as
  // without weights, and the coefficients go to the programs large enough to use them.
  int weight_min_length = 16;
};

enum class RefineMethod : uint8_t {
  NelderMead,  // local simplex search only
  DeThenNm     // differential evolution (global) first, then Nelder-Mead from its best point
};

// Constant refinement. Offspring picked for it (offspring_share) get lm_iterations of
// Levenberg-Marquardt with exact Jacobians, and a quick Nelder-Mead polish only where that did
// not improve them, unless LM converged on the error itself (then the constants are already
// at its optimum; with lm_metric least_squares that is only rmse of one channel); archive
// members get archive_lm_iterations of LM, then the full derivative-free refinement
// (`method`).
struct RefineSchedule {
  double offspring_share = 1.0;    // share of each generation's offspring refined
  int lm_iterations = 5;           // LM iterations per refined offspring; 0 = derivative-free
  int archive_lm_iterations = 30;  // LM iterations per archive refinement; 0 = none
  int offspring_evaluations = 60;  // budget of the quick Nelder-Mead polish (no restarts)
  int archive_period = 10;         // every N generations, fully refine unrefined archive members
  int archive_max = 32;            // archive members refined per period, at most
  NelderMeadConfig nm;             // full refinement: budget, restarts and coefficients
  RefineMethod method = RefineMethod::NelderMead;  // of the full (archive) refinement
  int de_evaluations = 300;                        // DE budget before Nelder-Mead (de+nm)
  // What LM fits: the configured error (reweighted rounds, levenberg_marquardt.hpp), the
  // plain sum of squares, or auto: the configured error without linear scaling, the sum of
  // squares with it (measured, docs/constant-fitting.md).
  LmObjective lm_metric = LmObjective::Auto;
  // Which unrefined members a period serves first ("oldest": storage order; "accurate":
  // lowest error first). It decides who waits only when more than archive_max members are
  // unrefined; on the DFG ablation (3 seeds, archive_max 4) "accurate" did not do better, so
  // the default stays the storage order.
  ArchiveRefineOrder archive_order = ArchiveRefineOrder::Oldest;
};

enum class MultiOutputMode : uint8_t {
  Joint,   // one program computes every output; shared sub-expressions cost once
  TwoStep  // fit `first` alone, then the others with its chosen
           // expression as an extra input; the result is one program (the DAG of both)
};

struct MultiOutputConfig {
  MultiOutputMode mode = MultiOutputMode::Joint;
  std::string first;          // two_step: the output fitted first (e.g. "B")
  double first_share = 0.4;   // two_step: share of every budget spent on the first step
  double first_max_cost = 0;  // two_step: the pick is the most accurate first-step member of
                              // cost <= this; 0 = the knee of its front (see two_step.hpp)
};

// Islands (demes): see lgp/search/migration.hpp.
struct IslandConfig {
  int count = 4;                // islands; the population is split evenly between them, and
                                // at most population / 4 islands are used (4 individuals each)
  int migration_interval = 10;  // generations between migrations; 0 = islands never exchange
  int migrants = 4;             // first-front members each island sends per migration
  int restart_after = 0;        // generations without a better island best before the island
                                // restarts from random programs and archive members; 0 = never
  // How the members of each archive refinement rejoin the islands (one island each):
  // "interleaved" (in turn) or "by_cost" (consecutive cost slices, see IslandDeal).
  IslandDeal deal = IslandDeal::ByCost;
  // Island k has profiles[k % size] (a profile's length and slots are capped at the run's);
  // [{}] = every island searches the run's program shape. The default: islands 0-2 search the
  // cheap end (32 opcodes, 8 slots, no weights) and island 3 grows long programs with weights,
  // its survival stratified by cost (8 slices) so that long members outlive cheaper ones of
  // about the same error; measured on every peer table and the recovery suite
  // (docs/accurate-end.md).
  std::vector<IslandProfile> profiles = {
      {32, 8, 0}, {32, 8, 0}, {32, 8, 0}, {.cost_strata = 8}};
  // Who sends migrants to whom: "ring" (the next island) or "by_profile" (the next island of
  // the same profile).
  MigrationTopology topology = MigrationTopology::Ring;
  Status validate() const;
};

// Exhaustive enumeration of small expressions before the search (search/exhaustive.hpp): the
// results seed the islands and the front JSON gets their certificate ("exhaustive").
struct ExhaustiveConfig {
  int max_ops = 0;        // operators per expression, 1..8; 0 = off
  std::vector<Op> ops;    // operators (arity <= 3); empty = program.ops
  int constants = 2;      // free constants per expression, 0..8
  double seconds = 60;    // budget; sizes not finished by then are reported incomplete
  int screen_rows = 256;  // rows of the screening fit (every row for smaller tables)
  int keep = 64;          // per operator count, screened expressions refitted on every row
};

struct SearchConfig {
  int population = 400;   // individuals per generation, all islands together
  int generations = 100;  // budget; 0 = unlimited (then another budget must be set)
  // Budget in program evaluations (a Jacobian pass over n constants counts 1 + n); 0 = none.
  uint64_t max_evaluations = 0;
  double wall_time_s = 0;   // budget in seconds; 0 = unlimited
  uint64_t seed = 1;        // same seed + config + threads => same front
  int threads = 0;          // OpenMP threads; 0 = all cores
  int tournament_size = 2;  // NSGA-II binary tournament by default
  double error_bias = 0.0;  // share of tournaments decided by error alone, not (rank,
                            // crowding): steers the search to the accurate end
  // Survival stratified by cost: the pool's cost range is cut into this many equal slices, and
  // a quarter of the survivors are the lowest-error distinct members of each slice, whatever
  // their Pareto rank (0 = off: plain NSGA-II survival). Keeps large programs alive where
  // they are dominated by cheap ones of about the same error.
  int cost_strata = 0;
  // Entries of the semantic cache (search/semantic_cache.hpp): objectives and offspring LM
  // fits, keyed by a program's effective form, so that clones and intron-only mutants are not
  // evaluated or fitted again. It changes time, never the result; 0 = off.
  int semantic_cache = 1 << 16;
  bool linear_scaling = false;   // fit each output as a*f + b with the closed-form a, b
                                 // (Keijzer; Operon); the front's programs include the mad
  bool seed_references = false;  // start from the config's reference formulas (those that fit
                                 // the program shape) besides random programs
  MultiOutputConfig multi_output;
  IslandConfig islands;
  VariationConfig variation;
  RefineSchedule refine;
  ArchiveConfig archive;
  ExhaustiveConfig exhaustive;
};

struct EvalConfig {
  int block_size = 256;  // rows per interpreter block; multiple of 16, in [16, 16384]
};

// A relative path named in a config file is relative to that file's directory (parseRunConfig
// joins it to base_dir), like data.path; the defaults and paths given on the command line
// (`lgp run -o`, `--csv`, `--checkpoint`, `--status`) are relative to the working directory.
struct OutputConfig {
  std::string front_json = "front.json";     // default: in the working directory
  std::string front_csv = "front.csv";       // empty = not written
  double progress_interval_s = 1.0;          // progress line period; 0 = every generation
  std::vector<double> progress_cost_levels;  // best error at cost <= c; empty = automatic
  std::string checkpoint;                    // `lgp run` checkpoint file; empty = none
  double checkpoint_interval_s = 60;         // seconds between checkpoints (and one at the end)
};

// How islands on different MPI ranks exchange migrants (lgp/search/mpi_driver.hpp).
enum class MigrationMode : uint8_t {
  Async,  // non-blocking: a rank takes what has arrived; a slow rank never stalls the others
  Sync    // every rank waits for its neighbours' migrants each round: reproducible fronts
};

// Runs over MPI (`mpirun -np N lgp run cfg.json`). Ignored by a run without a launcher.
struct MpiConfig {
  int np = 0;  // ranks lgpd launches for this run; 0 = run in-process (lgp run ignores it)
  MigrationMode migration = MigrationMode::Async;
};

struct RunConfig {
  DataConfig data;
  ProgramConfig program;
  ObjectiveConfig objectives;
  SearchConfig search;
  EvalConfig eval;
  OutputConfig output;
  MpiConfig mpi;
  nlohmann::json references = nlohmann::json::array();  // formulas to score beside the front
  std::filesystem::path base_dir;  // directory of the config file (for relative data paths)

  Status validate() const;
  // The bounds that depend on the table's output count (validate() applies them where
  // data.outputs lists the outputs; every table source applies them once the table is known):
  // under linear scaling max_length + outputs * genes <= 255 opcodes and constants +
  // outputs * (genes + 1) <= 255 slots, so that register and constant indices fit a byte.
  Status validateShape(size_t num_outputs) const;
  ProgramShape shape(int num_inputs, int num_outputs) const;
  CostModel costModel() const;
  DiscontinuityModel discontinuityModel() const;
  ErrorConfig errorConfig(const std::vector<std::string>& output_names) const;
};

// Operators used when the config lists none: everything except the rarely useful
// trigonometric pair (add them explicitly for periodic data).
std::vector<Op> defaultOps();

std::string_view toString(RefineMethod m);
std::string_view toString(LmObjective o);
std::string_view toString(ArchiveRefineOrder o);
std::string_view toString(IslandDeal d);
std::string_view toString(MigrationTopology t);
std::string_view toString(MultiOutputMode m);
std::string_view toString(MigrationMode m);

// Parses and validates. Errors name the JSON path, e.g.
// "/search/population: must be an integer >= 4 (got 2)" or "/search/popsize: unknown key".
Expected<RunConfig> parseRunConfig(const nlohmann::json& j, const std::filesystem::path& base_dir);
// Largest run config file read (configs are small; a table goes in its own file).
inline constexpr size_t kMaxConfigBytes = size_t{64} << 20;
Expected<RunConfig> loadRunConfig(const std::filesystem::path& path);
// The same for a config's text read elsewhere (e.g. by MPI rank 0); `path` names it in errors
// and gives the directory relative data paths start from.
Expected<RunConfig> parseRunConfigText(const std::string& text, const std::filesystem::path& path);
nlohmann::json toJson(const RunConfig& c);

}  // namespace lgp
